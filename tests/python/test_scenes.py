"""Every scene's FMU: valid for fmpy, carrying exactly its own variables with
their units, simulating like the native run; a bad scene writes no FMU."""

import csv
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from conftest import FMU_DIR, ROOT, native_beamstop

SCENES = {
    "PinnedBeamStop": "pinned_beam",
    "WaggBishopChain": "wagg_bishop_chain",
    "WaggBishopCantilever1": "wagg_bishop_cantilever_1mode",
    "WaggBishopCantilever4": "wagg_bishop_cantilever_4mode",
    "SteelCantileverStop": "steel_cantilever",
    "SpringStopSoft": "spring_stop_soft",
    "SpringStopHard": "spring_stop_hard",
    "SpringStopVeryHard": "spring_stop_very_hard",
    "HertzStop": "hertz_stop",
    "RotatingBeamImpact": "rotating_beam",
    "SpinUpBeam": "spin_up",
    "TappingArm": "tapping_arm",
}

def modal(n, *patterns):
    return {p.format(j=j) for p in patterns for j in range(1, n + 1)}

STOP_OUTPUTS = {"w", "v", "impacts", "t_last_impact", "sticking", "sticks", "stuck_time", "lambda", "impulse"}
SPRING_STOP_OUTPUTS = {"w", "v", "force", "penetration", "contact", "contacts", "t_last_contact", "E_stored", "E_dissipated", "impulse"}

# What each FMU must expose, written out by hand from the scene descriptions.
EXPECTED = {
    "WaggBishopChain": {
        "A1.amplitude", "A1.omega", "stop.R", "stop.eps", "stop.gap",
        *(f"stop.{o}" for o in STOP_OUTPUTS), "x1.w", "x1.v", "energy", "impact_energy",
    } | modal(2, "q0[{j}]", "qd0[{j}]", "q[{j}]", "qd[{j}]", "FE[{j}]", "DE[{j}]"),
    "WaggBishopCantilever1": {
        "base.amplitude", "base.omega", "zeta", "tip_stop.R", "tip_stop.eps", "tip_stop.gap", "tip_stop.x",
        *(f"tip_stop.{o}" for o in STOP_OUTPUTS), "tip.x", "root.x", "tip.w", "tip.v", "root.M",
        "energy", "impact_energy",
    } | modal(1, "q0[{j}]", "qd0[{j}]", "q[{j}]", "qd[{j}]", "FE[{j}]", "DE[{j}]"),
    "SteelCantileverStop": {
        "shaker.amplitude", "shaker.omega", "zeta", "stop.R", "stop.eps", "stop.gap", "stop.x",
        *(f"stop.{o}" for o in STOP_OUTPUTS), "tip.x", "clamp.x", "tip.w", "tip.v", "clamp.M",
        "force.x", "force", "a_clamp", "energy",
    } | modal(8, "q0[{j}]", "qd0[{j}]"),
}
for name, modes in (("SpringStopSoft", 5), ("SpringStopHard", 20), ("SpringStopVeryHard", 20)):
    EXPECTED[name] = {
        "shaker.amplitude", "shaker.omega", "zeta", "stop.k", "stop.c", "stop.gap", "stop.x",
        *(f"stop.{o}" for o in SPRING_STOP_OUTPUTS), "tip.x", "root.x", "tip.w", "tip.v", "root.M", "energy",
    } | modal(modes, "q0[{j}]", "qd0[{j}]")
# The Hertz stop: K and the restitution its Lankarani-Nikravesh damping aims at.
EXPECTED["HertzStop"] = {
    "shaker.amplitude", "shaker.omega", "zeta", "stop.K", "stop.e", "stop.gap", "stop.x",
    *(f"stop.{o}" for o in SPRING_STOP_OUTPUTS), "tip.x", "root.x", "tip.w", "tip.v", "root.M", "energy",
    "solver.integration_tolerance",
} | modal(20, "q0[{j}]", "qd0[{j}]")
EXPECTED["WaggBishopCantilever4"] = (EXPECTED["WaggBishopCantilever1"] - modal(1, "q0[{j}]", "qd0[{j}]", "q[{j}]", "qd[{j}]", "FE[{j}]", "DE[{j}]")) | modal(
    4, "q0[{j}]", "qd0[{j}]", "q[{j}]", "qd[{j}]", "FE[{j}]", "DE[{j}]")

# The rotating hub beam (DWZ): the hub, the tip, the root moment, and
# the surface's outputs only where the scene has a surface; the spin-up's hub
# motion is prescribed, so it has no torque input but the torque it needs.
ROTATING_OUTPUTS = {"theta", "theta_dot", "tip.w", "tip.x", "tip.y", "root.M", "energy"}
EXPECTED["RotatingBeamImpact"] = {"J_h", "K", "e", "theta0", "theta_dot0", "torque", "solver.tolerance"} | ROTATING_OUTPUTS | {
    f"stop.{o}" for o in ("force", "penetration", "contact", "contacts", "impulse", "E_dissipated")}
EXPECTED["SpinUpBeam"] = {"J_h", "theta0", "omega_s", "T", "hub.torque", "solver.tolerance"} | ROTATING_OUTPUTS
# The tapping arm: a swinging hub (theta0 + A sin(Omega t)), damped modes, a Hertz surface.
EXPECTED["TappingArm"] = {"J_h", "K", "e", "zeta", "theta0", "A", "Omega", "hub.torque", "solver.tolerance"} | ROTATING_OUTPUTS | {
    f"stop.{o}" for o in ("force", "penetration", "contact", "contacts", "impulse", "E_dissipated")}

