"""The FMI 3.0 co-simulation FMUs (target/fmu3/): compliant with the
standard, equal to the FMI 2.0 FMUs bit for bit without early return, and
with early return and event mode, returning at every event's own time with
the discrete change left to fmi3UpdateDiscreteStates.

Event times are checked against the FMI 2.0 FMU's own event log (logEvents,
`t = <17 digits>: ...`), the free pinned beam's first impact against its
closed form 1/(2 pi).
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from conftest import FREE_FIRST_IMPACT, FREE_VIBRATION, ROOT

FMU2_DIR = ROOT / "target" / "fmu"
FMU3_DIR = ROOT / "target" / "fmu3"
NAMES = sorted(p.stem for p in FMU3_DIR.glob("*.fmu"))

# A short horizon per scene: a few events each (SpinUpBeam has no stop),
# seconds of test time in all.
HORIZON = {
    "HertzStop": 0.1,
    "PinnedBeamStop": 20.0,
    "RigidAndHertzStops": 3.0,
    "RotatingBeamImpact": 0.02,
    "SpinUpBeam": 3.0,
    "SpringStopHard": 0.1,
    "SpringStopSoft": 0.1,
    "SpringStopVeryHard": 0.1,
    "SteelCantileverStop": 0.3,
    "TappingArm": 0.3,
    "WaggBishopCantilever1": 30.0,
    "WaggBishopCantilever4": 30.0,
    "WaggBishopChain": 30.0,
}

ULP4 = 4


def ulps(a: float, b: float) -> float:
    return abs(a - b) / math.ulp(max(abs(a), abs(b)))


def test_every_scene_has_an_fmi3_fmu():
    assert NAMES == sorted(p.stem for p in FMU2_DIR.glob("*.fmu") if p.stem != "PDController")
    assert set(NAMES) == set(HORIZON)


# ------------------------------------------------------------ compliance

@pytest.mark.parametrize("name", NAMES)
def test_validates_and_fmutool_finds_it_compliant(name):
    fmu = FMU3_DIR / f"{name}.fmu"
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    assert md.fmiVersion == "3.0"
    cs = md.coSimulation
    assert cs.hasEventMode and cs.mightReturnEarlyFromDoStep and cs.providesIntermediateUpdate
    assert cs.canReturnEarlyAfterIntermediateUpdate and cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    fmutool = Path(sys.executable).parent / "fmutool"
    out = subprocess.run([str(fmutool), "-input", str(fmu), "-check"], capture_output=True, text=True, timeout=120)
    text = out.stdout + out.stderr
    assert "compliant with FMI-3.0" in text and "No semantic error" in text, text


# ------------------------------------------------------------ FMI 2.0 event log

def fmi2_events(name: str, stop: float, step: float, start_values=None) -> list[float]:
    """The times of the state-changing events the FMI 2.0 FMU logs over
    (start, stop], stepped on a grid of `step`."""
    fmu = FMU2_DIR / f"{name}.fmu"
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    messages = []

    def log(env, instance, status, category, message):
        if category == b"logEvents":
            messages.append(message.decode())

    logger = fmi2CallbackLoggerTYPE(log)
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = logger
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu)), modelIdentifier=md.coSimulation.modelIdentifier, instanceName="ref")
    slave.instantiate(callbacks=callbacks)
    slave.setDebugLogging(True, ["logEvents"])
    start = float(md.defaultExperiment.startTime or 0.0)
    slave.setupExperiment(startTime=start)
    for k, v in (start_values or {}).items():
        slave.setReal([vr[k]], [v])
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    t, n = start, 0
    while t < stop - 1e-12 * max(1.0, stop):
        n += 1
        t_next = min(start + n * step, stop)
        slave.doStep(t, t_next - t)
        t = t_next
    slave.terminate()
    slave.freeInstance()
    times = []
    for m in messages:
        if "grazing" in m:
            continue
        g = re.match(r"t = ([-+0-9.eE]+):", m)
        assert g, m
        te = float(g.group(1))
        if te > start and (not times or te != times[-1]):
            times.append(te)
    return times


# ------------------------------------------------------------ simulate_fmu

@pytest.mark.parametrize("name", NAMES)
def test_without_early_return_equals_fmi2_bit_for_bit(name):
    stop = HORIZON[name]
    step = stop / 40
    r2 = simulate_fmu(str(FMU2_DIR / f"{name}.fmu"), stop_time=stop, output_interval=step)
    r3 = simulate_fmu(str(FMU3_DIR / f"{name}.fmu"), stop_time=stop, output_interval=step)
    assert r2.dtype.names == r3.dtype.names
    for n in r2.dtype.names:
        a, b = r2[n], r3[n]
        assert a.shape == b.shape, n
        same = (a == b) | (np.isnan(a.astype(float)) & np.isnan(b.astype(float)))
        assert same.all(), (name, n, a[~same][:3], b[~same][:3])


@pytest.mark.parametrize("name", NAMES)
def test_early_return_and_event_mode_sample_every_event_before_and_after(name):
    """fmpy's loop with early return and event mode: a row just before and
    one just after every event, at the event's own time (the FMI 2.0 FMU's
    logged time, to 4 ulp); the two rows differ in some output."""
    stop = HORIZON[name]
    step = stop / 20
    r = simulate_fmu(str(FMU3_DIR / f"{name}.fmu"), stop_time=stop, output_interval=step, early_return_allowed=True, use_event_mode=True)
    t = r["time"]
    pairs = [i for i in range(len(t) - 1) if t[i] == t[i + 1] and t[i] > t[0]]
    expected = [te for te in fmi2_events(name, stop, step) if te < stop]
    got = [float(t[i]) for i in pairs]
    got = [x for x in got if x < stop]
    assert len(got) == len(expected), (name, got[:5], expected[:5])
    for a, b in zip(got, expected):
        assert ulps(a, b) <= ULP4, (name, a, b)
    outputs = [n for n in r.dtype.names if n != "time"]
    for i in pairs:
        assert any(r[n][i] != r[n][i + 1] for n in outputs), (name, t[i])


# ------------------------------------------------------------ hand-written loops

class Slave3:
    """An FMU3Slave of one scene with value references by name."""

    def __init__(self, name: str, event_mode=False, early_return=False, intermediate_update=None, start_values=None, log_message=None):
        fmu = FMU3_DIR / f"{name}.fmu"
        self.md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.s = FMU3Slave(guid=self.md.guid, unzipDirectory=extract(str(fmu)), modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.s.instantiate(eventModeUsed=event_mode, earlyReturnAllowed=early_return, intermediateUpdate=intermediate_update, logMessage=log_message)
        for k, v in (start_values or {}).items():
            self.s.setFloat64([self.vr[k]], [v])
        self.s.enterInitializationMode(startTime=0.0)
        self.s.exitInitializationMode()
        if event_mode:
            self.s.updateDiscreteStates()
            self.s.enterStepMode()
        self.t = 0.0

    def get(self, name):
        vr = [self.vr[name]]
        ty = self.types[name]
        if ty == "Float64":
            return self.s.getFloat64(vr)[0]
        if ty == "Int32":
            return self.s.getInt32(vr)[0]
        return self.s.getBoolean(vr)[0]

    def step(self, h):
        ev, term, early, last = self.s.doStep(self.t, h)
        assert not term
        self.t = last
        return ev, early, last

    def update(self):
        self.s.enterEventMode()
        result = self.s.updateDiscreteStates()
        self.s.enterStepMode()
        return result

    def free(self):
        self.s.terminate()
        self.s.freeInstance()


def step_event_to_event(name, h, stop, start_values=None, on_event=None):
    """Early return and event mode, steps of h to stop: the times returned
    early with eventHandlingNeeded."""
    s = Slave3(name, event_mode=True, early_return=True, start_values=start_values)
    met = []
    n = 0
    while s.t < stop:
        target = min((n + 1) * h, stop)
        ev, early, last = s.step(target - s.t)
        if ev:
            met.append(last)
            if on_event:
                on_event(s)
            s.update()
        if not early:
            n += 1
    s.free()
    return met


def test_pinned_beam_unit_steps_return_at_every_impact_stick_and_release():
    """VSM12's Figure 4 scene (impacts, chatter, sticking) stepped by 1
    time unit: a return at every event, at the FMI 2.0 FMU's time; at
    each impact the velocity before the update reverses by R in it."""
    R = 0.7
    checked = []

    def on_event(s):
        v_before, n_before, stuck_before = s.get("v_stop"), s.get("impacts"), s.get("sticking")
        s.s.enterEventMode()
        s.s.updateDiscreteStates()
        v_after, n_after, stuck_after = s.get("v_stop"), s.get("impacts"), s.get("sticking")
        s.s.enterStepMode()
        s.s.enterEventMode()  # the second update changes nothing
        assert s.s.updateDiscreteStates()[3] is False
        assert s.get("v_stop") == v_after
        s.s.enterStepMode()
        if n_after == n_before + 1 and not stuck_after:
            # R, or 0 for the impact that ends a chatter sequence.
            assert v_after == pytest.approx(-R * v_before, rel=1e-12, abs=1e-12) or v_after == pytest.approx(0.0, abs=1e-9)
            checked.append(v_before)
        assert (n_before, stuck_before, v_before) != (n_after, stuck_after, v_after)

    # on_event makes the update itself: the loop's update then finds nothing pending.
    met = step_event_to_event("PinnedBeamStop", 1.0, 20.0, on_event=on_event)
    expected = fmi2_events("PinnedBeamStop", 20.0, 1.0)
    assert len(met) == len(expected) > 100
    assert max(ulps(a, b) for a, b in zip(met, expected)) <= ULP4
    assert len(checked) > 50


def test_free_vibration_first_impact_at_one_over_two_pi():
    met = step_event_to_event("PinnedBeamStop", 1.0, 1.0, start_values=FREE_VIBRATION)
    assert ulps(met[0], FREE_FIRST_IMPACT) <= ULP4, (met[0], FREE_FIRST_IMPACT)
    expected = fmi2_events("PinnedBeamStop", 1.0, 1.0, FREE_VIBRATION)
    assert len(met) == len(expected) and max(ulps(a, b) for a, b in zip(met, expected)) <= ULP4


def test_event_at_the_end_of_a_step_is_left_to_event_mode():
    """Event mode without early return: events inside a step are handled
    as FMI 2.0 does; one exactly at the step's end is reported."""
    s = Slave3("PinnedBeamStop", event_mode=True, early_return=False, start_values=FREE_VIBRATION)
    ev, early, last = s.step(FREE_FIRST_IMPACT)
    assert (ev, early, last) == (True, False, FREE_FIRST_IMPACT)
    v = s.get("v_stop")
    assert s.get("impacts") == 0 and v > 0
    s.update()
    assert s.get("impacts") == 1 and s.get("v_stop") == pytest.approx(-v, rel=1e-14)
    ev, early, last = s.step(1.0 - FREE_FIRST_IMPACT)  # several impacts inside: handled
    assert (ev, early) == (False, False) and s.get("impacts") > 2
    s.free()


