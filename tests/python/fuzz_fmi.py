"""A seeded fuzzer of the FMU's C API: random FMI call sequences and
corrupted serialized states, through ctypes on the FMU's shared library.

    python tests/python/fuzz_fmi.py --fmu target/fmu/PinnedBeamStop.fmu --seed 1 --calls 100000

(the long run; tests/python/test_fuzz.py runs a bounded one over every FMU
in CI). `--fmi 3` fuzzes an FMI 3.0 FMU (target/fmu3/*.fmu) through its
fmi3 functions instead: tests/python/fuzz_fmi3.py, which shares this
file's helpers. Each run prints a JSON summary: calls made, corrupted states tried,
the longest single call, every broken promise with the seed and call
index that reproduce it, and the calls before the first (with the values
set). Parameter and input values are drawn over the whole
admitted range too (`admitted_value`: the ends, the start value, log-uniform
magnitudes inside wide ranges, uniform). Promises checked after every call:

- the return is a legal fmi2Status; the call returns within LIMIT s (a hang
  detector only: the work bound is the next promise);
- every fmi2DoStep that runs logs, with the category logAll on (the fuzzer
  turns it on in every instance), one line `fmi2DoStep: work W of C <unit>
  (the step's cap)` with W <= C: the work the FMU counted against its cap
  (WORK_LINE_REQUIRED = False, or --work-line optional, tolerates an FMU
  that does not log it yet);
- outputs read with fmi2OK are finite, and no stop is penetrated beyond
  rounding (its displacement against its gap parameter and side);
- a call refused for a bad argument (fmi2Error while the instance was
  stepping) leaves the instance usable: a following fmi2GetReal succeeds;
- a corrupted serialized state is refused, or the state it gives is one the
  model can be in (the same output checks, then a step that returns);
- rollback (`rollback`, also right after a set of an input or a tunable
  parameter): every state the FMU serializes deserializes into another
  instance, which then takes the same fmi2DoStep with the same status and
  the same outputs bit for bit; restored into the instance it came from
  (step, restore, step again), the step repeats bit for bit too.
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
import re
import shutil
import struct
import sys
import tempfile
import time
import weakref
import zipfile
from ctypes import POINTER, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p
from pathlib import Path

from fmpy import read_model_description
from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

LIMIT = 120.0  # seconds: a hang detector only (the work a step does is bounded by its logged cap)
# The line every fmi2DoStep / fmi3DoStep logs (category logAll) after its work.
WORK_LINE = re.compile(r"(fmi[23]DoStep): work (\d+) of (\d+) (.+) \(the step's cap\)")
# Until every FMU logs it: False (or --work-line optional) accepts a DoStep without the line.
WORK_LINE_REQUIRED = True
OK, WARNING, DISCARD, ERROR, FATAL, PENDING = range(6)
STEP_COMPLETE, STEP_FAILED, READABLE = "stepComplete", "stepFailed", ("init", "stepComplete", "stepFailed", "terminated")


def admitted_value(v, rng: random.Random, kinds=("lo", "hi", "start", "uniform", "log", "log")) -> float:
    """A value over the variable's whole admitted range [min, max]: an end,
    its start value, uniform, or log-uniform: over [min, max] when both are
    positive and span more than 2 decades, else magnitudes over the 12
    decades below the largest bound, with the range's sign(s) (a tolerance of
    1e-6 in [1e-13, 1e-3], a damping of 1 in [0, 1e8], an initial coordinate
    of 1 in [-500, 500] are all drawn often)."""
    lo, hi = float(v.min), float(v.max)
    kind = rng.choice(kinds)
    if kind == "lo":
        return lo
    if kind == "hi":
        return hi
    if kind == "start" and v.start is not None:
        return float(v.start)
    if kind in ("log", "start"):
        if lo > 0 and hi / lo > 100:
            return min(hi, max(lo, math.exp(rng.uniform(math.log(lo), math.log(hi)))))
        m = max(abs(lo), abs(hi))
        if m > 0 and (lo >= 0 or hi <= 0 or m > 100):
            x = math.exp(rng.uniform(math.log(m) - 12 * math.log(10), math.log(m)))
            sign = 1.0 if lo >= 0 else -1.0 if hi <= 0 else rng.choice([-1.0, 1.0])
            return min(hi, max(lo, sign * x))
    return rng.uniform(lo, hi)


class Harness:
    # The statuses a call may return (FMI 3.0 has no Pending).
    LEGAL = (OK, WARNING, DISCARD, ERROR, FATAL, PENDING)

    def __init__(self, fmu: str, seed: int):
        self.rng = random.Random(seed)
        self.seed = seed
        self.md = read_model_description(fmu)
        self.dir = Path(tempfile.mkdtemp(prefix="fuzz"))
        weakref.finalize(self, shutil.rmtree, self.dir, ignore_errors=True)  # the extracted FMU
        with zipfile.ZipFile(fmu) as z:
            z.extractall(self.dir)
        ident = self.md.coSimulation.modelIdentifier
        self.lib = ctypes.CDLL(str(self.dir / "binaries" / "linux64" / f"{ident}.so"))
        self._types()
        self.messages: collections.deque[str] = collections.deque(maxlen=200)
        self.work_lines: list[tuple] = []  # (function, work, cap, unit) of every work line logged
        self.work_required = WORK_LINE_REQUIRED

        def log(env, name, status, category, message):
            m = message.decode("utf-8", "replace")
            self.messages.append(m)
            w = WORK_LINE.search(m)
            if w:
                self.work_lines.append((w.group(1), int(w.group(2)), int(w.group(3)), w.group(4)))

        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(log)
        self.reals = [v for v in self.md.modelVariables if v.type == "Real"]
        self.ints = [v for v in self.md.modelVariables if v.type == "Integer"]
        self.bools = [v for v in self.md.modelVariables if v.type == "Boolean"]
        self.settable = [v for v in self.reals if v.causality in ("parameter", "input")]
        self.outputs = [v for v in self.reals if v.causality == "output"]
        self.n_vr = len(self.md.modelVariables)
        self.stops = self._stops()
        self.c = None
        self.state = None  # our model of the instance's state machine
        self.time = 0.0
        self.snapshots: dict[int, str] = {}
        self.calls = 0
        self.states_tried = 0
        self.longest = (0.0, "")
        self.broken: list[str] = []
        self.recent: collections.deque[str] = collections.deque(maxlen=60)  # the latest calls, for reports
        self.first_trace: list[str] = []  # the calls up to the first broken promise
        self.dump_dir: Path | None = None  # --dump: where the states a broken promise concerns go
        self.last_state: bytes | None = None
        self.log_all = False  # whether the instance logs the category logAll
        self.twin = None  # a second instance, for states restored across instances
        ex = self.md.defaultExperiment
        self.h_experiment = float(ex.stepSize) if ex is not None and ex.stepSize is not None else 0.01
        self.counts = collections.Counter()

    # ---------------------------------------------------------------- setup
    def _types(self):
        L = self.lib
        sig = {
            "fmi2Instantiate": (c_void_p, [c_char_p, c_int, c_char_p, c_char_p, c_void_p, c_int, c_int]),
            "fmi2FreeInstance": (None, [c_void_p]),
            "fmi2SetupExperiment": (c_int, [c_void_p, c_int, c_double, c_double, c_int, c_double]),
            "fmi2EnterInitializationMode": (c_int, [c_void_p]),
            "fmi2ExitInitializationMode": (c_int, [c_void_p]),
            "fmi2Terminate": (c_int, [c_void_p]),
            "fmi2Reset": (c_int, [c_void_p]),
            "fmi2GetReal": (c_int, [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_double)]),
            "fmi2SetReal": (c_int, [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_double)]),
            "fmi2GetInteger": (c_int, [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_int)]),
            "fmi2GetBoolean": (c_int, [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_int)]),
            "fmi2DoStep": (c_int, [c_void_p, c_double, c_double, c_int]),
            "fmi2CancelStep": (c_int, [c_void_p]),
            "fmi2GetRealStatus": (c_int, [c_void_p, c_int, POINTER(c_double)]),
            "fmi2GetBooleanStatus": (c_int, [c_void_p, c_int, POINTER(c_int)]),
            "fmi2GetStatus": (c_int, [c_void_p, c_int, POINTER(c_int)]),
            "fmi2GetFMUstate": (c_int, [c_void_p, POINTER(c_void_p)]),
            "fmi2SetFMUstate": (c_int, [c_void_p, c_void_p]),
            "fmi2FreeFMUstate": (c_int, [c_void_p, POINTER(c_void_p)]),
            "fmi2SerializedFMUstateSize": (c_int, [c_void_p, c_void_p, POINTER(c_size_t)]),
            "fmi2SerializeFMUstate": (c_int, [c_void_p, c_void_p, c_char_p, c_size_t]),
            "fmi2DeSerializeFMUstate": (c_int, [c_void_p, c_char_p, c_size_t, POINTER(c_void_p)]),
            "fmi2SetDebugLogging": (c_int, [c_void_p, c_int, c_size_t, POINTER(c_char_p)]),
        }
        for name, (res, args) in sig.items():
            f = getattr(L, name)
            f.restype, f.argtypes = res, args

    def _stops(self):
        """(displacement output, gap parameter, side) of every stop, from the scene."""
        scene = json.loads((self.dir / "resources" / "scene.json").read_text())
        names = {v.name for v in self.md.modelVariables}
        out = []
        for s in scene.get("stops", []):
            if s["law"]["type"] != "restitution":
                continue  # a compliant stop may be penetrated: its force is checked instead
            rename = s.get("names", {})
            w = rename.get("w", f"{s['name']}.w")
            gap = rename.get("gap", f"{s['name']}.gap")
            if w in names and gap in names:
                out.append((self.var(w), self.var(gap), 1.0 if s.get("side", "positive") == "positive" else -1.0))
        return out

    def var(self, name):
        return next(v for v in self.md.modelVariables if v.name == name)

    # ---------------------------------------------------------------- calls
    def call(self, what: str, f, *args):
        if self.broken and not self.first_trace:
            self.first_trace = list(self.recent)
        t0 = time.perf_counter()
        r = f(*args)
        dt = time.perf_counter() - t0
        self.calls += 1
        self.recent.append(f"{self.calls}: {what} -> {r}")
        if dt > self.longest[0]:
            self.longest = (dt, what)
        if dt > LIMIT:
            self.broken.append(f"seed {self.seed} call {self.calls}: {what} took {dt:.1f} s")
        if f.restype is c_int and r not in self.LEGAL:
            self.broken.append(f"seed {self.seed} call {self.calls}: {what} returned {r}")
        return r

    def value(self, v=None) -> float:
        pool = [0.0, 1.0, -1.0, 1e-300, 5e-324, -5e-324, 1e308, -1e308, 1e150, math.nan, math.inf, -math.inf]
        if v is not None and v.min is not None and v.max is not None:
            lo, hi = float(v.min), float(v.max)
            pool += [lo, hi, lo - abs(lo) * 1e-12 - 1e-300, hi + abs(hi) * 1e-12 + 1e-300, self.rng.uniform(lo, hi)] * 3
        if v is not None and v.start is not None:
            pool += [float(v.start)] * 3
        if v is not None and v.min is not None and v.max is not None:
            # the whole admitted range: ends, log-uniform inside wide ranges, uniform
            pool += [admitted_value(v, self.rng) for _ in range(10)]
        return self.rng.choice(pool)

    def vr(self, pool):
        if self.rng.random() < 0.1:
            return self.rng.choice([self.n_vr, self.n_vr + 7, 2**32 - 1])
        return self.rng.choice(pool).valueReference

    def instantiate(self):
        self.c = self.call("fmi2Instantiate", self.lib.fmi2Instantiate, b"fuzz", 1, self.md.guid.encode(),
                           (self.dir / "resources").as_uri().encode(), byref(self.callbacks), 0, self.rng.random() < 0.3)
        assert self.c, "fmi2Instantiate returned NULL: " + " | ".join(list(self.messages)[-3:])
        self.state = "instantiated"
        self.time = 0.0
        self.log_all = self.logging(self.c, True, [b"logAll"]) == OK

    def logging(self, c, on: bool, categories: list[bytes]) -> int:
        arr = (c_char_p * max(1, len(categories)))(*categories) if categories else None
        return self.call("fmi2SetDebugLogging", self.lib.fmi2SetDebugLogging, c, on, len(categories), arr)

    def work_check(self, what: str, n_lines: int, r: int, log_all: bool | None = None):
        """The work line(s) a DoStep logged since `n_lines` (len(self.work_lines) before it):
        one, with work <= cap, for a step that ran (OK, Warning, Discard)."""
        new = self.work_lines[n_lines:]
        for f, work, cap, unit in new:
            self.counts["work_lines"] += 1
            if work > cap:
                self.report(f"{what}: work {work} of {cap} {unit} exceeds the step's cap")
        ran = r in (OK, WARNING, DISCARD)
        if ran and (self.log_all if log_all is None else log_all):
            if not new:
                self.counts["no_work_line"] += 1
                if self.work_required:
                    self.report(f"{what} returned {r} without a work line (logAll on): {' | '.join(list(self.messages)[-2:])}")
            elif len(new) > 1:
                self.report(f"{what} logged {len(new)} work lines, not one")

    def report(self, what: str):
        self.broken.append(f"seed {self.seed} call {self.calls}: {what}")
        self.dump_state()

    def dump_state(self):
        """With --dump, to replay a broken promise without the calls before
        it: the bytes of the state serialized last (the one a restore or a
        rollback broke on), DIR/seed-S-call-N-last.bin, and of the current
        state where the instance can save it, DIR/seed-S-call-N-now.bin (no
        call of the run's own: the run is the same with and without)."""
        if self.dump_dir is None:
            return
        self.dump_dir.mkdir(parents=True, exist_ok=True)
        stem = self.dump_dir / f"seed-{self.seed}-call-{self.calls}"
        if self.last_state is not None:
            stem.with_name(stem.name + "-last.bin").write_bytes(self.last_state)
        kept = list(self.messages)  # what the instance logs here is not the run's
        now = self.state_bytes() if self.c is not None else None
        self.messages.clear()
        self.messages.extend(kept)
        if now is not None:
            stem.with_name(stem.name + "-now.bin").write_bytes(now)

    def state_bytes(self) -> bytes | None:
        """The current state serialized, or None."""
        L, c = self.lib, self.c
        s = c_void_p()
        if L.fmi2GetFMUstate(c, byref(s)) != OK:
            return None
        size = c_size_t()
        ok = L.fmi2SerializedFMUstateSize(c, s, byref(size)) == OK
        buf = ctypes.create_string_buffer(size.value)
        ok = ok and L.fmi2SerializeFMUstate(c, s, buf, size.value) == OK
        L.fmi2FreeFMUstate(c, byref(s))
        return bytes(buf.raw) if ok else None

    # ---------------------------------------------------------------- checks
    def check_outputs(self, where: str):
        if self.state not in READABLE:
            return
        vrs = [v.valueReference for v in self.outputs]
        arr = (c_uint * len(vrs))(*vrs)
        vals = (c_double * len(vrs))()
        r = self.call("fmi2GetReal(outputs)", self.lib.fmi2GetReal, self.c, arr, len(vrs), vals)
        if r != OK:
            if self.state in ("stepComplete", "stepFailed", "terminated"):
                self.broken.append(f"seed {self.seed} call {self.calls}: outputs unreadable after {where}: "
                                   + " | ".join(list(self.messages)[-2:]))
            return
        got = dict(zip(vrs, vals))
        for v in self.outputs:
            if not math.isfinite(got[v.valueReference]):
                self.report(f"{v.name} = {got[v.valueReference]} after {where}")
        for v in self.outputs:
            # Stop forces and impulses push, never pull.
            if v.name.endswith((".force", ".impulse", ".E_stored", ".E_dissipated")) and got[v.valueReference] < -1e-9 * max(1.0, abs(got[v.valueReference])):
                self.report(f"{v.name} = {got[v.valueReference]} < 0 after {where}")
        for w, gap, side in self.stops:
            g = (c_double * 1)()
            self.lib.fmi2GetReal(self.c, (c_uint * 1)(gap.valueReference), 1, g)
            y = got[w.valueReference]
            penetration = side * y - g[0]
            # Rounding is relative to the largest displacement the model
            # admits (the gap's declared bound, 1000 structure lengths).
            if penetration > 1e-9 * (abs(g[0]) + abs(y)) + 1e-15 * float(gap.max):
                self.report(f"{w.name} = {y} penetrates gap {g[0]} after {where}")

    # ---------------------------------------------------------------- moves
    def move(self):
        rng = self.rng
        if self.c is None:
            self.instantiate()
            return
        L, c = self.lib, self.c
        op = rng.choices(
            ["setup", "enter", "exit", "set", "get", "geti", "step", "step", "step", "getstate", "setstate",
             "serialize", "reset", "terminate", "cancel", "status", "logging", "free", "rollback"],
            weights=[3, 3, 3, 12, 6, 2, 12, 12, 12, 3, 3, 3, 1, 1, 1, 2, 1, 0.3, 4])[0]
        if op == "setup":
            start = rng.choice([0.0, 0.0, 0.0, 1.5, -3.0, 1e6, 1e15, math.nan, math.inf])
            stop_defined = rng.random() < 0.5
            r = self.call("fmi2SetupExperiment", L.fmi2SetupExperiment, c, 0, 0.0, start, stop_defined,
                          rng.choice([start + 100.0, start - 1.0, math.nan]))
            if r == OK:
                self.time = start
        elif op == "enter":
            if self.call("fmi2EnterInitializationMode", L.fmi2EnterInitializationMode, c) == OK:
                self.state = "init"
        elif op == "exit":
            if self.call("fmi2ExitInitializationMode", L.fmi2ExitInitializationMode, c) == OK:
                self.state = STEP_COMPLETE
                self.check_outputs("fmi2ExitInitializationMode")
        elif op == "set":
            n = rng.choice([1, 1, 1, 2, 3])
            vars_ = [rng.choice(self.settable) for _ in range(n)]
            vrs = [self.vr(self.settable) if rng.random() < 0.2 else v.valueReference for v in vars_]
            vals = [self.value(v) for v in vars_]
            r = self.call(f"fmi2SetReal {vrs}={vals}", L.fmi2SetReal, c, (c_uint * n)(*vrs), n, (c_double * n)(*vals))
            if r == ERROR and self.state == STEP_COMPLETE:
                self.check_outputs(f"refused fmi2SetReal {vrs}={vals}")
            elif r == OK:
                self.check_outputs(f"fmi2SetReal {vrs}={vals}")
                if self.state == STEP_COMPLETE and rng.random() < 0.3:
                    self.rollback(f"right after fmi2SetReal {vrs}={vals}")
        elif op == "get":
            n = rng.choice([1, 2, 5])
            vrs = [self.vr(self.reals) for _ in range(n)]
            self.call("fmi2GetReal", L.fmi2GetReal, c, (c_uint * n)(*vrs), n, (c_double * n)())
        elif op == "geti":
            pool = self.ints or self.reals
            vrs = [self.vr(pool)]
            self.call("fmi2GetInteger", L.fmi2GetInteger, c, (c_uint * 1)(*vrs), 1, (c_int * 1)())
            if self.bools:
                self.call("fmi2GetBoolean", L.fmi2GetBoolean, c, (c_uint * 1)(self.vr(self.bools)), 1, (c_int * 1)())
        elif op == "step":
            h = rng.choice([1e-3, 1e-2, 1e-2, 0.1, 1.0, 1e-12, 1e-300, 5e-324, 50.0, 1e3, 0.0, -1.0, math.nan, math.inf])
            t = self.time if rng.random() < 0.9 else rng.choice([self.time + 1.0, math.nan, -1.0])
            n_lines = len(self.work_lines)
            r = self.call(f"fmi2DoStep(t={t}, h={h})", L.fmi2DoStep, c, t, h, 1)
            self.work_check(f"fmi2DoStep(t={t}, h={h})", n_lines, r)
            if r == OK:
                self.time = t + h
                self.check_outputs(f"fmi2DoStep(h={h})")
            elif r == DISCARD:
                reached = c_double()
                L.fmi2GetRealStatus(c, 2, byref(reached))
                if not (math.isfinite(reached.value) and reached.value >= self.time):
                    self.broken.append(f"seed {self.seed} call {self.calls}: discarded step reports time {reached.value}")
                self.state = STEP_FAILED
                self.check_outputs("discarded fmi2DoStep")
            elif r == ERROR and self.state == STEP_COMPLETE:
                self.check_outputs(f"refused fmi2DoStep(t={t}, h={h})")
        elif op == "getstate":
            s = c_void_p()
            if self.call("fmi2GetFMUstate", L.fmi2GetFMUstate, c, byref(s)) == OK:
                self.snapshots[s.value] = (self.state, self.time)
        elif op == "setstate" and self.snapshots:
            key = rng.choice(list(self.snapshots))
            if self.call("fmi2SetFMUstate", L.fmi2SetFMUstate, c, c_void_p(key)) == OK:
                self.state, self.time = self.snapshots[key]
                self.check_outputs("fmi2SetFMUstate")
        elif op == "serialize":
            self.serialize_round_trip()
        elif op == "reset":
            if self.call("fmi2Reset", L.fmi2Reset, c) == OK:
                self.state, self.time = "instantiated", 0.0
        elif op == "terminate":
            if self.call("fmi2Terminate", L.fmi2Terminate, c) == OK:
                self.state = "terminated"
        elif op == "cancel":
            self.call("fmi2CancelStep", L.fmi2CancelStep, c)
        elif op == "status":
            self.call("fmi2GetStatus", L.fmi2GetStatus, c, rng.randrange(-1, 6), byref(c_int()))
            self.call("fmi2GetRealStatus", L.fmi2GetRealStatus, c, rng.randrange(-1, 6), byref(c_double()))
            self.call("fmi2GetBooleanStatus", L.fmi2GetBooleanStatus, c, rng.randrange(-1, 6), byref(c_int()))
        elif op == "logging":
            cats = [b"logEvents", b"logAll", b"nonsense"][: rng.randrange(0, 4)]
            on = rng.random() < 0.5
            if self.logging(c, on, cats) == OK and (not cats or b"logAll" in cats):
                self.log_all = on
            if not self.log_all and rng.random() < 0.7:
                self.log_all = self.logging(c, True, [b"logAll"]) == OK  # mostly on: the work check needs it
        elif op == "rollback":
            self.rollback("")
        elif op == "free":
            self.free()

    def free(self):
        L, c = self.lib, self.c
        for key in list(self.snapshots):
            L.fmi2FreeFMUstate(c, byref(c_void_p(key)))
        self.snapshots.clear()
        self.call("fmi2FreeInstance", L.fmi2FreeInstance, c)
        self.c = None
        if self.twin is not None:
            L.fmi2FreeInstance(self.twin)
            self.twin = None

    # ---------------------------------------------------------------- rollback
    def outputs_bits(self, c) -> bytes:
        """Every output (Real, Integer, Boolean) as raw bytes: compared bit for bit."""
        L = self.lib
        out = b""
        for pool, get, ctype in ((self.outputs, L.fmi2GetReal, c_double),
                                 ([v for v in self.ints if v.causality == "output"], L.fmi2GetInteger, c_int),
                                 ([v for v in self.bools if v.causality == "output"], L.fmi2GetBoolean, c_int)):
            if pool:
                vals = (ctype * len(pool))()
                r = get(c, (c_uint * len(pool))(*[v.valueReference for v in pool]), len(pool), vals)
                out += bytes([r]) + bytes(vals)
        return out

    def rollback_step(self, c, t: float, h: float, who: str, log_all: bool):
        """fmi2DoStep(t, h) on c: (status, lastSuccessfulTime on Discard, outputs)."""
        n_lines = len(self.work_lines)
        r = self.call(f"fmi2DoStep(t={t}, h={h}) ({who})", self.lib.fmi2DoStep, c, t, h, 0)
        self.work_check(f"fmi2DoStep(t={t}, h={h}) ({who})", n_lines, r, log_all)
        reached = c_double(math.nan)
        if r == DISCARD:
            self.lib.fmi2GetRealStatus(c, 2, byref(reached))
        return r, reached.value.hex(), self.outputs_bits(c) if r in (OK, WARNING, DISCARD) else b""

    def restore_into(self, c, data: bytes) -> tuple[int, str]:
        L = self.lib
        s = c_void_p()
        r = self.call("fmi2DeSerializeFMUstate(rollback)", L.fmi2DeSerializeFMUstate, c, data, len(data), byref(s))
        if r != OK:
            return r, "fmi2DeSerializeFMUstate: " + " | ".join(list(self.messages)[-1:])
        r = self.call("fmi2SetFMUstate(rollback)", L.fmi2SetFMUstate, c, s)
        L.fmi2FreeFMUstate(c, byref(s))
        return r, "" if r == OK else "fmi2SetFMUstate: " + " | ".join(list(self.messages)[-1:])

    def rollback(self, why: str):
        """A master's rollback: save (get + serialize), step; the state
        deserialized into a second instance takes the same step, and restored
        into this one, steps again: the same status, the same outputs, bit for bit."""
        if self.state != STEP_COMPLETE or self.c is None or not math.isfinite(self.time):
            return
        L, rng = self.lib, self.rng
        data = self.serialized()
        if data is None:
            self.report(f"fmi2GetFMUstate/fmi2SerializeFMUstate failed in stepComplete {why}")
            return
        self.counts["rollbacks"] += 1
        t = self.time
        h = rng.choice([self.h_experiment, 10 * self.h_experiment, 1e-3, 1e-2])
        where = f"state saved at t = {t!r}{' ' + why if why else ''}, then fmi2DoStep(h={h})"
        first = self.rollback_step(self.c, t, h, "original", self.log_all)
        if self.twin is None:
            self.twin = L.fmi2Instantiate(b"twin", 1, self.md.guid.encode(), (self.dir / "resources").as_uri().encode(),
                                          byref(self.callbacks), 0, 0)
            self.twin_log_all = self.logging(self.twin, True, [b"logAll"]) == OK
        r, msg = self.restore_into(self.twin, data)
        if r != OK and "instance state Error" in msg:
            # the instance was in the Error state (a step that failed), which no instance restores, by design
            self.counts["error_state_saved"] += 1
            self.state = None
            return
        if r != OK:
            self.report(f"a state the FMU serialized was refused by another instance ({where}): {msg}")
        else:
            self.counts["restored_elsewhere"] += 1
            again = self.rollback_step(self.twin, t, h, "another instance", self.twin_log_all)
            if again != first:
                self.report(f"restored in another instance, the step differs ({where}): status {first[0]} vs {again[0]}, "
                            f"outputs {'differ' if first[2] != again[2] else 'equal'}")
        if rng.random() < 0.5:
            # step, restore, step again: the same instance
            r, msg = self.restore_into(self.c, data)
            if r != OK:
                self.report(f"a state the FMU serialized was refused by its own instance ({where}): {msg}")
                self.state = None
                return
            self.counts["restored_here"] += 1
            again = self.rollback_step(self.c, t, h, "rolled back", self.log_all)
            if again != first:
                self.report(f"rolled back, the step differs ({where}): status {first[0]} vs {again[0]}, "
                            f"outputs {'differ' if first[2] != again[2] else 'equal'}")
        r = first[0]
        if r == OK:
            self.time = t + h
            self.check_outputs(f"fmi2DoStep(h={h}) after a rollback")
        elif r == DISCARD:
            self.state = STEP_FAILED
        elif r != WARNING:
            self.state = None

    def serialized(self):
        L, c = self.lib, self.c
        s = c_void_p()
        if L.fmi2GetFMUstate(c, byref(s)) != OK:
            return None
        size = c_size_t()
        L.fmi2SerializedFMUstateSize(c, s, byref(size))
        buf = ctypes.create_string_buffer(size.value)
        L.fmi2SerializeFMUstate(c, s, buf, size.value)
        L.fmi2FreeFMUstate(c, byref(s))
        self.last_state = bytes(buf.raw)
        return self.last_state

    def corrupt(self, data: bytes) -> bytes:
        rng = self.rng
        b = bytearray(data)
        kind = rng.randrange(5)
        if kind == 0 and len(b) > 8:  # a double slot
            k = rng.randrange(0, len(b) - 8)
            struct.pack_into("<d", b, k, rng.choice([math.nan, math.inf, -math.inf, 1e308, -1e300, 5e-324, 1e6, -0.5]))
        elif kind == 1:  # random bytes
            for _ in range(rng.randint(1, 4)):
                b[rng.randrange(len(b))] = rng.randrange(256)
        elif kind == 2:  # truncate
            del b[rng.randrange(len(b)):]
        elif kind == 3:  # extend
            b += bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
        else:  # an integer field (counts, flags, lengths)
            k = rng.randrange(0, max(1, len(b) - 8))
            struct.pack_into("<Q", b, k, rng.choice([0, 1, 2**63, 2**64 - 1, 64, 3]))
        return bytes(b)

    def serialize_round_trip(self):
        """A serialized state, corrupted, restored: refused, or a state the
        model can be in."""
        L, c = self.lib, self.c
        data = self.serialized()
        if data is None:
            return
        self.states_tried += 1
        before = (self.state, self.time)
        if before[0] == "error":
            return
        bad = self.corrupt(data)
        s = c_void_p()
        r = self.call("fmi2DeSerializeFMUstate", L.fmi2DeSerializeFMUstate, c, bad, len(bad), byref(s))
        if r != OK:
            self.check_outputs("refused fmi2DeSerializeFMUstate")
            return
        if self.call("fmi2SetFMUstate(corrupted)", L.fmi2SetFMUstate, c, s) == OK:
            t = c_double()
            L.fmi2GetRealStatus(c, 2, byref(t))
            self.time = t.value
            self.state = None  # unknown: read what we can
            outs = (c_double * len(self.outputs))()
            vrs = (c_uint * len(self.outputs))(*[v.valueReference for v in self.outputs])
            if L.fmi2GetReal(c, vrs, len(self.outputs), outs) == OK:
                self.state = STEP_COMPLETE
                self.check_outputs("restored corrupted state")
                n_lines = len(self.work_lines)
                r = self.call("fmi2DoStep(after corrupted)", L.fmi2DoStep, c, self.time, 0.01, 1)
                self.work_check("fmi2DoStep(after corrupted)", n_lines, r)
                if r == OK:
                    self.time += 0.01
                    self.check_outputs("step after a restored corrupted state")
        L.fmi2FreeFMUstate(c, byref(s))
        # back to the true state, which must be accepted
        good = c_void_p()
        if L.fmi2DeSerializeFMUstate(c, data, len(data), byref(good)) == OK:
            L.fmi2SetFMUstate(c, good)
            L.fmi2FreeFMUstate(c, byref(good))
            self.state, self.time = before
        else:
            self.broken.append(f"seed {self.seed} call {self.calls}: a true serialized state was refused: "
                               + " | ".join(list(self.messages)[-2:]))

    def run(self, calls: int) -> dict:
        while self.calls < calls:
            self.move()
        if self.c is not None:
            self.free()
        return {"fmu": self.md.coSimulation.modelIdentifier, "seed": self.seed, "calls": self.calls,
                "states": self.states_tried, "longest_s": self.longest[0], "longest_call": self.longest[1],
                "counts": dict(self.counts), "work_line_required": self.work_required,
                "broken": self.broken[:20], "n_broken": len(self.broken), "first_trace": self.first_trace}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fmu", required=True)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--calls", type=int, default=10000)
    ap.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="the FMI version of the FMU (default 2)")
    ap.add_argument("--work-line", choices=("required", "optional"), default="required" if WORK_LINE_REQUIRED else "optional",
                    help="whether every DoStep that runs must log its work line (logAll)")
    ap.add_argument("--dump", metavar="DIR", help="at each broken promise, write the state serialized last and the current one to DIR")
    a = ap.parse_args()
    if a.fmi == 3:
        from fuzz_fmi3 import Harness3

        h = Harness3(a.fmu, a.seed)
    else:
        h = Harness(a.fmu, a.seed)
    h.work_required = a.work_line == "required"
    h.dump_dir = Path(a.dump) if a.dump else None
    print(json.dumps(h.run(a.calls)))


if __name__ == "__main__":
    sys.exit(main())
