"""Simulation results against independent computations: closed forms of
the free beam, conservation of energy, the constraint w_stop <= d, ODE
integrations with scipy (free flight and the sticking phase), the native
`beamstop run`, and independence of the communication step."""

import csv
import math
import re
import subprocess

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fmpy import simulate_fmu

from conftest import (
    ALL_OUTPUTS,
    FMU_PATH,
    FREE_ENERGY,
    FREE_FIRST_IMPACT,
    FREE_VIBRATION,
    N_MODES,
    modal_energy,
    mode_shape,
    model_description,
    variables,
    native_beamstop,
    omega_mode,
    w_at,
)

X_STOP = 0.4
W_STOP = np.array([mode_shape(j, X_STOP) for j in range(1, N_MODES + 1)])
OMEGA = np.array([omega_mode(j) for j in range(1, N_MODES + 1)])


def load_modal_amplitudes(F):
    """Modal forces of a uniform load F: int_0^1 F W_j dx = F sqrt2 (1 - cos j pi) / (j pi)."""
    return np.array([F * math.sqrt(2.0) * (1.0 - math.cos(j * math.pi)) / (j * math.pi)
                     for j in range(1, N_MODES + 1)])


def close(a, b, tol):
    return abs(a - b) <= tol * max(1.0, abs(a), abs(b))


# ------------------------------------------------------------------ default experiment

@pytest.fixture(scope="module")
def default_result():
    ex = model_description().defaultExperiment
    return simulate_fmu(str(FMU_PATH), output_interval=float(ex.stepSize))


def test_default_experiment_runs(default_result):
    ex = model_description().defaultExperiment
    r = default_result
    assert set(ALL_OUTPUTS) <= set(r.dtype.names)
    assert r["time"][0] == float(ex.startTime)
    assert r["time"][-1] == pytest.approx(float(ex.stopTime), abs=1e-12)
    assert len(r) == round((float(ex.stopTime) - float(ex.startTime)) / float(ex.stepSize)) + 1
    for n in r.dtype.names:
        assert np.all(np.isfinite(r[n].astype(float))), n


def test_default_scene_story(default_result):
    """The paper's Figure 4: stuck at t = 0 with lambda < 0 right after,
    release near 3.18, chatter, sticking again near 6.49."""
    r = default_result
    t, stick, lam, imp = r["time"], r["sticking"], r["lambda"], r["impacts"]
    assert stick[0]
    assert lam[(t > 0) & (t <= 0.1)].max() < 0.0
    first_free = t[np.argmax(~stick)]
    assert 3.18 <= first_free <= 3.19, first_free
    assert imp[t < 3.18].max() == 0
    after = (t > first_free) & stick
    restick = t[np.argmax(after)]
    assert 6.48 <= restick <= 6.50, restick
    assert imp[t <= restick].max() > 20, "chatter: many impacts before sticking again"


def test_default_scene_constraint_and_reaction(default_result):
    r = default_result
    d = float(variables()["d"].start)
    q = np.column_stack([r[f"q[{j}]"] for j in range(1, N_MODES + 1)])
    qd = np.column_stack([r[f"qd[{j}]"] for j in range(1, N_MODES + 1)])
    # outputs consistent with their definitions (computed here, independently)
    assert np.allclose(r["w_stop"], q @ W_STOP, rtol=0, atol=1e-12)
    assert np.allclose(r["v_stop"], qd @ W_STOP, rtol=0, atol=1e-10)
    energy = 0.5 * (qd ** 2 + (OMEGA ** 2) * q ** 2).sum(axis=1)
    assert np.allclose(r["energy"], energy, rtol=1e-12, atol=1e-15)
    # the stop is on the +w side
    assert r["w_stop"].max() <= d + 1e-12
    # while sticking the beam sits on the stop and is pushed back; otherwise no reaction
    s = r["sticking"].astype(bool)
    assert np.all(np.abs(r["w_stop"][s] - d) <= 1e-12)
    assert np.all(np.abs(r["v_stop"][s]) <= 1e-9)
    assert np.all(r["lambda"][s] <= 0.0)
    assert np.all(r["lambda"][~s] == 0.0)
    # impacts never decrease; t_last_impact is an impact time inside the run
    assert np.all(np.diff(r["impacts"]) >= 0)
    assert np.all(r["t_last_impact"] <= r["time"] + 1e-15)