SI_UNITS = {"tip.w": "m", "tip.v": "m/s", "clamp.M": "N.m", "stop.lambda": "N", "stop.t_last_impact": "s",
            "shaker.amplitude": "m/s2", "shaker.omega": "rad/s", "force": "N", "a_clamp": "m/s2",
            "stop.gap": "m", "energy": "J", "stop.eps": "s", "q0[1]": "m", "qd0[1]": "m/s"}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_every_fmu_validates(name):
    problems = validate_fmu(str(FMU_DIR / f"{name}.fmu"))
    assert problems == [], problems


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_each_fmu_lists_exactly_its_own_variables(name):
    md = read_model_description(str(FMU_DIR / f"{name}.fmu"))
    assert {v.name for v in md.modelVariables} == EXPECTED[name]


def test_si_variables_carry_their_units():
    md = read_model_description(str(FMU_DIR / "SteelCantileverStop.fmu"))
    units = {v.name: v.unit for v in md.modelVariables}
    for name, unit in SI_UNITS.items():
        assert units[name] == unit, (name, units[name])
    defined = {u.name for u in md.unitDefinitions}
    assert {u for u in units.values() if u} <= defined


@pytest.mark.parametrize("name", sorted(SCENES))
def test_default_experiment_matches_the_native_run(name, tmp_path):
    md = read_model_description(str(FMU_DIR / f"{name}.fmu"))
    exp = md.defaultExperiment
    stop = min(float(exp.stopTime), 20.0 * float(exp.stepSize) * 100)
    step = float(exp.stepSize)
    outputs = [v.name for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
    result = simulate_fmu(str(FMU_DIR / f"{name}.fmu"), stop_time=stop, output_interval=step, output=outputs)
    scene = ROOT / "scenes" / f"{SCENES[name]}.json"
    subprocess.run(native_beamstop() + ["run", str(scene), "--stop", repr(stop), "--step", repr(step), "--out", str(tmp_path)],
                   check=True, capture_output=True)
    with open(tmp_path / f"{name}.csv") as f:
        native = list(csv.DictReader(f))
    last = native[-1]
    assert abs(float(last["time"]) - result["time"][-1]) < 1e-9
    for o in outputs:
        a, b = result[o][-1], float(last[o])
        assert abs(a - b) <= 1e-10 * max(1.0, abs(b)), (o, a, b)


@pytest.mark.parametrize("name", sorted(SCENES))
@pytest.mark.parametrize("steps", [1, 10])
def test_the_whole_horizon_runs_in_one_or_ten_steps(name, steps):
    # The work cap catches runaway work only: a master may step over the
    # whole default experiment at default settings.
    exp = read_model_description(str(FMU_DIR / f"{name}.fmu")).defaultExperiment
    stop = float(exp.stopTime)
    result = simulate_fmu(str(FMU_DIR / f"{name}.fmu"), stop_time=stop, output_interval=stop / steps)
    assert result["time"][-1] == pytest.approx(stop)


def test_the_tolerance_parameter_trades_accuracy_for_work():
    # HertzStop's tolerance is a parameter: over its first contacts the
    # answer moves towards the tightest one as the tolerance falls, and
    # stays within 1000 times the tolerance asked (of the gap; measured
    # 10 to 400 times over 21 contacts in 0.2 s).
    fmu = str(FMU_DIR / "HertzStop.fmu")
    common = dict(stop_time=0.1, output_interval=1e-4, output=["tip.w", "stop.contacts"])
    tight = simulate_fmu(fmu, start_values={"solver.integration_tolerance": 1e-13}, **common)
    assert tight["stop.contacts"][-1] >= 4
    errors = []
    for tolerance in (1e-4, 1e-8):
        asked = simulate_fmu(fmu, start_values={"solver.integration_tolerance": tolerance}, **common)
        errors.append(np.max(np.abs(asked["tip.w"] - tight["tip.w"])) / 1e-3)
        assert errors[-1] < 1e3 * tolerance, (tolerance, errors[-1])
    assert errors[0] > 10 * errors[1] > 0.0, errors


@pytest.mark.parametrize("mutation, message", [
    (lambda s: s["stops"][0].__setitem__("gapp", s["stops"][0].pop("gap")), "unknown field `gapp`"),
    (lambda s: s["stops"][0]["law"].__setitem__("R", 1.5), "stops[0].law.R"),
    (lambda s: s["structure"].__setitem__("modes", 0), "structure.modes = 0"),
    (lambda s: s["stops"][0].__setitem__("x", 1.4), "stops[0].x"),
])
def test_a_bad_scene_is_refused_and_no_fmu_is_written(mutation, message, tmp_path):
    scene = json.loads((ROOT / "scenes" / "pinned_beam.json").read_text())
    scene["name"] = "BadScene"
    mutation(scene)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(scene))
    fmu = FMU_DIR / "BadScene.fmu"
    fmu.unlink(missing_ok=True)
    run = subprocess.run(native_beamstop() + ["package", str(path)], capture_output=True, text=True)
    assert run.returncode != 0
    assert message in run.stderr, run.stderr
    assert not fmu.exists()
