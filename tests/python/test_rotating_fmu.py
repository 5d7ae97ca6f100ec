"""The rotating hub beam FMUs (DWZ: RotatingBeamImpact.fmu, the paper's
aluminium beam striking a plane with Hertz contact; SpinUpBeam.fmu, the
Kane-Ryan-Banerjee spin-up) stepped through fmpy, checked against
conservation laws the FMU does not impose itself:

- work of the hub torque = change of the structure's energy + the energy the
  contact dissipated (both read from the FMU, computed from different
  quantities: the state, and the integrated damping power);
- the contact impulse per step sums to the integral of the contact force;
- results do not depend on the communication step, and a serialized state
  restored in a fresh instance continues bit for bit;
- bad values are refused with the variable's name and allowed range, and the
  instance stays usable."""

import shutil
from pathlib import Path

import numpy as np
import pytest
from ctypes import byref

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, fmi2CoSimulation

from conftest import FMU_DIR, LogCapture

IMPACT = FMU_DIR / "RotatingBeamImpact.fmu"
SPIN = FMU_DIR / "SpinUpBeam.fmu"


class Unit:
    """One instance of an FMU, with get/set by name and a message log."""

    def __init__(self, fmu: Path, name="u"):
        self.md = read_model_description(str(fmu))
        self.dir = extract(str(fmu))
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.log = LogCapture()
        s = self.slave = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                                   modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        s.callbacks = self.log.callbacks
        s.component = s.fmi2Instantiate(name.encode(), fmi2CoSimulation, s.guid.encode(),
                                        Path(self.dir, "resources").as_uri().encode(), byref(s.callbacks), 0, 0)
        assert s.component, self.log.text()
        self.t = 0.0

    def start(self, values=None, t0=0.0):
        self.slave.setupExperiment(startTime=t0)
        self.slave.enterInitializationMode()
        for k, v in (values or {}).items():
            self.set(k, v)
        self.slave.exitInitializationMode()
        self.t = t0
        return self

    def set(self, name, value):
        self.slave.setReal([self.vars[name].valueReference], [value])

    def get(self, name):
        v = self.vars[name]
        if v.type == "Real":
            return self.slave.getReal([v.valueReference])[0]
        if v.type == "Integer":
            return self.slave.getInteger([v.valueReference])[0]
        return self.slave.getBoolean([v.valueReference])[0]

    def outputs(self):
        return {n: self.get(n) for n, v in self.vars.items() if v.causality == "output"}

    def step(self, h):
        self.slave.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
        self.t += h

    def close(self):
        self.slave.terminate()
        self.slave.freeInstance()
        shutil.rmtree(self.dir, ignore_errors=True)


def run(fmu, values, t_end, h, extra=None):
    u = Unit(fmu).start(values)
    rows = [dict(time=0.0, **u.outputs())]
    n = int(round(t_end / h))
    for k in range(n):
        if extra:
            extra(u, k)
        u.step(h)
        rows.append(dict(time=u.t, **u.outputs()))
    u.close()
    return {k: np.array([r[k] for r in rows], dtype=float) for k in rows[0]}


def test_work_of_the_torque_equals_energy_gained_plus_dissipated():
    # Start 0.3 rad before the surface at rest and push with a constant
    # torque: the tip strikes at about 1.9 rad/s and chatters (13 contacts)
    # before the hub swings back. Radau IIA is not symplectic: the balance
    # holds to the integration tolerance (1e-10) times the steps taken.
    tau, theta0 = 2.0, -0.3
    r = run(IMPACT, {"theta0": theta0, "theta_dot0": 0.0}, 0.4, 1e-3, extra=lambda u, k: u.set("torque", tau))
    assert r["stop.contacts"][-1] >= 5
    assert r["stop.force"].max() > 100.0
    work = tau * (r["theta"] - theta0)
    balance = r["energy"] + r["stop.E_dissipated"] - r["energy"][0] - work
    scale = np.max(np.abs(work))
    assert np.max(np.abs(balance)) < 1e-7 * scale, np.max(np.abs(balance)) / scale
    assert r["stop.E_dissipated"][-1] > 1e-3 * scale  # the contact did dissipate


