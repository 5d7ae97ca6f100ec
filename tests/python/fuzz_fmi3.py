"""The FMI 3.0 sibling of fuzz_fmi.py: random fmi3 call sequences and
corrupted serialized states, through ctypes on an FMI 3.0 FMU's shared
library (target/fmu3/*.fmu).

    python tests/python/fuzz_fmi3.py --fmu target/fmu3/PinnedBeamStop.fmu --seed 1 --calls 100000

(or `fuzz_fmi.py --fmi 3 ...`; tests/python/test_fuzz.py runs a bounded
one over every FMU in CI). It shares the value pools, the value-reference
picks, the state corruption and the timing of every call with fuzz_fmi.py.
Each instance is instantiated with eventModeUsed, earlyReturnAllowed, an
intermediate-update callback (which may request early returns and may try
to call back into the instance) and logging chosen at random. Promises
checked after every call, as for FMI 2.0:

- the return is a legal fmi3Status (OK .. Fatal), within LIMIT s (fuzz_fmi.py);
- outputs read with fmi3OK are finite (Int32 counts >= 0, Booleans 0 or 1),
  no stop is penetrated beyond rounding, and 'time' reads the time the
  importer was told;
- fmi3DoStep keeps its word: an early return only when allowed and before
  the step's end, eventHandlingNeeded only with event mode, lastSuccessfulTime
  within the step, and steps make progress (no endless early returns at
  one time);
- a call refused for a bad argument leaves the instance usable: outputs
  still read, and it stays in the state it was in (a later call the state
  machine allows is not an "Illegal call sequence"); a call the state
  machine forbids is refused;
- the intermediate-update callback is called with a time inside the step,
  and a call back into the running instance from it is refused;
- a corrupted serialized state is refused, or the state it gives is one the
  model can be in (the same output checks, no event mode in an instance
  instantiated without it, then a step that returns), and the true state
  is accepted again;
- every fmi3DoStep that runs logs its work line (logAll) with work <= cap,
  as in fuzz_fmi.py (WORK_LINE_REQUIRED);
- rollback (`rollback`, also right after a set): a state saved in step
  mode, in event mode or with an event pending is deserialized into another
  instance, made with the same flags or with other eventModeUsed /
  earlyReturnAllowed; with the same flags it takes the same calls (the
  event-mode updates, then the same fmi3DoStep) with the same results bit
  for bit; with other flags it continues as a master with those flags would
  (no event-mode call without eventModeUsed) and, where neither DoStep
  met an event, gives the same outputs bit for bit. It may refuse the state
  (fmi3Error with a message) only if the state was saved in event mode
  and the instance has no eventModeUsed. A step with other flags that
  fails past the original's early return, its contact's steps below the
  time's resolution there (late times), is counted, not compared. Restored
  into its own instance (step, restore, step again) the calls repeat bit
  for bit. (The intermediate-update callback asks for every early return
  during these steps, which is what an instance without a callback gets.)
A crash kills this process and a hang never finishes: the caller (the test)
runs it in a subprocess with a timeout and reports both.
"""

from __future__ import annotations

import argparse
import collections
import ctypes
import json
import math
import random
import shutil
import sys
import tempfile
import weakref
import zipfile
from ctypes import CFUNCTYPE, POINTER, byref, c_char_p, c_double, c_int, c_int32, c_size_t, c_uint, c_uint8, c_void_p
from pathlib import Path

from fmpy import read_model_description

from fuzz_fmi import DISCARD, ERROR, FATAL, OK, WARNING, WORK_LINE, WORK_LINE_REQUIRED, Harness

LOG_CALLBACK = CFUNCTYPE(None, c_void_p, c_int, c_char_p, c_char_p)
INTERMEDIATE_CALLBACK = CFUNCTYPE(None, c_void_p, c_double, c_uint8, c_uint8, c_uint8, c_uint8, POINTER(c_uint8),
                                  POINTER(c_double))

# The FMI 3.0 co-simulation states (the FMU's names, src/fmi3/state_machine.rs).
INSTANTIATED, INIT, EVENT, STEP, DISCARDED, TERMINATED, ERRORED = (
    "Instantiated", "InitializationMode", "EventMode", "StepMode", "StepDiscarded", "Terminated", "Error")
ALIVE = (INSTANTIATED, INIT, EVENT, STEP, DISCARDED, TERMINATED, ERRORED)
READABLE = (INIT, EVENT, STEP, DISCARDED, TERMINATED, ERRORED)
# Where each function may be called (FMI 3.0.1 section 4.2.1, as the FMU's table).
ALLOWED = {
    "fmi3EnterInitializationMode": (INSTANTIATED,),
    "fmi3ExitInitializationMode": (INIT,),
    "fmi3EnterEventMode": (STEP,),
    "fmi3Terminate": (EVENT, STEP, DISCARDED),
    "fmi3Reset": ALIVE,
    "fmi3GetFloat64": READABLE, "fmi3GetInt32": READABLE, "fmi3GetBoolean": READABLE,
    "fmi3SetFloat64": (INSTANTIATED, INIT, EVENT, STEP), "fmi3SetInt32": (INSTANTIATED, INIT, EVENT, STEP),
    "fmi3SetBoolean": (INSTANTIATED, INIT, EVENT, STEP),
    "fmi3UpdateDiscreteStates": (EVENT,),
    "fmi3EnterStepMode": (EVENT,),
    "fmi3DoStep": (STEP,),
}
# The moves a careful importer would make in each state: most moves are
# drawn from these, so that runs get far into the simulation.
PREFERRED = {
    INSTANTIATED: ["set", "enter", "enter"],
    INIT: ["set", "get", "exit", "exit", "exit"],
    EVENT: ["update", "update", "stepmode", "get", "set", "serialize"],
    STEP: ["step", "step", "step", "set", "get", "geti", "eventmode", "serialize", "getstate", "setstate"],
    DISCARDED: ["terminate", "reset", "setstate", "get"],
    TERMINATED: ["reset", "get", "free"],
    ERRORED: ["reset", "setstate", "get"],
}
# Messages of a DoStep refused for its arguments (the state is unchanged).
STEP_REFUSALS = ("currentCommunicationPoint", "communicationStepSize", "t + h", "output argument", "no simulation")


