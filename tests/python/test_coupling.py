"""The controller-coupling example (python/beamstop_tools/coupling, scripts/coupling),
shortened: a PD controller slews RotatingBeamImpact.fmu until the tip rests
against the surface, through fmpy and through OSP libcosim with
PDController.fmu (examples/coupling/pd_controller, built here with cargo).

Physics asserted on the run:
- the hub ends at the static rest angle: a PD torque Kp (theta_ref - theta)
  balanced by a cantilever held on the surface by its tip (exact cantilever
  compliance L^3 / 3 EI, Hertz penetration), within the error of 6 modes;
- at rest the contact force balances the torque about the axis,
  F x_tip = torque within 1 % (the force averaged exactly, as impulse over
  time, over the final stretch), and so does the root bending moment;
- libcosim (fixed-step, Jacobi) and the fmpy loop in the same ordering give
  the same trajectory bit for bit.
"""
from __future__ import annotations

import dataclasses
import random
import shutil
import zipfile

import numpy as np
import pytest

from beamstop_tools.coupling import controller, runs, system as osp
from beamstop_tools.coupling.pd_slew import analyse, beam_data, compare, plant_frequencies, static_rest
from conftest import FMU_DIR

BEAM_FMU = FMU_DIR / "RotatingBeamImpact.fmu"
T_END = 1.3      # s: the slew, impacts and chatter (the last onset near 0.95 s), then pressed
WINDOW = 0.3     # s: the final stretch averaged as "at rest"


@pytest.fixture(scope="module")
def controller_fmu(tmp_path_factory):
    if shutil.which("cargo") is None:
        pytest.skip("cargo is needed to build PDController.fmu")
    out = tmp_path_factory.mktemp("coupling") / "PDController.fmu"
    return controller.build_fmu(out)


@pytest.fixture(scope="module")
def structure(controller_fmu, tmp_path_factory):
    """The example's system structure, pointing at the FMUs under test."""
    assert BEAM_FMU.is_file(), f"{BEAM_FMU} missing: run `cargo run --release -- package` first"
    sys_ = osp.load()
    sims = dict(sys_.simulators)
    sims["beam"] = dataclasses.replace(sims["beam"], fmu=BEAM_FMU)
    sims["controller"] = dataclasses.replace(sims["controller"], fmu=controller_fmu)
    # libcosim reads the file: write a copy with these sources
    text = sys_.path.read_text()
    text = text.replace('source="../../target/fmu/RotatingBeamImpact.fmu"', f'source="{BEAM_FMU.as_posix()}"')
    text = text.replace('source="../../target/coupling/PDController.fmu"', f'source="{controller_fmu.as_posix()}"')
    path = tmp_path_factory.mktemp("osp") / "OspSystemStructure.xml"
    path.write_text(text)
    loaded = osp.load(path)
    assert loaded.simulators["beam"].fmu == BEAM_FMU and loaded.simulators["controller"].fmu == controller_fmu
    return loaded


def test_controller_fmu_passes_fmpy_validation(controller_fmu):
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(controller_fmu)) == []


def test_controller_fmu_carries_only_its_kind(controller_fmu):
    """Each FMU carries only what its scene needs: the controller's binary
    links beamstop's FMI layer but none of beamstop's own kinds (no contact
    laws, no modal or rotating simulation)."""
    with zipfile.ZipFile(controller_fmu) as z:
        binary = z.read("binaries/linux64/PDController.so")
    with zipfile.ZipFile(BEAM_FMU) as z:
        beam_binary = z.read("binaries/linux64/RotatingBeamImpact.so")
    for marker in (b"lankarani_nikravesh", b"RotatingBeam"):
        assert marker in beam_binary, marker
        assert marker not in binary, f"PDController.so carries {marker!r}"
    assert len(binary) < len(beam_binary), (len(binary), len(beam_binary))