def test_spin_up_torque_work_equals_energy_gained():
    # Prescribed spin-up: the work of the torque the motion needs (an output)
    # integrated by Simpson's rule equals the gain in energy.
    h = 0.005
    r = run(SPIN, {}, 15.0, h)
    power = r["hub.torque"] * r["theta_dot"]
    work = np.concatenate([[0.0], np.cumsum((power[:-1:2] + 4 * power[1::2] + power[2::2]) * h / 3)])
    gained = r["energy"][::2] - r["energy"][0]
    assert r["theta_dot"][-1] == pytest.approx(6.0, rel=1e-12)
    assert np.max(np.abs(work - gained)) < 1e-6 * gained[-1], np.max(np.abs(work - gained)) / gained[-1]


def test_contact_impulse_per_step_sums_to_the_force_integral():
    h = 2e-6
    r = run(IMPACT, {}, 0.004, h)
    assert r["stop.contacts"][-1] >= 1
    f = r["stop.force"]
    trapezoid = np.sum((f[1:] + f[:-1]) * h / 2)
    impulses = r["stop.impulse"][1:].sum()
    assert impulses > 0.1
    assert impulses == pytest.approx(trapezoid, rel=2e-4)


def test_results_do_not_depend_on_the_communication_step():
    coarse = run(IMPACT, {}, 0.02, 1e-3)
    fine = run(IMPACT, {}, 0.02, 1e-4)
    assert coarse["stop.contacts"][-1] >= 2
    for name in ("theta", "theta_dot", "tip.w", "stop.force", "root.M", "energy", "stop.E_dissipated"):
        a, b = coarse[name], fine[name][::10]
        scale = np.max(np.abs(b))
        assert np.max(np.abs(a - b)) <= 1e-9 * scale, (name, np.max(np.abs(a - b)) / scale)
    assert np.array_equal(coarse["stop.contacts"], fine["stop.contacts"][::10])


def test_serialized_state_continues_bit_for_bit_in_a_fresh_instance():
    a = Unit(IMPACT, "a").start()
    for _ in range(3):
        a.step(1e-5)  # inside the first contact (t = 0 to 8e-5 s)
    assert a.get("stop.contact")
    state = a.slave.serializeFMUstate(a.slave.getFMUstate())
    t = a.t
    for _ in range(50):
        a.step(1e-4)  # through the next contacts
    expected = a.outputs()
    assert a.get("stop.contacts") >= 3
    b = Unit(IMPACT, "b").start()
    b.slave.setFMUstate(b.slave.deSerializeFMUstate(state))
    b.t = t
    for _ in range(50):
        b.step(1e-4)
    assert b.outputs() == expected
    a.close()
    b.close()


def refusal(u, name, value, *words):
    """The call fails, and its message names the variable and says why (by default: its allowed range)."""
    u.log.clear()
    with pytest.raises(Exception):
        u.set(name, value)
    message = " ".join(u.log.errors())
    for w in (f"'{name}'", *(words or ["allowed"])):
        assert w in message, message


@pytest.mark.parametrize("name, value, words", [
    ("J_h", 0.0, ["allowed", "(0, "]), ("J_h", -1.0, ["allowed"]), ("theta_dot0", 1e7, ["allowed", "87.757"]),
    ("K", -1.0, ["allowed", "10000000000000000]"]), ("e", 1.5, ["allowed", "[0, 1]"]), ("theta0", float("nan"), ["allowed", "10000"])])
def test_bad_parameters_are_refused_naming_the_variable_and_range(name, value, words):
    u = Unit(IMPACT)
    u.slave.setupExperiment(startTime=0.0)
    u.slave.enterInitializationMode()
    refusal(u, name, value, *words)
    u.slave.exitInitializationMode()  # the refused value changed nothing
    assert u.get(name) == float(u.vars[name].start)
    u.step(1e-3)
    assert np.isfinite(u.get("theta"))
    u.close()


def test_fixed_parameters_and_out_of_range_torque_are_refused_after_initialisation():
    u = Unit(IMPACT).start()
    u.step(1e-3)
    theta = u.get("theta")
    refusal(u, "J_h", 0.1, "fixed parameter")
    refusal(u, "torque", 1e12, "allowed", "input")
    assert u.get("J_h") == 0.05 and u.get("torque") == 0.0
    u.set("torque", 5.0)
    u.step(1e-3)
    assert u.get("theta") != theta
    u.close()