@pytest.mark.parametrize("name,h,stop", [("SpringStopHard", 0.05, 0.1), ("HertzStop", 0.05, 0.1), ("RotatingBeamImpact", 0.01, 0.02)])
def test_compliant_contacts_return_at_their_onsets_and_separations(name, h, stop):
    """Contact onsets and separations of the compliant stops: returned at
    the FMI 2.0 FMU's times; the displacements and velocities do not jump
    (nothing is reset: equal to rounding), the contact's own counters and
    flags do."""
    changed = []

    def on_event(s):
        reals = [k for k, ty in s.types.items() if ty == "Float64" and k != "time" and s.md.modelVariables[s.vr[k]].causality == "output"
                 and k.endswith((".w", ".v", "_w", "_v", "tip.w", "tip.v"))]
        others = [k for k, ty in s.types.items() if ty in ("Int32", "Boolean")]
        before = {k: s.get(k) for k in reals + others}
        s.s.enterEventMode()
        s.s.updateDiscreteStates()
        s.s.enterStepMode()
        after = {k: s.get(k) for k in reals + others}
        # Equal to rounding: a linear contact phase reads them from its own
        # (coupled) coordinates after the switch.
        assert all(after[k] == pytest.approx(before[k], rel=1e-12, abs=1e-15) for k in reals), [(k, before[k], after[k]) for k in reals]
        changed.append(any(before[k] != after[k] for k in others))

    met = step_event_to_event(name, h, stop, on_event=on_event)
    expected = fmi2_events(name, stop, h)
    assert len(met) == len(expected) >= 2, (met, expected)
    assert max(ulps(a, b) for a, b in zip(met, expected)) <= ULP4
    assert sum(changed) >= len(met) // 2, changed