class Harness3(Harness):
    LEGAL = (OK, WARNING, DISCARD, ERROR, FATAL)

    def __init__(self, fmu: str, seed: int):  # noqa: super().__init__ is FMI 2.0's
        self.rng = random.Random(seed)
        self.seed = seed
        self.md = read_model_description(fmu)
        assert self.md.fmiVersion.startswith("3"), f"{fmu} is not an FMI 3.0 FMU"
        self.dir = Path(tempfile.mkdtemp(prefix="fuzz3"))
        weakref.finalize(self, shutil.rmtree, self.dir, ignore_errors=True)  # the extracted FMU
        with zipfile.ZipFile(fmu) as z:
            z.extractall(self.dir)
        ident = self.md.coSimulation.modelIdentifier
        self.lib = ctypes.CDLL(str(self.dir / "binaries" / "x86_64-linux" / f"{ident}.so"))
        self._types()
        self.messages: collections.deque[str] = collections.deque(maxlen=200)

        self.n_messages = 0
        self.work_lines: list[tuple] = []  # (function, work, cap, unit) of every work line logged
        self.work_required = WORK_LINE_REQUIRED

        def log(env, status, category, message):
            self.n_messages += 1
            m = message.decode("utf-8", "replace") if message is not None else ""
            self.messages.append(m)
            w = WORK_LINE.search(m)
            if w:
                self.work_lines.append((w.group(1), int(w.group(2)), int(w.group(3)), w.group(4)))

        self.log_callback = LOG_CALLBACK(log)
        self.intermediate_callback = INTERMEDIATE_CALLBACK(self._intermediate)
        mv = self.md.modelVariables
        self.reals = [v for v in mv if v.type == "Float64" and v.causality != "independent"]
        self.ints = [v for v in mv if v.type == "Int32"]
        self.bools = [v for v in mv if v.type == "Boolean"]
        self.time_var = next(v for v in mv if v.causality == "independent")
        self.settable = [v for v in self.reals if v.causality in ("parameter", "input")]
        self.outputs = [v for v in self.reals if v.causality == "output"]
        self.int_outputs = [v for v in self.ints if v.causality == "output"]
        self.bool_outputs = [v for v in self.bools if v.causality == "output"]
        self.n_vr = len(mv)
        assert self.time_var.valueReference == self.n_vr - 1, "time is the last value reference"
        self.stops = self._stops()
        self.c = None
        self.state = None  # our model of the instance's state (None: unknown)
        self.time = 0.0
        self.options = {}
        self.snapshots: dict[int, tuple] = {}
        self.calls = 0
        self.states_tried = 0
        self.longest = (0.0, "")
        self.broken: list[str] = []
        self.stuck = 0  # consecutive early returns without progress
        self.stepping = None  # (t, t + h) of the running fmi3DoStep, for the callback
        self.counts = collections.Counter()
        self.recent: collections.deque[str] = collections.deque(maxlen=25)  # the latest calls, for reports
        self.first_trace: list[str] = []
        self.log_all = False  # whether the instance logs the category logAll
        self.twins: dict[tuple, int] = {}  # (eventModeUsed, earlyReturnAllowed) -> an instance for restores
        self.pending_event = False  # a DoStep asked for event handling that has not been made (None: unknown)
        self.snap_pending: dict[int, object] = {}
        self.forced_requests = False  # the callback asks for every early return (rollback steps)
        ex = self.md.defaultExperiment
        self.h_experiment = float(ex.stepSize) if ex is not None and ex.stepSize is not None else 0.01

    # ---------------------------------------------------------------- setup
    def _types(self):
        L = self.lib
        P = POINTER
        vr_args = [c_void_p, P(c_uint), c_size_t]
        sig = {
            "fmi3InstantiateCoSimulation": (c_void_p, [c_char_p, c_char_p, c_char_p, c_uint8, c_uint8, c_uint8, c_uint8,
                                                       P(c_uint), c_size_t, c_void_p, LOG_CALLBACK,
                                                       INTERMEDIATE_CALLBACK]),
            "fmi3FreeInstance": (None, [c_void_p]),
            "fmi3EnterInitializationMode": (c_int, [c_void_p, c_uint8, c_double, c_double, c_uint8, c_double]),
            "fmi3ExitInitializationMode": (c_int, [c_void_p]),
            "fmi3EnterEventMode": (c_int, [c_void_p]),
            "fmi3EnterStepMode": (c_int, [c_void_p]),
            "fmi3Terminate": (c_int, [c_void_p]),
            "fmi3Reset": (c_int, [c_void_p]),
            "fmi3UpdateDiscreteStates": (c_int, [c_void_p] + [P(c_uint8)] * 5 + [P(c_double)]),
            "fmi3DoStep": (c_int, [c_void_p, c_double, c_double, c_uint8, P(c_uint8), P(c_uint8), P(c_uint8),
                                   P(c_double)]),
            "fmi3GetFloat64": (c_int, vr_args + [P(c_double), c_size_t]),
            "fmi3SetFloat64": (c_int, vr_args + [P(c_double), c_size_t]),
            "fmi3GetInt32": (c_int, vr_args + [P(c_int32), c_size_t]),
            "fmi3SetInt32": (c_int, vr_args + [P(c_int32), c_size_t]),
            "fmi3GetBoolean": (c_int, vr_args + [P(c_uint8), c_size_t]),
            "fmi3SetBoolean": (c_int, vr_args + [P(c_uint8), c_size_t]),
            "fmi3GetFloat32": (c_int, vr_args + [P(ctypes.c_float), c_size_t]),
            "fmi3GetFMUState": (c_int, [c_void_p, P(c_void_p)]),
            "fmi3SetFMUState": (c_int, [c_void_p, c_void_p]),
            "fmi3FreeFMUState": (c_int, [c_void_p, P(c_void_p)]),
            "fmi3SerializedFMUStateSize": (c_int, [c_void_p, c_void_p, P(c_size_t)]),
            "fmi3SerializeFMUState": (c_int, [c_void_p, c_void_p, c_char_p, c_size_t]),
            "fmi3DeserializeFMUState": (c_int, [c_void_p, c_char_p, c_size_t, P(c_void_p)]),
            "fmi3SetDebugLogging": (c_int, [c_void_p, c_uint8, c_size_t, P(c_char_p)]),
            "fmi3SetTime": (c_int, [c_void_p, c_double]),
            "fmi3EnterConfigurationMode": (c_int, [c_void_p]),
            "fmi3EvaluateDiscreteStates": (c_int, [c_void_p]),
            "fmi3GetNumberOfContinuousStates": (c_int, [c_void_p, P(c_size_t)]),
            "fmi3GetClock": (c_int, vr_args + [P(c_uint8)]),
        }
        for name, (res, args) in sig.items():
            f = getattr(L, name)
            f.restype, f.argtypes = res, args

    def flag(self) -> int:
        """A C bool as a byte: mostly 0 or 1, sometimes another non-zero byte."""
        return self.rng.choice([0, 1, 1, 0, 2, 255])

    def last(self, n: int = 2) -> str:
        return " | ".join(list(self.messages)[-n:])

    def report(self, what: str):
        if not self.broken:
            self.first_trace = [f"options {self.options}"] + list(self.recent)
        self.broken.append(f"seed {self.seed} call {self.calls}: {what}")
        self.dump_state()

    def call(self, what: str, f, *args):
        r = super().call(what, f, *args)
        self.recent.append(f"{self.calls}: {what} -> {r}")
        return r

    # ---------------------------------------------------------------- the state machine
    def fmi(self, name: str, *args, label: str | None = None) -> int:
        """Calls fmi3<name> and checks it against our model of the state machine."""
        before = self.n_messages
        r = self.call(label or name, getattr(self.lib, name), *args)
        allowed = ALLOWED.get(name)
        if allowed is not None and self.state is not None:
            if r == ERROR and self.state in allowed:
                k = min(self.n_messages - before, len(self.messages))
                new = list(self.messages)[len(self.messages) - k:]
                if any("Illegal call sequence" in m for m in new):
                    self.report(f"{label or name} refused as an illegal call sequence in state {self.state}, "
                                f"which allows it: {self.last(1)}")
            elif r in (OK, WARNING) and self.state not in allowed:
                self.report(f"{label or name} accepted in state {self.state}, where the state machine forbids it")
        return r

    def _intermediate(self, env, t, set_requested, get_allowed, finished, can_return_early, requested, requested_time):
        try:
            self.counts["intermediateUpdate"] += 1
            if self.stepping is None:
                self.report(f"intermediateUpdate(t={t}) called outside fmi3DoStep")
                return
            t0, t1 = self.stepping
            if not (math.isfinite(t) and t0 - 1e-9 * max(1.0, abs(t0)) <= t <= t1 + 1e-9 * max(1.0, abs(t1))):
                self.report(f"intermediateUpdate(t={t}) outside the step [{t0}, {t1}]")
            if can_return_early and not self.options["early"]:
                self.report("intermediateUpdate offers an early return to an instance without earlyReturnAllowed")
            if get_allowed or set_requested:
                self.report("intermediateUpdate allows variable access, but requiredIntermediateVariables was empty")
            if self.rng.random() < self.options["reenter"]:
                # A call back into the running instance: refused, no aliasing.
                vrs = (c_uint * 1)(self.outputs[0].valueReference)
                vals = (c_double * 1)()
                r = self.lib.fmi3GetFloat64(self.c, vrs, 1, vals, 1)
                self.counts["reentered"] += 1
                if r != ERROR:
                    self.report(f"a call back into the running instance from intermediateUpdate returned {r}")
                r = self.lib.fmi3EnterEventMode(self.c)
                if r != ERROR:
                    self.report(f"fmi3EnterEventMode from inside intermediateUpdate returned {r}")
            want = self.forced_requests or self.rng.random() < self.options["request"]
            requested[0] = 1 if want else 0
            requested_time[0] = t
        except Exception as e:  # never let an exception cross into the FMU (ctypes would print it)
            self.report(f"intermediateUpdate callback raised {e!r}")

    def instantiate(self):
        rng = self.rng
        token = self.md.instantiationToken.encode()
        resources = str(self.dir / "resources") + rng.choice(["", "/"])
        if rng.random() < 0.1:
            # Refused: no instance, a message, no crash.
            bad = rng.choice(["token", "required", "name", "path", "relative"])
            args = [b"fuzz", token, resources.encode(), 0, 1, 0, 0, None, 0, None, self.log_callback,
                    self.intermediate_callback]
            if bad == "token":
                args[1] = b"{not-the-token}"
            elif bad == "required":
                args[7], args[8] = (c_uint * 1)(self.outputs[0].valueReference), 1
            elif bad == "name":
                args[0] = rng.choice([None, b""])
            elif bad == "path":
                args[2] = rng.choice([None, b"/nonexistent/resources", b""])
            else:
                args[2] = b"resources"
            c = self.call(f"fmi3InstantiateCoSimulation(bad {bad})", self.lib.fmi3InstantiateCoSimulation, *args)
            if c:
                self.report(f"fmi3InstantiateCoSimulation with a bad {bad} returned an instance")
                self.lib.fmi3FreeInstance(c)
            return
        self.options = {
            "event": rng.random() < 0.5,
            "early": rng.random() < 0.5,
            "callback": rng.random() < 0.4,
            "request": rng.choice([0.02, 0.5, 1.0]),
            "reenter": rng.choice([0.0, 0.0, 0.2]),
        }
        o = self.options
        self.c = self.call(
            f"fmi3InstantiateCoSimulation(event={o['event']}, early={o['early']}, callback={o['callback']})",
            self.lib.fmi3InstantiateCoSimulation, b"fuzz", token, resources.encode(), 0, rng.random() < 0.3,
            o["event"] * rng.choice([1, 2, 255]), o["early"] * rng.choice([1, 2, 255]), None, 0, None,
            self.log_callback, self.intermediate_callback if o["callback"] else INTERMEDIATE_CALLBACK())
        assert self.c, "fmi3InstantiateCoSimulation returned NULL: " + self.last(3)
        self.state = INSTANTIATED
        self.time = 0.0
        self.stuck = 0
        self.pending_event = False
        self.log_all = self.logging(self.c, 1, [b"logAll"]) == OK

    def logging(self, c, on: int, categories: list[bytes]) -> int:
        arr = (c_char_p * max(1, len(categories)))(*categories) if categories else None
        return self.call("fmi3SetDebugLogging", self.lib.fmi3SetDebugLogging, c, on, len(categories), arr)

    # ---------------------------------------------------------------- reads
    def get(self, kind: str, vrs: list[int], label: str | None = None, raw: bool = False):
        ctype = {"Float64": c_double, "Int32": c_int32, "Boolean": c_uint8}[kind]
        n = len(vrs)
        vals = (ctype * max(1, n))()
        f = getattr(self.lib, f"fmi3Get{kind}")
        args = (self.c, (c_uint * max(1, n))(*vrs), n, vals, n)
        r = f(*args) if raw else self.fmi(f"fmi3Get{kind}", *args, label=label)
        return r, list(vals)[:n]

    def check_outputs(self, where: str):
        if self.state not in READABLE:
            return
        vrs = [v.valueReference for v in self.outputs] + [self.time_var.valueReference]
        r, vals = self.get("Float64", vrs, label="fmi3GetFloat64(outputs)")
        if r != OK:
            if self.state in (STEP, EVENT, DISCARDED, TERMINATED):
                self.report(f"outputs unreadable in {self.state} after {where}: {self.last()}")
            return
        got = dict(zip(vrs, vals))
        for v in self.outputs:
            x = got[v.valueReference]
            if not math.isfinite(x):
                self.report(f"{v.name} = {x} after {where}")
            # Stop forces and impulses push, never pull.
            if v.name.endswith((".force", ".impulse", ".E_stored", ".E_dissipated")) and x < -1e-9 * max(1.0, abs(x)):
                self.report(f"{v.name} = {x} < 0 after {where}")
        t = got[self.time_var.valueReference]
        if self.state in (STEP, EVENT) and self.time is not None and not (
                math.isfinite(t) and abs(t - self.time) <= 1e-9 * max(1.0, abs(self.time))):
            self.report(f"time reads {t}, the importer's time is {self.time}, after {where}")
        for w, gap, side in self.stops:
            _, (g,) = self.get("Float64", [gap.valueReference], raw=True)
            y = got[w.valueReference]
            penetration = side * y - g
            if penetration > 1e-9 * (abs(g) + abs(y)) + 1e-15 * float(gap.max):
                self.report(f"{w.name} = {y} penetrates gap {g} after {where}")
        if self.int_outputs:
            r, ints = self.get("Int32", [v.valueReference for v in self.int_outputs], raw=True)
            if r == OK:
                for v, x in zip(self.int_outputs, ints):
                    if x < 0:
                        self.report(f"{v.name} = {x} < 0 after {where}")
            elif self.state in (STEP, EVENT, DISCARDED, TERMINATED):
                self.report(f"Int32 outputs unreadable after {where}: {self.last()}")
        if self.bool_outputs:
            r, bools = self.get("Boolean", [v.valueReference for v in self.bool_outputs], raw=True)
            if r == OK:
                for v, x in zip(self.bool_outputs, bools):
                    if x not in (0, 1):
                        self.report(f"{v.name} = byte {x}, not a C bool, after {where}")
            elif self.state in (STEP, EVENT, DISCARDED, TERMINATED):
                self.report(f"Boolean outputs unreadable after {where}: {self.last()}")

    # ---------------------------------------------------------------- moves
    def any_vr(self, pool):
        """A value reference from the pool, or of another type, or time, or none at all."""
        x = self.rng.random()
        if x < 0.05:
            return self.time_var.valueReference
        if x < 0.1:
            return self.rng.choice(self.reals + self.ints + self.bools).valueReference
        return self.vr(pool or self.reals)

    def event_protocol(self):
        """fmi3EnterEventMode (after a step that asked for it), updates, fmi3EnterStepMode."""
        rng = self.rng
        if self.state == STEP and self.fmi("fmi3EnterEventMode", self.c) == OK:
            self.state = EVENT
        if self.state != EVENT:
            return
        if rng.random() < 0.3:
            self.check_outputs("fmi3EnterEventMode (before the update)")
        for _ in range(10):
            flags = [c_uint8(7) for _ in range(5)]
            nxt = c_double(math.nan)
            r = self.fmi("fmi3UpdateDiscreteStates", self.c, *[byref(f) for f in flags], byref(nxt))
            if r != OK:
                if r == ERROR and not any("Illegal call sequence" in m for m in list(self.messages)[-1:]):
                    self.state = None
                return
            need, terminate, nominals, values, defined = (f.value for f in flags)
            if any(v not in (0, 1) for v in (need, terminate, nominals, values, defined)):
                self.report(f"fmi3UpdateDiscreteStates left a flag unset: {[need, terminate, nominals, values, defined]}")
            if defined and not (math.isfinite(nxt.value) and nxt.value >= self.time):
                self.report(f"fmi3UpdateDiscreteStates: nextEventTime {nxt.value} before the time {self.time}")
            self.check_outputs("fmi3UpdateDiscreteStates")
            if not need:
                break
        else:
            self.report("fmi3UpdateDiscreteStates still needs an update after 10 calls")
        if rng.random() < 0.95 and self.fmi("fmi3EnterStepMode", self.c) == OK:
            self.state = STEP
            self.pending_event = False

    def do_step(self, t: float, h: float, label: str):
        L, c = self.lib, self.c
        event, terminate, early = c_uint8(7), c_uint8(7), c_uint8(7)
        lst = c_double(math.nan)
        self.stepping = (t, t + h) if math.isfinite(t) and math.isfinite(h) else (t, t)
        state_before, time_before = self.state, self.time
        n_lines = len(self.work_lines)
        try:
            r = self.fmi("fmi3DoStep", c, t, h, self.flag(), byref(event), byref(terminate), byref(early), byref(lst),
                         label=label)
        finally:
            self.stepping = None
        self.work_check(label, n_lines, r)
        if r == OK:
            self.pending_event = bool(event.value) and bool(self.options.get("event"))
            self.state = STEP if self.state is None else self.state
            if event.value not in (0, 1) or terminate.value not in (0, 1) or early.value not in (0, 1):
                self.report(f"{label}: output flags not C bools: {event.value}, {terminate.value}, {early.value}")
            end = t + h
            tol = 1e-9 * max(1.0, abs(end))
            if not math.isfinite(lst.value) or lst.value < t - tol or lst.value > end + tol:
                self.report(f"{label}: lastSuccessfulTime = {lst.value} outside the step [{t}, {end}]")
            if early.value:
                if not self.options.get("early"):
                    self.report(f"{label}: returned early without earlyReturnAllowed")
                if lst.value >= end:
                    self.report(f"{label}: early return at {lst.value}, not before the step's end {end}")
                self.time = lst.value
            else:
                if math.isfinite(lst.value) and abs(lst.value - end) > tol:
                    self.report(f"{label}: completed step reports lastSuccessfulTime = {lst.value}, not {end}")
                self.time = end
            if event.value and not self.options.get("event"):
                self.report(f"{label}: eventHandlingNeeded without eventModeUsed")
            if terminate.value:
                self.counts["terminateSimulation"] += 1
            if early.value and math.isfinite(lst.value) and lst.value <= time_before:
                self.stuck += 1
                if self.stuck == 50:
                    self.report(f"{label}: 50 early returns in a row without progress at t = {lst.value}")
            else:
                self.stuck = 0
            self.counts["early" if early.value else "full"] += 1
            self.counts["eventHandlingNeeded"] += bool(event.value)
            self.check_outputs(label)
            if event.value and self.rng.random() < 0.85:
                self.event_protocol()
        elif r == DISCARD:
            if not (math.isfinite(lst.value) and lst.value >= self.time - 1e-9 * max(1.0, abs(self.time))):
                self.report(f"{label}: discarded step reports lastSuccessfulTime {lst.value}")
            self.state, self.time = DISCARDED, None
            self.check_outputs(f"discarded {label}")
        elif r == ERROR:
            refused = any(k in self.last(1) for k in STEP_REFUSALS + ("Illegal call sequence",))
            if not refused and state_before == STEP:
                self.state = None  # a failure of the run: the Error state, or a refusal we do not know
            elif state_before in (STEP, EVENT):
                self.check_outputs(f"refused {label}")

    def move(self):
        rng = self.rng
        if self.c is None:
            self.instantiate()
            return
        L, c = self.lib, self.c
        op = rng.choice(PREFERRED[self.state]) if self.state in PREFERRED and rng.random() < 0.5 else rng.choices(
            ["enter", "exit", "set", "seti", "get", "geti", "step", "step", "step", "eventmode", "update",
             "stepmode", "getstate", "setstate", "freestate", "serialize", "reset", "terminate", "absent", "logging",
             "free", "rollback"],
            weights=[3, 3, 12, 2, 6, 3, 12, 12, 12, 2, 2, 2, 3, 3, 1, 3, 1, 1, 1, 1, 0.3, 4])[0]
        if op == "enter":
            # (far start times are rarer than in fuzz_fmi.py: this fuzzer initialises more
            # often, and a run built at t = 1e15 takes most of a second)
            start = rng.choice([0.0] * 12 + [1.5, -3.0, 1e6, 1e15, math.nan, math.inf])
            stop_defined = rng.random() < 0.5
            stop = rng.choice([start + 100.0, start - 1.0, math.nan])
            r = self.fmi("fmi3EnterInitializationMode", c, self.flag(), rng.choice([1e-6, 0.0, -1.0, math.nan]),
                         start, stop_defined, stop, label=f"fmi3EnterInitializationMode(start={start}, stop={stop if stop_defined else None})")
            if r == OK:
                self.state, self.time = INIT, start
        elif op == "exit":
            if self.fmi("fmi3ExitInitializationMode", c) == OK:
                self.state = EVENT if self.options["event"] else STEP
                self.pending_event = False
                self.check_outputs("fmi3ExitInitializationMode")
                if self.state == EVENT and rng.random() < 0.8:
                    self.event_protocol()
        elif op == "set":
            n = rng.choice([1, 1, 1, 2, 3])
            vars_ = [rng.choice(self.settable) for _ in range(n)]
            vrs = [self.any_vr(self.settable) if rng.random() < 0.2 else v.valueReference for v in vars_]
            vals = [self.value(v) for v in vars_]
            n_values = n if rng.random() < 0.95 else rng.choice([0, n + 1])
            arr = (c_double * max(1, n, n_values))(*vals)
            r = self.fmi("fmi3SetFloat64", c, (c_uint * n)(*vrs), n, arr, n_values,
                         label=f"fmi3SetFloat64({vrs}={vals}, nValues={n_values})")
            if r == ERROR and self.state in (STEP, EVENT):
                self.check_outputs(f"refused fmi3SetFloat64 {vrs}={vals}")
            elif r == OK and (self.state != INIT or rng.random() < 0.25):
                # (in InitializationMode each read after a change builds the run: slow at a far start time)
                self.check_outputs(f"fmi3SetFloat64 {vrs}={vals}")
            if r == OK and self.state in (STEP, EVENT) and rng.random() < 0.3:
                self.rollback(f"right after fmi3SetFloat64({vrs}={vals})")
        elif op == "seti":
            # No Int32 or Boolean parameter or input exists: every set is refused.
            if rng.random() < 0.5:
                vrs = [self.any_vr(self.ints)]
                r = self.fmi("fmi3SetInt32", c, (c_uint * 1)(*vrs), 1, (c_int32 * 1)(rng.choice([0, 1, -1, 2**31 - 1])), 1)
            else:
                vrs = [self.any_vr(self.bools)]
                r = self.fmi("fmi3SetBoolean", c, (c_uint * 1)(*vrs), 1, (c_uint8 * 1)(self.flag()), 1)
            if r == OK and not any(v.valueReference in vrs and v.causality in ("parameter", "input")
                                   for v in self.ints + self.bools):
                self.report(f"a set of the non-settable value reference {vrs} was accepted")
            if r == ERROR and self.state in (STEP, EVENT):
                self.check_outputs(f"refused set of {vrs}")
        elif op == "get":
            n = rng.choice([1, 2, 5])
            vrs = [self.any_vr(self.reals) for _ in range(n)]
            r, vals = self.get("Float64", vrs)
            if r == OK:
                for vr, x in zip(vrs, vals):
                    if not math.isfinite(x) and self.state in (STEP, EVENT):
                        self.report(f"fmi3GetFloat64({vr}) = {x}")
            elif r == ERROR and self.state in (STEP, EVENT):
                self.check_outputs(f"refused fmi3GetFloat64 {vrs}")
        elif op == "geti":
            self.get("Int32", [self.any_vr(self.ints)])
            if self.bools:
                r, (b,) = self.get("Boolean", [self.any_vr(self.bools)])
                if r == OK and b not in (0, 1):
                    self.report(f"fmi3GetBoolean gave byte {b}")
        elif op == "step":
            h = rng.choice([1e-3, 1e-2, 1e-2, 0.1, 1.0, 1e-12, 1e-300, 5e-324, 50.0, 1e3, 0.0, -1.0, math.nan, math.inf])
            now = self.time if self.time is not None else 0.0
            t = now if rng.random() < 0.9 else rng.choice([now + 1.0, math.nan, -1.0])
            self.do_step(t, h, f"fmi3DoStep(t={t}, h={h})")
        elif op == "eventmode":
            if self.fmi("fmi3EnterEventMode", c) == OK:
                self.state = EVENT
                self.check_outputs("fmi3EnterEventMode")
        elif op == "update":
            if self.state == EVENT and rng.random() < 0.7:
                self.event_protocol()
            else:
                flags = [c_uint8() for _ in range(5)]
                ptrs = [byref(f) for f in flags]
                if rng.random() < 0.2:
                    ptrs[rng.randrange(5)] = None  # a NULL output: refused
                r = self.fmi("fmi3UpdateDiscreteStates", c, *ptrs, byref(c_double()))
                if r == ERROR and self.state == EVENT:
                    self.check_outputs("refused fmi3UpdateDiscreteStates")
        elif op == "stepmode":
            if self.fmi("fmi3EnterStepMode", c) == OK:
                self.state = STEP
                self.pending_event = None  # unknown: were the updates made?
        elif op == "getstate":
            s = c_void_p()
            reuse = self.snapshots and rng.random() < 0.3
            if reuse:
                s = c_void_p(rng.choice(list(self.snapshots)))
            if self.fmi("fmi3GetFMUState", c, byref(s)) == OK:
                if reuse and s.value not in self.snapshots:
                    self.report("fmi3GetFMUState into an existing state gave another pointer")
                self.snapshots[s.value] = (self.state, self.time)
                self.snap_pending[s.value] = self.pending_event
        elif op == "setstate" and self.snapshots:
            key = rng.choice(list(self.snapshots))
            if self.fmi("fmi3SetFMUState", c, c_void_p(key)) == OK:
                self.state, self.time = self.snapshots[key]
                self.pending_event = self.snap_pending.get(key)
                self.check_outputs("fmi3SetFMUState")
        elif op == "freestate" and self.snapshots:
            key = rng.choice(list(self.snapshots))
            s = c_void_p(key)
            if self.fmi("fmi3FreeFMUState", c, byref(s)) == OK:
                del self.snapshots[key]
                if s.value:
                    self.report("fmi3FreeFMUState did not set the state to NULL")
        elif op == "serialize":
            self.serialize_round_trip()
        elif op == "reset":
            if self.fmi("fmi3Reset", c) == OK:
                self.state, self.time = INSTANTIATED, 0.0
                self.pending_event = False
        elif op == "terminate":
            if self.fmi("fmi3Terminate", c) == OK:
                self.state = TERMINATED
                self.check_outputs("fmi3Terminate")
        elif op == "absent":
            # What this FMU does not have: refused with a message, the instance unchanged.
            which = rng.randrange(5)
            if which == 0:
                r = self.call("fmi3SetTime", L.fmi3SetTime, c, 1.0)
            elif which == 1:
                r = self.call("fmi3EnterConfigurationMode", L.fmi3EnterConfigurationMode, c)
            elif which == 2:
                r = self.call("fmi3EvaluateDiscreteStates", L.fmi3EvaluateDiscreteStates, c)
            elif which == 3:
                r = self.call("fmi3GetNumberOfContinuousStates", L.fmi3GetNumberOfContinuousStates, c, byref(c_size_t()))
            else:
                vrs = (c_uint * 1)(self.outputs[0].valueReference)
                r = self.call("fmi3GetFloat32", L.fmi3GetFloat32, c, vrs, 1, (ctypes.c_float * 1)(), 1)
            if r != ERROR:
                self.report(f"a function this FMU does not provide returned {r}")
            if self.state in (STEP, EVENT):
                self.check_outputs("a refused absent function")
        elif op == "logging":
            cats = [b"logEvents", b"logAll", b"logStatusError", b"nonsense"][: rng.randrange(0, 5)]
            arr = (c_char_p * max(1, len(cats)))(*cats) if cats else None
            on = self.flag()
            if self.fmi("fmi3SetDebugLogging", c, on, len(cats), arr) == OK and (not cats or b"logAll" in cats):
                self.log_all = on != 0
            if not self.log_all and rng.random() < 0.7:
                self.log_all = self.logging(c, 1, [b"logAll"]) == OK  # mostly on: the work check needs it
        elif op == "rollback":
            self.rollback("")
        elif op == "free":
            self.free()

    def free(self):
        for key in list(self.snapshots):
            self.lib.fmi3FreeFMUState(self.c, byref(c_void_p(key)))
        self.snapshots.clear()
        self.snap_pending.clear()
        self.call("fmi3FreeInstance", self.lib.fmi3FreeInstance, self.c)
        self.c = None
        for twin in self.twins.values():
            self.lib.fmi3FreeInstance(twin)
        self.twins.clear()

    # ---------------------------------------------------------------- rollback
    def outputs_bits(self, c) -> bytes:
        """Every output (Float64 with time, Int32, Boolean) as raw bytes, compared bit for bit."""
        L = self.lib
        out = b""
        for pool, get, ctype in ((self.outputs + [self.time_var], L.fmi3GetFloat64, c_double),
                                 (self.int_outputs, L.fmi3GetInt32, c_int32), (self.bool_outputs, L.fmi3GetBoolean, c_uint8)):
            if pool:
                vals = (ctype * len(pool))()
                r = get(c, (c_uint * len(pool))(*[v.valueReference for v in pool]), len(pool), vals, len(pool))
                out += bytes([r]) + bytes(vals)
        return out

    def twin(self, flags: tuple) -> int | None:
        """An instance made with these flags (no callback), instantiated only: restores go into it."""
        if flags not in self.twins:
            c = self.call(f"fmi3InstantiateCoSimulation(twin, event={flags[0]}, early={flags[1]})",
                          self.lib.fmi3InstantiateCoSimulation, b"twin", self.md.instantiationToken.encode(),
                          (str(self.dir / "resources") + "/").encode(), 0, 0, int(flags[0]), int(flags[1]), None, 0,
                          None, self.log_callback, INTERMEDIATE_CALLBACK())
            if not c:
                self.report(f"fmi3InstantiateCoSimulation of a twin returned NULL: {self.last(1)}")
                return None
            self.logging(c, 1, [b"logAll"])
            self.twins[flags] = c
        return self.twins[flags]

    def restore_into(self, c, data: bytes) -> tuple[int, str]:
        L = self.lib
        s = c_void_p()
        r = self.call("fmi3DeserializeFMUState(rollback)", L.fmi3DeserializeFMUState, c, data, len(data), byref(s))
        if r != OK:
            return r, "fmi3DeserializeFMUState: " + self.last(1)
        r = self.call("fmi3SetFMUState(rollback)", L.fmi3SetFMUState, c, s)
        L.fmi3FreeFMUState(c, byref(s))
        return r, "" if r == OK else "fmi3SetFMUState: " + self.last(1)

    def segment(self, c, event_mode: bool, in_event: bool, pending: bool, t: float, h: float, who: str,
                log_all: bool) -> list[tuple]:
        """What a master with these flags does from a restored state: with event
        mode and an event pending (or in event mode), enter event mode, update
        until done, enter step mode; then fmi3DoStep(t, h). The records of
        every call, outputs as bytes."""
        L = self.lib
        recs = []
        if event_mode and (in_event or pending):
            if not in_event:
                recs.append(("fmi3EnterEventMode", self.call(f"fmi3EnterEventMode ({who})", L.fmi3EnterEventMode, c)))
            for _ in range(10):
                flags = [c_uint8(7) for _ in range(5)]
                r = self.call(f"fmi3UpdateDiscreteStates ({who})", L.fmi3UpdateDiscreteStates, c,
                              *[byref(f) for f in flags], byref(c_double()))
                recs.append(("fmi3UpdateDiscreteStates", r, [f.value for f in flags[:2]], self.outputs_bits(c)))
                if r != OK or not flags[0].value:
                    break
            recs.append(("fmi3EnterStepMode", self.call(f"fmi3EnterStepMode ({who})", L.fmi3EnterStepMode, c)))
        event, terminate, early = c_uint8(7), c_uint8(7), c_uint8(7)
        lst = c_double(math.nan)
        n_lines = len(self.work_lines)
        label = f"fmi3DoStep(t={t}, h={h}) ({who})"
        self.stepping = (t, t + h)
        self.forced_requests = True
        try:
            r = self.call(label, L.fmi3DoStep, c, t, h, 0, byref(event), byref(terminate), byref(early), byref(lst))
        finally:
            self.stepping = None
            self.forced_requests = False
        self.step_message = self.last(1) if r != OK else ""
        self.work_check(label, n_lines, r, log_all)
        recs.append(("fmi3DoStep", r, event.value, early.value, lst.value.hex(),
                     self.outputs_bits(c) if r in (OK, WARNING, DISCARD) else b""))
        return recs

    def rollback(self, why: str):
        """A master's rollback: save (get + serialize), continue; the state
        restored into another instance (same or other flags) and into its own."""
        if self.c is None or self.state not in (STEP, EVENT) or self.time is None or not math.isfinite(self.time):
            return
        rng = self.rng
        data = self.serialized()
        if data is None:
            self.report(f"fmi3GetFMUState/fmi3SerializeFMUState failed in {self.state} {why}: {self.last(1)}")
            return
        self.counts["rollbacks"] += 1
        own = (bool(self.options["event"]), bool(self.options["early"]))
        in_event = self.state == EVENT
        pending = self.pending_event is True
        t = self.time
        h = rng.choice([self.h_experiment, 10 * self.h_experiment, 1e-3, 1e-2])
        where = (f"state saved in {self.state}{' with an event pending' if pending else ''} at t = {t!r} "
                 f"by an instance with eventModeUsed={own[0]}, earlyReturnAllowed={own[1]}{' ' + why if why else ''}, "
                 f"then fmi3DoStep(h={h})")
        first = self.segment(self.c, own[0], in_event, pending, t, h, "original", self.log_all)
        flags = own if rng.random() < 0.4 else rng.choice([f for f in ((False, False), (False, True), (True, False),
                                                                        (True, True)) if f != own])
        twin = self.twin(flags)
        if twin is not None:
            self.counts["restores_same_flags" if flags == own else "restores_other_flags"] += 1
            r, msg = self.restore_into(twin, data)
            if r != OK and "instance state Error" in msg:
                # the instance was in the Error state (a step that failed), which no instance restores, by design
                self.counts["error_state_saved"] += 1
                self.state = ERRORED
                return
            if r != OK:
                legal = flags != own and not flags[0] and in_event and r == ERROR and msg.split(": ")[-1].strip()
                if legal:
                    self.counts["refused_legally"] += 1
                else:
                    self.report(f"a state the FMU serialized was refused by an instance with eventModeUsed={flags[0]}, "
                                f"earlyReturnAllowed={flags[1]} ({where}): {msg}")
            else:
                second = self.segment(twin, flags[0], in_event, pending, t, h, "restored", True)
                if flags == own:
                    if second != first:
                        self.report(f"restored in another instance, the calls differ ({where}): "
                                    f"{self.first_difference(first, second)}")
                else:
                    a, b = first[-1], second[-1]
                    if b[1] == DISCARD:
                        # without the original's early returns the step may meet more events: its work cap may end it
                        self.counts["other_flags_discarded"] += 1
                    elif b[1] == ERROR and a[1] == OK and a[3] and "the resolution of the time there" in self.step_message:
                        # The original returned early, short of where the other failed: at a late time
                        # (t ~ 1e6 s) a contact's steps may fall below the time's resolution there, which
                        # fails the step with a message saying so. Not compared.
                        self.counts["other_flags_failed_past_the_early_return"] += 1
                    elif b[1] != OK and a[1] == OK:
                        self.report(f"restored in an instance with eventModeUsed={flags[0]}, earlyReturnAllowed={flags[1]}, "
                                    f"fmi3DoStep returned {b[1]} ({where}): {self.step_message}")
                    elif a[1] == b[1] == OK and not (a[2] or a[3] or b[2] or b[3]):
                        self.counts["compared_other_flags"] += 1
                        if a[5] != b[5]:
                            self.report(f"restored in an instance with eventModeUsed={flags[0]}, earlyReturnAllowed="
                                        f"{flags[1]}, a step without events gives other outputs ({where})")
        if rng.random() < 0.5 and first[-1][1] in (OK, WARNING, DISCARD):
            # step, restore, step again: the same instance
            r, msg = self.restore_into(self.c, data)
            if r != OK:
                self.report(f"a state the FMU serialized was refused by its own instance ({where}): {msg}")
                self.state = None
                return
            self.counts["restored_here"] += 1
            again = self.segment(self.c, own[0], in_event, pending, t, h, "rolled back", self.log_all)
            if again != first:
                self.report(f"rolled back, the calls differ ({where}): {self.first_difference(first, again)}")
        # the original's state after its segment
        r, event, early, lst = first[-1][1], first[-1][2], first[-1][3], float.fromhex(first[-1][4])
        if r == OK:
            self.state = STEP
            self.time = lst if early else t + h
            self.pending_event = bool(event) and own[0]
            self.check_outputs(f"fmi3DoStep(h={h}) after a rollback")
        elif r == DISCARD:
            self.state, self.time = DISCARDED, None
        else:
            self.state = None

    @staticmethod
    def first_difference(a: list, b: list) -> str:
        for x, y in zip(a, b):
            if x != y:
                return (f"{x[0]}: status {x[1]} vs {y[1]}, " + ("outputs differ" if x[-1] != y[-1] else f"{x[1:-1]} vs {y[1:-1]}"))
        return f"{len(a)} calls vs {len(b)}"

    def state_bytes(self) -> bytes | None:
        L, c = self.lib, self.c
        s = c_void_p()
        if L.fmi3GetFMUState(c, byref(s)) != OK:
            return None
        size = c_size_t()
        ok = L.fmi3SerializedFMUStateSize(c, s, byref(size)) == OK
        buf = ctypes.create_string_buffer(size.value)
        ok = ok and L.fmi3SerializeFMUState(c, s, buf, size.value) == OK
        L.fmi3FreeFMUState(c, byref(s))
        return bytes(buf.raw) if ok else None

    def serialized(self):
        L, c = self.lib, self.c
        s = c_void_p()
        if L.fmi3GetFMUState(c, byref(s)) != OK:
            return None
        size = c_size_t()
        L.fmi3SerializedFMUStateSize(c, s, byref(size))
        buf = ctypes.create_string_buffer(size.value)
        r = L.fmi3SerializeFMUState(c, s, buf, size.value)
        if r == OK and size.value > 0 and self.rng.random() < 0.1:
            # Too small a buffer: refused.
            if self.call("fmi3SerializeFMUState(short)", L.fmi3SerializeFMUState, c, s, buf, size.value - 1) != ERROR:
                self.report("fmi3SerializeFMUState into a buffer one byte short was not refused")
        L.fmi3FreeFMUState(c, byref(s))
        if r == OK:
            self.last_state = bytes(buf.raw)
        return bytes(buf.raw) if r == OK else None

    def serialize_round_trip(self):
        """A serialized state, corrupted, restored: refused, or a state the
        model can be in; then the true state back."""
        L, c = self.lib, self.c
        data = self.serialized()
        if data is None:
            return
        # The true state first: it must be accepted (but for the Error
        # state, which the FMU restores in no instance, by design).
        good = c_void_p()
        r = self.call("fmi3DeserializeFMUState(true)", L.fmi3DeserializeFMUState, c, data, len(data), byref(good))
        if r != OK:
            if "instance state Error" in self.last(1):
                self.state = ERRORED
            else:
                self.report(f"a true serialized state (in {self.state}) was refused: {self.last(1)}")
            return
        L.fmi3FreeFMUState(c, byref(good))
        self.states_tried += 1
        before = (self.state, self.time)
        bad = self.corrupt(data)
        s = c_void_p()
        r = self.call("fmi3DeserializeFMUState", L.fmi3DeserializeFMUState, c, bad, len(bad), byref(s))
        if r != OK:
            self.check_outputs("refused fmi3DeserializeFMUState")
        elif self.call("fmi3SetFMUState(corrupted)", L.fmi3SetFMUState, c, s) == OK:
            self.state = None  # unknown: read what we can
            self.pending_event = None
            r, (t,) = self.get("Float64", [self.time_var.valueReference], raw=True)
            if r == OK:
                self.time = t
                if not math.isfinite(t):
                    self.report(f"a restored corrupted state has time {t}")
                outs = [v.valueReference for v in self.outputs]
                if self.get("Float64", outs, raw=True)[0] == OK:
                    self.state = STEP  # for check_outputs: every check, no state-machine promise
                    self.check_outputs("restored corrupted state")
                    self.state = None
                    if not self.options["event"] and self.call("fmi3EnterStepMode(probe)", L.fmi3EnterStepMode, c) == OK:
                        self.report("a restored corrupted state put an instance without eventModeUsed in event mode")
                    self.do_step(t, 0.01, "fmi3DoStep(after corrupted)")
            L.fmi3FreeFMUState(c, byref(s))
        else:
            L.fmi3FreeFMUState(c, byref(s))
        # back to the true state, accepted above
        good = c_void_p()
        if L.fmi3DeserializeFMUState(c, data, len(data), byref(good)) == OK and L.fmi3SetFMUState(c, good) == OK:
            L.fmi3FreeFMUState(c, byref(good))
            self.state, self.time = before
            self.check_outputs("the true state restored")
        else:
            self.report(f"a true serialized state, accepted once, was refused: {self.last(1)}")
            self.state = None

    def run(self, calls: int) -> dict:
        while self.calls < calls:
            self.move()
        if self.c is not None:
            self.free()
        return {"fmu": self.md.coSimulation.modelIdentifier, "fmi": 3, "seed": self.seed, "calls": self.calls,
                "states": self.states_tried, "longest_s": self.longest[0], "longest_call": self.longest[1],
                "counts": dict(self.counts), "work_line_required": self.work_required,
                "broken": self.broken[:20], "n_broken": len(self.broken), "first_trace": self.first_trace}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fmu", required=True)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--calls", type=int, default=10000)
    ap.add_argument("--work-line", choices=("required", "optional"), default="required" if WORK_LINE_REQUIRED else "optional",
                    help="whether every fmi3DoStep that runs must log its work line (logAll)")
    a = ap.parse_args()
    h = Harness3(a.fmu, a.seed)
    h.work_required = a.work_line == "required"
    print(json.dumps(h.run(a.calls)))


if __name__ == "__main__":
    sys.exit(main())
