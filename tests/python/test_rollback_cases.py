"""The rollback cases co-simulation masters met, through the FMI calls
(issue 41): an input set just before a save, a state saved in event mode
taken to an instance without event mode, start times the clock cannot
resolve, and early returns only at the events the log reports. The
engine-level cases (tolerances, departing flags, pending switches,
corrupted times) are tests/integration/rollback.rs; freeing an instance's states is
checked under valgrind (tests/c/drive_fmu*.c)."""

from __future__ import annotations

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave, fmi3LogMessageCallback

from conftest import FMU_DIR, ROOT

FMU3_DIR = ROOT / "target" / "fmu3"


class Unit2:
    def __init__(self, name: str, instance: str = "a"):
        fmu = str(FMU_DIR / f"{name}.fmu")
        self.md = read_model_description(fmu)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.s = FMU2Slave(guid=self.md.guid, unzipDirectory=extract(fmu), modelIdentifier=self.md.coSimulation.modelIdentifier,
                           instanceName=instance)
        self.s.instantiate()
        self.outputs = [v for v in self.md.modelVariables if v.causality == "output"]

    def start(self, t=0.0):
        self.s.setupExperiment(startTime=t)
        self.s.enterInitializationMode()
        self.s.exitInitializationMode()

    def read(self):
        reals = [v.valueReference for v in self.outputs if v.type == "Real"]
        ints = [v.valueReference for v in self.outputs if v.type == "Integer"]
        bools = [v.valueReference for v in self.outputs if v.type == "Boolean"]
        return ([x.hex() for x in self.s.getReal(reals)], list(self.s.getInteger(ints)) if ints else [],
                list(self.s.getBoolean(bools)) if bools else [])


def test_an_input_set_before_a_save_is_resolved_and_the_state_restores():
    """PinnedBeamStop starts stuck on its stop; force = -1 set at t = 0 makes
    the reaction pull. Before any step the outputs show the beam released
    (no pulling reaction), and the state saved then (an iterating master's
    order: set inputs, save, step, restore, step) restores and steps on bit
    for bit."""
    u = Unit2("PinnedBeamStop")
    u.start()
    assert u.s.getBoolean([u.vr["sticking"]]) == [True]
    u.s.setReal([u.vr["force"]], [-1.0])
    assert u.s.getBoolean([u.vr["sticking"]]) == [False]
    assert u.s.getReal([u.vr["lambda"]])[0] <= 0.0
    state = u.s.getFMUstate()
    blob = u.s.serializeFMUstate(state)
    u.s.doStep(0.0, 0.1)
    first = u.read()
    u.s.setFMUstate(u.s.deSerializeFMUstate(blob))
    u.s.doStep(0.0, 0.1)
    assert u.read() == first
    u.s.terminate()
    u.s.freeInstance()