def test_early_return_without_event_mode_returns_after_the_change():
    s = Slave3("PinnedBeamStop", event_mode=False, early_return=True, start_values=FREE_VIBRATION)
    ev, early, last = s.step(1.0)
    assert (ev, early) == (False, True) and ulps(last, FREE_FIRST_IMPACT) <= ULP4
    assert s.get("impacts") == 1 and s.get("v_stop") < 0  # handled by the FMU
    s.free()


def test_intermediate_update_early_return_request_is_honoured():
    """Without event mode, an importer's intermediate-update callback
    decides: no early return at the first event, one at the second."""
    calls = []

    def intermediate_update(env, time, set_requested, get_allowed, step_finished, can_return_early, requested, requested_time):
        calls.append((time, bool(can_return_early), bool(step_finished), bool(get_allowed)))
        requested[0] = len(calls) == 2
        requested_time[0] = time

    s = Slave3("PinnedBeamStop", event_mode=False, early_return=True, intermediate_update=intermediate_update, start_values=FREE_VIBRATION)
    ev, early, last = s.step(1.0)
    assert (ev, early) == (False, True)
    assert len(calls) == 2 and last == calls[1][0] and s.get("impacts") == 2
    assert all(c[1] and c[2] and not c[3] for c in calls)
    assert ulps(calls[0][0], FREE_FIRST_IMPACT) <= ULP4
    s.free()