def test_matches_native_run(default_result, tmp_path, unzipdir):
    """fmpy through the FMU and the native `beamstop run` of the same scene agree."""
    ex = model_description().defaultExperiment
    scene = unzipdir / "resources" / "scene.json"
    cmd = native_beamstop() + ["run", str(scene), "--stop", str(float(ex.stopTime)),
                               "--step", str(float(ex.stepSize)), "--out", str(tmp_path)]
    subprocess.run(cmd, check=True, capture_output=True, timeout=300)
    with open(tmp_path / "PinnedBeamStop.csv") as f:
        rows = list(csv.DictReader(f))
    r = default_result
    assert len(rows) == len(r)
    last = rows[-1]
    assert float(last["time"]) == pytest.approx(20.0, abs=1e-12)
    for n in ALL_OUTPUTS:
        a, b = float(r[n][-1]), float(last[n])
        assert close(a, b, 1e-10), (n, a, b)
    # and at every output point
    for n in ALL_OUTPUTS:
        native = np.array([float(row[n]) for row in rows])
        diff = np.abs(r[n].astype(float) - native) / np.maximum(1.0, np.abs(native))
        k = int(np.argmax(diff))
        assert diff[k] <= 1e-10, (n, float(r["time"][k]), float(r[n][k]), native[k])


# ------------------------------------------------------------------ free vibration

def test_free_vibration_first_impact_at_quarter_period(make_instance):
    inst = make_instance().initialize(FREE_VIBRATION)
    assert inst.get("t_last_impact") == 0.0
    while inst.get("impacts") < 1:
        t_before = inst.time
        inst.step(0.01)
        assert inst.time < 1.0, "no impact found"
    assert inst.get("impacts") == 1
    assert t_before < FREE_FIRST_IMPACT <= inst.time
    assert abs(inst.get("t_last_impact") - FREE_FIRST_IMPACT) <= 1e-12


def test_free_vibration_closed_form_before_impact(make_instance):
    """Before the first impact only mode 1 moves: q1 = q10 cos(pi^2 t)."""
    inst = make_instance().initialize(FREE_VIBRATION)
    q10 = FREE_VIBRATION["q0[1]"]
    for _ in range(15):
        inst.step(0.01)
        t = inst.time
        w1 = omega_mode(1)
        assert inst.get("impacts") == 0
        assert abs(inst.get("q[1]") - q10 * math.cos(w1 * t)) <= 1e-12
        assert abs(inst.get("qd[1]") + q10 * w1 * math.sin(w1 * t)) <= 1e-10
        for j in range(2, N_MODES + 1):
            assert inst.get(f"q[{j}]") == 0.0 and inst.get(f"qd[{j}]") == 0.0


@pytest.mark.parametrize("R", [1.0, 0.5])
def test_impact_law_closed_form(make_instance, R):
    """Modal restitution: qd+ = qd- - (1 + R) W (W . qd-) / (W . W); then
    free flight q_j = qd_j+ / omega_j sin(omega_j (t - t1)) (q = 0 at t1)."""
    inst = make_instance().initialize({**FREE_VIBRATION, "R": R})
    while inst.time < 0.16 - 1e-12:
        inst.step(0.01)
    inst.step(0.005)
    t = inst.time
    assert inst.get("impacts") == 1
    t1 = FREE_FIRST_IMPACT
    qd_minus = np.zeros(N_MODES)
    qd_minus[0] = -FREE_VIBRATION["q0[1]"] * omega_mode(1)  # q1(t1) = 0, qd1 = 3 pi^2 / sqrt 2
    qd_plus = qd_minus - (1.0 + R) * W_STOP * (W_STOP @ qd_minus) / (W_STOP @ W_STOP)
    q_expected = qd_plus / OMEGA * np.sin(OMEGA * (t - t1))
    qd_expected = qd_plus * np.cos(OMEGA * (t - t1))
    assert np.allclose(inst.q(), q_expected, rtol=0, atol=1e-10), (inst.q(), q_expected)
    assert np.allclose(inst.qd(), qd_expected, rtol=0, atol=1e-8), (inst.qd(), qd_expected)
    e_minus = FREE_ENERGY
    e_lost = 0.5 * (1.0 - R * R) * (W_STOP @ qd_minus) ** 2 / (W_STOP @ W_STOP)
    assert inst.get("energy") == pytest.approx(e_minus - e_lost, rel=1e-11)


