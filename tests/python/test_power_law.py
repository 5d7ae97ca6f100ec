"""The power-law stop `F = max(0, K p^n + damping)` against an independent
integration: one mass on a weak spring dropped at speed v0 onto the stop,
at n = 1 (a flat punch) and n = 1.1 (a line contact), with linear and
Hunt-Crossley damping. beamstop (`beamstop run`, the FMU's engine, at the
tightest integration tolerance, 1e-14) against scipy's DOP853 at rtol
1e-12 with events: the time the push ends (contact duration) and the peak
force agree to 1e-8 relative, and the stop's energy outputs close the
balance to 1e-10 of the impact energy once the contact is over.
"""

from __future__ import annotations

import csv
import json
import subprocess

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from conftest import ROOT

BEAMSTOP = ROOT / "target" / "release" / "beamstop"
M, SPRING, V0, K = 0.5, 10.0, 0.3, 1e6
STEP, STOP = 1e-6, 0.006


def scene(n: float, damping: dict) -> dict:
    return {
        "name": "PowerLawDrop",
        "units": "SI",
        "structure": {"type": "chain", "masses": 1, "m": M, "k": SPRING, "c": 0.0},
        "stops": [{"name": "stop", "mass": 1, "gap": 0.0, "side": "positive",
                   "law": {"type": "power_law", "n": n, "K": K, **damping}}],
        "initial": {"qd": [V0]},
        "outputs": {"energy": True},
        "solver": {"integration_tolerance": 1e-14},
        "experiment": {"start": 0, "stop": STOP, "step": STEP},
    }


def force(n, damping, p, pd):
    """The law's unclamped force, written here from its formula."""
    spring = K * max(p, 0.0) ** n
    if damping.get("damping") == "hunt_crossley":
        return spring * (1.0 + 1.5 * (1.0 - damping["e"]) * pd / V0)
    return spring + damping.get("C", 0.0) * pd


def reference(n, damping):
    """scipy: x'' = (-k x - F) / m from the onset, to the end of the push."""
    def rhs(t, y):
        return [y[1], (-SPRING * y[0] - force(n, damping, y[0], y[1])) / M]

    def push_ends(t, y):  # the force reaches zero (or the mass leaves)
        return min(force(n, damping, y[0], y[1]), y[0]) if t > 0 else 1.0
    push_ends.terminal, push_ends.direction = True, -1

    def force_peaks(t, y):  # dF/dt = 0
        x, v = max(y[0], 0.0), y[1]
        a = rhs(t, y)[1]
        if damping.get("damping") == "hunt_crossley":
            h = 1.5 * (1.0 - damping["e"]) / V0
            return n * K * x ** (n - 1) * v * (1 + h * v) + K * x ** n * h * a
        return n * K * x ** (n - 1) * v + damping.get("C", 0.0) * a
    force_peaks.direction = -1

    sol = solve_ivp(rhs, (0.0, STOP), [0.0, V0], method="DOP853", rtol=1e-12, atol=1e-20,
                    events=[push_ends, force_peaks], dense_output=True)
    end = sol.t_events[0][0]
    t_peak = sol.t_events[1][0]
    x, v = sol.sol(t_peak)
    return end, force(n, damping, x, v)


def peak_of(t, f):
    """The largest sample, refined by the parabola through it and its neighbours."""
    i = int(np.argmax(f))
    (f0, f1, f2), h = f[i - 1:i + 2], t[i + 1] - t[i]
    d = 0.5 * (f0 - f2) / (f0 - 2 * f1 + f2)
    return f1 - 0.25 * (f0 - f2) * d


CASES = [(1.0, {"damping": "hunt_crossley", "e": 0.8}), (1.1, {"damping": "hunt_crossley", "e": 0.8}),
         (1.0, {"C": 40.0}), (1.1, {"C": 40.0})]