def test_a_state_saved_in_event_mode_is_refused_by_an_instance_without_it():
    """A state carries the choices of the instance that saved it: one saved
    in event mode (an impact pending) restores into an instance with event
    mode, and an instance made with eventModeUsed = false refuses it, as
    serialized bytes and as a state pointer, and stays usable."""
    fmu = str(FMU3_DIR / "PinnedBeamStop.fmu")
    md = read_model_description(fmu)
    here = extract(fmu)
    messages = []

    @fmi3LogMessageCallback
    def log(env, status, category, message):
        messages.append(message.decode())

    def unit(name, event_mode):
        s = FMU3Slave(guid=md.guid, unzipDirectory=here, modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        s.instantiate(eventModeUsed=event_mode, earlyReturnAllowed=event_mode, logMessage=log)
        s.enterInitializationMode(startTime=0.0)
        s.exitInitializationMode()
        if event_mode:
            s.updateDiscreteStates()
            s.enterStepMode()
        return s

    saver = unit("saver", True)
    event, _, early, at = saver.doStep(0.0, 100.0)
    assert event and early
    saver.enterEventMode()
    state = saver.getFMUState()
    blob = saver.serializeFMUState(state)
    other = unit("other", False)
    with pytest.raises(FMICallException):
        other.deserializeFMUState(blob)
    assert "eventModeUsed = false" in messages[-1], messages[-1]
    with pytest.raises(FMICallException):
        other.setFMUState(state)
    other.doStep(0.0, 0.5)  # refused, and still usable
    with_event_mode = unit("with", True)
    with_event_mode.setFMUState(with_event_mode.deserializeFMUState(blob))
    saver.freeFMUState(state)
    for s in (saver, other, with_event_mode):
        s.freeInstance()


def test_a_state_with_an_event_pending_in_step_mode_restores_without_event_mode():
    """A state saved in step mode after an early return at an impact, the
    importer not having entered event mode (the change still pending),
    restores into an instance made without event mode: its next step makes
    the change first, as the saving instance's does, bit for bit (the FMI
    3.0 fuzzer, RotatingBeamImpact seed 9107, found it refused)."""
    fmu = str(FMU3_DIR / "PinnedBeamStop.fmu")
    md = read_model_description(fmu)
    here = extract(fmu)
    vrs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Float64"]

    def unit(name, event_mode):
        s = FMU3Slave(guid=md.guid, unzipDirectory=here, modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        s.instantiate(eventModeUsed=event_mode, earlyReturnAllowed=event_mode)
        s.enterInitializationMode(startTime=0.0)
        s.exitInitializationMode()
        if event_mode:
            s.updateDiscreteStates()
            s.enterStepMode()
        return s

    saver = unit("saver", True)
    event, _, early, at = saver.doStep(0.0, 100.0)
    assert event and early
    blob = saver.serializeFMUState(saver.getFMUState())
    other = unit("other", False)
    other.setFMUState(other.deserializeFMUState(blob))
    assert other.getFloat64(vrs) == saver.getFloat64(vrs), "the values before the impact"
    assert saver.doStep(at, 1e-3)[:3] == (False, False, False), "no event in the step"
    other.doStep(at, 1e-3)
    assert [x.hex() for x in other.getFloat64(vrs)] == [x.hex() for x in saver.getFloat64(vrs)]
    # and the state the restored instance writes restores again
    again = unit("again", False)
    again.setFMUState(again.deserializeFMUState(other.serializeFMUState(other.getFMUState())))
    for s in (saver, other, again):
        s.freeInstance()


def test_a_state_terminated_with_an_event_pending_restores():
    """Terminated right after a step that returned at an event, its change
    not made: the state saved then restores (it was refused as "an event
    pending in instance state Terminated": the FMI 3.0 fuzzer,
    SpringStopHard seed 9111)."""
    fmu = str(FMU3_DIR / "PinnedBeamStop.fmu")
    md = read_model_description(fmu)
    s = FMU3Slave(guid=md.guid, unzipDirectory=extract(fmu), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="terminated")
    s.instantiate(eventModeUsed=True, earlyReturnAllowed=True)
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    s.updateDiscreteStates()
    s.enterStepMode()
    event, _, early, at = s.doStep(0.0, 100.0)
    assert event and early
    s.terminate()
    blob = s.serializeFMUState(s.getFMUState())
    s.setFMUState(s.deserializeFMUState(blob))
    s.freeInstance()


def test_a_change_that_fails_at_an_early_return_leaves_a_plain_error_state():
    """Without event mode the FMU makes an early return's discrete change
    itself. HertzStop started at t = 1e6 with mode 15 at 41,665 m/s (inside
    its range) needs contact steps the time cannot resolve there: the change
    at the first onset fails, saying so. The instance is then in the Error
    state, and the state it saves is refused as that (the FMU restores no
    Error state), not as one with an event left pending (the fuzzer's seed
    9102 found it)."""
    fmu = str(FMU3_DIR / "HertzStop.fmu")
    md = read_model_description(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    messages = []

    @fmi3LogMessageCallback
    def log(env, status, category, message):
        messages.append(message.decode())

    s = FMU3Slave(guid=md.guid, unzipDirectory=extract(fmu), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="early")
    s.instantiate(eventModeUsed=False, earlyReturnAllowed=True, logMessage=log)
    s.enterInitializationMode(startTime=1e6, stopTime=1e6 + 1.0)
    s.setFloat64([vr["qd0[15]"]], [41665.2597365613])
    s.exitInitializationMode()
    with pytest.raises(FMICallException):
        s.doStep(1e6, 1e-4)
    assert "the resolution of the time there" in messages[-1], messages[-1]
    state = s.getFMUState()
    blob = s.serializeFMUState(state)
    with pytest.raises(FMICallException):
        s.deserializeFMUState(blob)
    assert "instance state Error cannot be restored" in messages[-1], messages[-1]
    s.freeFMUState(state)
    s.freeInstance()


def test_an_fmi3_instance_refuses_fmi2_s_step_canceled_state():
    """StepCanceled is FMI 2.0's state after fmi2CancelStep. A serialized
    state claiming it was restored into an FMI 3.0 instance, which then
    refused every call, even a restore of a true state (the FMI 3.0
    fuzzer, RotatingBeamImpact seed 9106): it is refused, and the instance
    steps on."""
    import struct

    fmu = str(FMU3_DIR / "PinnedBeamStop.fmu")
    md = read_model_description(fmu)
    messages = []

    @fmi3LogMessageCallback
    def log(env, status, category, message):
        messages.append(message.decode())

    s = FMU3Slave(guid=md.guid, unzipDirectory=extract(fmu), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="canceled")
    s.instantiate(logMessage=log)
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    s.doStep(0.0, 0.1)
    state = s.getFMUState()
    blob = bytearray(s.serializeFMUState(state))
    s.freeFMUState(state)
    # Magic (8 bytes), format version (4), the token's length (4) and the
    # token, then the instance state's code.
    at = 16 + struct.unpack_from("<I", blob, 12)[0]
    assert struct.unpack_from("<I", blob, at)[0] == 4, "saved in step mode"
    struct.pack_into("<I", blob, at, 16)
    with pytest.raises(FMICallException):
        s.deserializeFMUState(bytes(blob))
    assert "StepCanceled is FMI 2.0's" in messages[-1], messages[-1]
    s.doStep(0.1, 0.1)
    s.freeInstance()


@pytest.mark.parametrize("name", ["PinnedBeamStop", "SpinUpBeam", "RotatingBeamImpact", "HertzStop"])
def test_a_start_time_the_clock_cannot_resolve_is_refused_at_once(name):
    """1e300 (FMI 3.0's fmi3EnterInitializationMode) and 1e308 (FMI 2.0's
    fmi2SetupExperiment): refused before any output is computed, by every
    kind; a start the clock resolves is taken."""
    fmu3 = str(FMU3_DIR / f"{name}.fmu")
    md = read_model_description(fmu3)
    s = FMU3Slave(guid=md.guid, unzipDirectory=extract(fmu3), modelIdentifier=md.coSimulation.modelIdentifier, instanceName="a")
    s.instantiate()
    with pytest.raises(FMICallException):
        s.enterInitializationMode(startTime=1e300)
    s.freeInstance()
    u = Unit2(name)
    with pytest.raises(FMICallException):
        u.s.setupExperiment(startTime=1e308)
    u.start(1.0)
    u.s.doStep(1.0, float(md.defaultExperiment.stepSize))
    u.s.freeInstance()


def test_early_returns_come_only_at_logged_events():
    """HertzStop with early return and event mode, stepped at 1e-4 past
    t = 0.3007 s, where a push ends with penetration left and the point
    leaves the stop later: that separation changes no output and is not
    logged, and the step does not return there. One early return per
    logEvents line."""
    fmu = str(FMU3_DIR / "HertzStop.fmu")
    md = read_model_description(fmu)
    lines = []

    @fmi3LogMessageCallback
    def log(env, status, category, message):
        if category == b"logEvents":
            lines.append(message.decode())

    s = FMU3Slave(guid=md.guid, unzipDirectory=extract(fmu), modelIdentifier=md.coSimulation.modelIdentifier, instanceName="a")
    s.instantiate(eventModeUsed=True, earlyReturnAllowed=True, loggingOn=True, logMessage=log)
    s.setDebugLogging(True, ["logEvents"])
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    s.updateDiscreteStates()
    s.enterStepMode()
    lines.clear()
    t, n, returns = 0.0, 0, 0
    while t < 0.302:
        target = (n + 1) * 1e-4
        event, _, early, last = s.doStep(t, target - t)
        t = last
        if event:
            returns += 1
            s.enterEventMode()
            s.updateDiscreteStates()
            s.enterStepMode()
        if not early:
            n += 1
    assert returns == len(lines) > 10, (returns, len(lines))
    s.freeInstance()