def test_free_vibration_energy_is_conserved(make_instance):
    inst = make_instance().initialize(FREE_VIBRATION, stop_time=20.0)
    rec = []
    inst.step_to(20.0, 0.01, rec)
    assert rec[-1][1]["impacts"] > 10
    worst = 0.0
    for t, o in rec:
        e = modal_energy([o[f"q[{j}]"] for j in range(1, 5)], [o[f"qd[{j}]"] for j in range(1, 5)])
        assert o["energy"] == pytest.approx(e, rel=1e-12)
        worst = max(worst, abs(o["energy"] - FREE_ENERGY) / FREE_ENERGY)
    assert worst <= 1e-11, worst


def test_free_vibration_never_penetrates(make_instance):
    inst = make_instance().initialize(FREE_VIBRATION, stop_time=20.0)
    rec = []
    inst.step_to(20.0, 0.01, rec)
    for t, o in rec:
        w = w_at(X_STOP, [o[f"q[{j}]"] for j in range(1, 5)])
        assert abs(o["w_stop"] - w) <= 1e-12, t
        assert o["w_stop"] <= 0.0 + 1e-12, (t, o["w_stop"])


@pytest.mark.parametrize("gap", [0.05, -0.05, 0.0])
def test_loaded_beam_never_penetrates(make_instance, gap):
    """Default load, other gaps; a preload needs an initial state below the stop."""
    start = {"d": gap}
    if gap < 0:
        start["q0[1]"] = 2.0 * gap / mode_shape(1, X_STOP)  # w_stop(0) = 2 gap < gap
    inst = make_instance().initialize(start, stop_time=10.0)
    rec = []
    inst.step_to(10.0, 0.01, rec)
    assert rec[-1][1]["impacts"] > 0
    for t, o in rec:
        assert o["w_stop"] <= gap + 1e-12, (t, o["w_stop"])
        if o["sticking"]:
            assert abs(o["w_stop"] - gap) <= 1e-12
            assert o["lambda"] <= 0.0


# ------------------------------------------------------------------ against ODE integrations

def test_free_flight_matches_ode_with_damping_load_and_point_force(make_instance):
    """No contact (huge gap): q'' + 2 zeta w q' + w^2 q = f sin(Omega t) + W(x_force) P."""
    F, Om, zeta, P, xf = 76.8, 2.7, 0.05, 5.0, 0.3
    q0 = np.array([0.0, 0.01, 0.0, 0.0])
    qd0 = np.array([0.0, 0.0, 0.5, 0.0])
    start = {"d": 1e3, "zeta": zeta, "omega": Om, "x_force": xf, "F": F,
             "q0[2]": q0[1], "qd0[3]": qd0[2]}
    inst = make_instance().initialize(start)
    inst.set({"force": P})
    rec = []
    inst.step_to(3.0, 0.01, rec)
    fj = load_modal_amplitudes(F)
    bj = np.array([mode_shape(j, xf) for j in range(1, N_MODES + 1)]) * P

    def rhs(t, y):
        q, qd = y[:N_MODES], y[N_MODES:]
        return np.concatenate([qd, fj * math.sin(Om * t) + bj - 2 * zeta * OMEGA * qd - OMEGA ** 2 * q])

    ts = [t for t, _ in rec]
    sol = solve_ivp(rhs, (0.0, 3.0), np.concatenate([q0, qd0]), method="DOP853",
                    rtol=1e-13, atol=1e-13, t_eval=ts)
    fmu = np.array([[o[f"q[{j}]"] for j in range(1, 5)] + [o[f"qd[{j}]"] for j in range(1, 5)] for _, o in rec])
    assert np.abs(fmu - sol.y.T).max() <= 1e-8
    assert all(o["impacts"] == 0 for _, o in rec)