def test_a_call_from_inside_the_intermediate_update_is_refused_with_a_message():
    """A call into the instance from inside its intermediate-update
    callback is refused (the running call owns the instance) and says why
    through the logger (it returned fmi3Error without a message)."""
    from ctypes import byref, c_double, c_uint32, c_void_p

    messages, seen = [], []

    def log_message(env, status, category, message):
        messages.append((status, message.decode()))

    def intermediate_update(env, time, set_requested, get_allowed, step_finished, can_return_early, requested, requested_time):
        if not seen:
            before = len(messages)
            value = (c_double * 1)()
            status = s.s.dll.fmi3GetFloat64(c_void_p(s.s.component), (c_uint32 * 1)(0), 1, value, 1)
            state = c_void_p()
            status_state = s.s.dll.fmi3GetFMUState(c_void_p(s.s.component), byref(state))
            seen.append((status, status_state, messages[before:]))

    s = Slave3("PinnedBeamStop", early_return=True, intermediate_update=intermediate_update, start_values=FREE_VIBRATION, log_message=log_message)
    s.step(1.0)
    assert seen, "the callback ran"
    status, status_state, logged = seen[0]
    assert (status, status_state) == (3, 3)  # fmi3Error
    assert [m for _, m in logged if "fmi3GetFloat64" in m and "intermediate-update callback" in m], logged
    assert [m for _, m in logged if "fmi3GetFMUState" in m], logged
    s.step(0.1)  # the instance goes on
    s.free()


def test_state_saved_in_event_mode_restores():
    """A state saved (and serialized) in event mode, before the update,
    carries the pending impact: restored, it reads the values before the
    impact, and the update and the steps after it repeat bit for bit."""
    s = Slave3("PinnedBeamStop", event_mode=True, early_return=True, start_values=FREE_VIBRATION)
    ev, early, last = s.step(1.0)
    assert ev and early
    s.s.enterEventMode()
    v_before = s.get("v_stop")
    state = s.s.getFMUState()
    blob = s.s.serializeFMUState(state)

    def continue_run():
        s.s.updateDiscreteStates()
        out = [s.get("v_stop"), s.get("impacts")]
        s.s.enterStepMode()
        s.t = last
        for _ in range(5):
            ev2, _, _ = s.step(0.1)
            out += [s.t, s.get("w_stop"), s.get("v_stop"), s.get("impacts")]
            if ev2:
                s.update()
        return out

    first = continue_run()
    assert first[0] == pytest.approx(-v_before, rel=1e-14)
    for restore in ("state", "serialized"):
        if restore == "state":
            s.s.setFMUState(state)
        else:
            s.s.setFMUState(s.s.deserializeFMUState(blob))
        assert s.get("v_stop") == v_before and s.get("impacts") == 0
        assert continue_run() == first
    s.s.freeFMUState(state)
    s.free()