@pytest.mark.parametrize("n,damping", CASES, ids=lambda c: str(c))
def test_a_dropped_mass_matches_an_independent_integration(tmp_path, n, damping):
    path = tmp_path / "drop.json"
    path.write_text(json.dumps(scene(n, damping)))
    subprocess.run([str(BEAMSTOP), "run", str(path), "--out", str(tmp_path)], check=True, capture_output=True)
    rows = list(csv.DictReader(open(tmp_path / "PowerLawDrop.csv")))
    t = np.array([float(r["time"]) for r in rows])
    f = np.array([float(r["stop.force"]) for r in rows])
    events = list(csv.DictReader(open(tmp_path / "PowerLawDrop_events.csv")))
    onset = [float(e["time"]) for e in events if e["event"] == "contact"]
    # The push ends where the force reaches zero: a separation (p = 0) or,
    # with linear damping, the point left inside the surface without force.
    ends = [float(e["time"]) for e in events if e["event"] != "contact"]
    assert onset == [0.0], events
    end_ref, peak_ref = reference(n, damping)
    duration = ends[0] - onset[0]
    assert abs(duration - end_ref) <= 1e-8 * end_ref, (duration, end_ref, events)
    peak = peak_of(t, f)
    assert abs(peak - peak_ref) <= 1e-8 * peak_ref, (peak, peak_ref)
    # Energy: the structure's, the stop's stored and dissipated energies
    # sum to the impact's kinetic energy: to 1e-10 of it once the contact
    # is over, to 1e-9 at every output point (an output a fraction of a
    # nanosecond before a separation's t^n corner is the least accurate).
    e0 = 0.5 * M * V0 ** 2
    total = np.array([float(r["energy"]) + float(r["stop.E_stored"]) + float(r["stop.E_dissipated"]) for r in rows])
    after = t > ends[-1]
    assert np.max(np.abs(total[after] - e0)) <= 1e-10 * e0, np.max(np.abs(total[after] - e0)) / e0
    assert np.max(np.abs(total - e0)) <= 1e-9 * e0, np.max(np.abs(total - e0)) / e0


def test_at_one_and_a_half_it_is_hertz_on_the_hertz_stop(tmp_path):
    """HertzStop's scene with its law written as a power law of n = 1.5: the
    same contacts, tip motion within 1e-12 of the gap at every millisecond."""
    hertz = json.loads((ROOT / "scenes" / "hertz_stop.json").read_text())
    power = json.loads(json.dumps(hertz))
    power["stops"][0]["law"] = {"type": "power_law", "n": 1.5, **{k: v for k, v in hertz["stops"][0]["law"].items() if k != "type"}}
    out = {}
    for name, s in [("hertz", hertz), ("power", power)]:
        (tmp_path / f"{name}.json").write_text(json.dumps(s))
        subprocess.run([str(BEAMSTOP), "run", str(tmp_path / f"{name}.json"), "--step", "1e-3", "--out", str(tmp_path / name)],
                       check=True, capture_output=True)
        rows = list(csv.DictReader(open(tmp_path / name / "HertzStop.csv")))
        out[name] = (np.array([float(r["tip.w"]) for r in rows]), int(rows[-1]["stop.contacts"]))
    gap = hertz["stops"][0]["gap"]
    assert out["hertz"][1] == out["power"][1] > 100, (out["hertz"][1], out["power"][1])
    worst = np.max(np.abs(out["hertz"][0] - out["power"][0]))
    assert worst <= 1e-12 * gap, worst / gap


def test_on_a_rotating_beams_surface_at_one_and_a_half_it_is_hertz(tmp_path):
    """RotatingBeamImpact with its surface's law written as a power law of
    n = 1.5: the same 12 contacts, the tip within 1e-8 of its largest
    deflection (the integration is adaptive: rounding-level differences in
    the force move its steps; measured 1.2e-10)."""
    hertz = json.loads((ROOT / "scenes" / "rotating_beam.json").read_text())
    power = json.loads(json.dumps(hertz))
    power["surface"]["law"] = {**hertz["surface"]["law"], "type": "power_law", "n": 1.5}
    out = {}
    for name, s in [("hertz", hertz), ("power", power)]:
        (tmp_path / f"{name}.json").write_text(json.dumps(s))
        subprocess.run([str(BEAMSTOP), "run", str(tmp_path / f"{name}.json"), "--out", str(tmp_path / name)], check=True, capture_output=True)
        rows = list(csv.DictReader(open(tmp_path / name / "RotatingBeamImpact.csv")))
        out[name] = (np.array([float(r["tip.w"]) for r in rows]), int(rows[-1]["stop.contacts"]))
    assert out["hertz"][1] == out["power"][1] == 12
    scale = np.max(np.abs(out["hertz"][0]))
    assert np.max(np.abs(out["hertz"][0] - out["power"][0])) <= 1e-8 * scale