def test_sticking_phase_matches_constrained_ode(make_instance):
    """Default scene: stuck from t = 0 until the reaction
    lambda = -W.(f - C qd - K q)/(W.W) changes sign (VSM12 eq. 33)."""
    inst = make_instance(logging_on=True)
    inst.slave.setDebugLogging(True, ["logEvents"])
    inst.initialize(stop_time=4.0)
    rec = []
    inst.step_to(3.5, 0.01, rec)
    F, Om, zeta = 76.8, 0.1 * math.pi ** 2, 0.05
    fj = load_modal_amplitudes(F)

    def free_acc(t, y):
        q, qd = y[:N_MODES], y[N_MODES:]
        return fj * math.sin(Om * t) - 2 * zeta * OMEGA * qd - OMEGA ** 2 * q

    def lam(t, y):
        return -(W_STOP @ free_acc(t, y)) / (W_STOP @ W_STOP)

    def rhs(t, y):
        return np.concatenate([y[N_MODES:], free_acc(t, y) + W_STOP * lam(t, y)])

    def release(t, y):
        return lam(t, y)

    release.terminal = True
    release.direction = 1
    stuck = [(t, o) for t, o in rec if o["sticking"]]
    sol = solve_ivp(rhs, (0.0, 3.5), np.zeros(2 * N_MODES), method="DOP853", rtol=1e-13, atol=1e-14,
                    t_eval=[t for t, _ in stuck], events=release)
    assert len(sol.t_events[0]) == 1
    t_release = sol.t_events[0][0]
    fmu = np.array([[o[f"q[{j}]"] for j in range(1, 5)] + [o[f"qd[{j}]"] for j in range(1, 5)] for _, o in stuck])
    assert np.abs(fmu - sol.y.T).max() <= 1e-9
    lam_ode = np.array([lam(t, y) for t, y in zip(sol.t, sol.y.T)])
    lam_fmu = np.array([o["lambda"] for _, o in stuck])
    assert np.abs(lam_fmu - lam_ode).max() <= 1e-8 * max(1.0, np.abs(lam_ode).max())
    # the release the FMU logs is the zero of the reaction
    releases = [float(m.group(1)) for m in (re.match(r"t = ([0-9.eE+-]+): release", x)
                                            for x in inst.log.messages("logEvents")) if m]
    assert releases, inst.log.text()
    assert abs(releases[0] - t_release) <= 1e-8, (releases[0], t_release)


def test_chatter_intervals_shrink_by_R(make_instance):
    """Chatter of a slow beam on the stop: successive inter-impact times
    shrink by about R (bouncing under a nearly constant force)."""
    inst = make_instance(logging_on=True)
    inst.slave.setDebugLogging(True, ["logEvents"])
    inst.initialize(stop_time=7.0)
    inst.step_to(7.0, 0.01)
    times = []
    for m in inst.log.messages("logEvents"):
        g = re.match(r"t = ([0-9.eE+-]+): (impact|sticking starts)", m)
        if g:
            times.append((float(g.group(1)), g.group(2)))
    stick = next(t for t, k in times if k == "sticking starts" and t > 1.0)
    assert 6.48 <= stick <= 6.50
    impacts = [t for t, k in times if k == "impact" and t <= stick]
    gaps = np.diff(impacts)
    ratios = gaps[1:] / gaps[:-1]
    tail = ratios[-15:]
    assert len(tail) == 15
    assert np.all(np.abs(tail - 0.7) <= 0.03), tail


# ------------------------------------------------------------------ step independence