def test_controller_fmu_and_its_python_mirror_agree_bit_for_bit(controller_fmu, tmp_path):
    """Random inputs, saturation and the anti-windup included."""
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(controller_fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    with zipfile.ZipFile(controller_fmu) as z:
        z.extractall(tmp_path)
    params = {"Kp": 80.0, "Kd": 10.0, "Ki": 40.0, "theta_ref": 0.02, "theta_start": -0.5, "T_slew": 0.3,
              "torque_max": 5.0}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=str(tmp_path), modelIdentifier="PDController", instanceName="c")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setReal([vr[k] for k in params], list(params.values()))
    fmu.setReal([vr["theta"], vr["theta_dot"]], [-0.5, 0.0])
    law = controller.Controller.from_values(params)
    assert fmu.getReal([vr["torque"]])[0] == law.law(0.0, -0.5, 0.0).torque
    fmu.exitInitializationMode()
    rng = random.Random(3)
    t, h = 0.0, 1e-3
    saturated = 0
    for k in range(600):
        theta, theta_dot = rng.uniform(-0.6, 0.1), rng.uniform(-3, 3)
        fmu.setReal([vr["theta"], vr["theta_dot"]], [theta, theta_dot])
        fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        expected = law.step(t, h, theta, theta_dot)
        torque, ref, integral = fmu.getReal([vr["torque"], vr["theta_r"], vr["integral"]])
        assert (torque, ref, integral) == (expected.torque, expected.reference, law.integral), f"step {k}"
        saturated += abs(torque) == params["torque_max"]
        t = (k + 1) * h
    assert 0 < saturated < 600
    fmu.terminate()
    fmu.freeInstance()


@pytest.fixture(scope="module")
def fmpy_run(structure):
    return runs.run_fmpy(structure, T_END, "jacobi")


@pytest.fixture(scope="module")
def libcosim_run(structure):
    pytest.importorskip("libcosimpy")
    return runs.run_libcosim(structure, T_END)


@pytest.fixture(scope="module")
def figures(structure, fmpy_run):
    d = beam_data(structure)
    c = {k: float(structure.simulators["controller"].initial[k]) for k in controller.PARAMETERS}
    return analyse(fmpy_run, d, c, WINDOW), d, c


def test_the_slew_strikes_the_surface_and_ends_pressed_against_it(figures, fmpy_run):
    fig, d, c = figures
    assert fig["first_contact"] is not None and fig["contacts"] >= 2
    assert fig["last_onset"] < T_END - WINDOW, "still bouncing in the final stretch"
    assert fig["contact_fraction_end"] == 1.0
    # the torque limit bounds the controller's output
    assert np.max(np.abs(fmpy_run["torque"])) <= c["torque_max"]


def test_the_hub_rests_at_the_static_angle(figures):
    fig, d, c = figures
    rest = static_rest(d, c)
    # the surface angle is 0; the hub rests past it by the tip's elastic deflection
    assert 0.0 < fig["theta_end"] < 2e-3
    assert fig["theta_end_span"] < 2e-5
    # 6 clamped-free modes carry the static tip compliance to ~1e-4; Hertz and geometric nonlinearity included
    assert fig["theta_end"] == pytest.approx(rest["theta"], rel=2e-3)
    assert fig["torque_end"] == pytest.approx(rest["torque"], rel=1e-3)


def test_at_rest_the_contact_force_balances_the_torque(figures):
    fig, d, _ = figures
    assert abs(fig["balance_rel"]) < 0.01, f"F x_tip / torque - 1 = {fig['balance_rel']:.3e}"
    assert abs(fig["root_M_rel"]) < 0.01, f"|root.M| / torque - 1 = {fig['root_M_rel']:.3e}"
    # root.M is a 6-mode sum: short of F L by what 6 clamped-free modes miss of a static tip force's root moment
    expected = plant_frequencies(d)["modal_root_moment"] - 1.0
    assert -0.01 < expected < -0.003
    assert fig["root_M_rel"] == pytest.approx(expected, abs=1e-3)


def test_libcosim_and_fmpy_agree(fmpy_run, libcosim_run):
    diff = compare(fmpy_run, libcosim_run)
    assert np.array_equal(fmpy_run["time"], libcosim_run["time"])
    assert diff["identical"], {k: v for k, v in diff.items() if k != "identical" and v}