@pytest.mark.parametrize("scene", ["default", "free_vibration"])
def test_result_does_not_depend_on_communication_step(make_instance, scene):
    start = None if scene == "default" else FREE_VIBRATION
    results = {}
    for h in (0.01, 0.37):
        inst = make_instance().initialize(start, stop_time=20.0)
        inst.step_to(20.0, h)
        assert inst.time == 20.0
        results[h] = inst.outputs()
    # an irregular step sequence, too
    rng = np.random.default_rng(1)
    inst = make_instance().initialize(start, stop_time=20.0)
    while inst.time < 20.0:
        h = min(float(rng.uniform(0.001, 0.9)), 20.0 - inst.time)
        if 20.0 - (inst.time + h) < 1e-9:
            h = 20.0 - inst.time
        inst.step(h)
    results["random"] = inst.outputs()
    ref = results[0.01]
    assert ref["impacts"] > 10
    for key, res in results.items():
        for n in ALL_OUTPUTS:
            assert close(float(res[n]), float(ref[n]), 1e-10), (key, n, res[n], ref[n])


# ------------------------------------------------------------------ tunable parameters and input between steps

def test_tunable_parameters_and_input_between_steps_match_piecewise_ode(make_instance):
    """No contact: F, omega changed once, the point force changed every step
    (held over the step); each step compared with an ODE integration."""
    zeta = 0.05
    x_force = float(variables()["x_force"].start)
    b = np.array([mode_shape(j, x_force) for j in range(1, N_MODES + 1)])
    inst = make_instance().initialize({"d": 1e3})
    F, Om = 76.8, 0.1 * math.pi ** 2
    y, t, worst = np.zeros(2 * N_MODES), 0.0, 0.0
    for k in range(40):
        P = 10.0 * math.sin(k)
        if k == 10:
            F, Om = -30.0, 5.0
            inst.set({"F": F, "omega": Om})
        inst.set({"force": P})
        t1 = (k + 1) * 0.05
        inst.advance_to(t1)
        fj = load_modal_amplitudes(F)

        def rhs(tt, yy):
            return np.concatenate([yy[N_MODES:], fj * math.sin(Om * tt) + b * P
                                   - 2 * zeta * OMEGA * yy[N_MODES:] - OMEGA ** 2 * yy[:N_MODES]])

        y = solve_ivp(rhs, (t, t1), y, method="DOP853", rtol=1e-13, atol=1e-13).y[:, -1]
        t = t1
        worst = max(worst, float(np.abs(np.array(inst.q() + inst.qd()) - y).max()))
    assert worst <= 1e-9, worst


def test_reaction_never_tensile_after_tuning_the_load(make_instance):
    """lambda is documented as <= 0. Stuck at t = 1, a load flipped so far
    that the stop would have to pull the beam: the outputs read right after
    fmi2SetReal must not show a tensile reaction while 'sticking' is true
    (either still compressive, or released with lambda = 0)."""
    inst = make_instance().initialize()
    inst.step_to(1.0, 0.01)
    assert inst.get("sticking") and inst.get("lambda") < 0.0
    inst.set({"F": -200.0})
    lam, stick = inst.get("lambda"), inst.get("sticking")
    inst.step(0.001)
    assert not inst.get("sticking"), "a tensile reaction releases the beam at once"
    assert lam <= 0.0, f"lambda = {lam} > 0 read after fmi2SetReal(F = -200) at t = 1 (sticking = {stick})"


def test_nonzero_start_time(make_instance):
    """t_last_impact is the start time before any impact; with F = 0 the
    first impact is a quarter period after the start."""
    t0 = 2.0
    inst = make_instance().initialize(FREE_VIBRATION, start_time=t0)
    assert inst.get("t_last_impact") == t0 and inst.get("impacts") == 0
    inst.step_to(t0 + 0.1, 0.01)
    assert inst.get("t_last_impact") == t0 and inst.get("impacts") == 0
    inst.advance_to(t0 + 0.17)  # the second impact comes 0.18196 after the start
    assert inst.get("impacts") == 1
    assert abs(inst.get("t_last_impact") - (t0 + FREE_FIRST_IMPACT)) <= 1e-12
