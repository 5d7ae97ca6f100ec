"""Rollback sweep: every state an FMU serializes must deserialize and
continue bit for bit (issue 41), for every FMU, FMI 2.0 and FMI 3.0.

    python tests/python/rollback_sweep.py                      # the full sweep, every FMU, both standards
    python tests/python/rollback_sweep.py --quick              # the bounded subset CI runs (test_rollback_sweep.py)
    python tests/python/rollback_sweep.py --fmu HertzStop --fmi 3 --fuzz 200 --seed 5
    python tests/python/rollback_sweep.py --fmu target/fmu/PinnedBeamStop.fmu   # a path: its standard from the file

A run does what an iterating co-simulation master does, through ctypes on
the FMU's shared library: before every communication step it sets the
inputs, saves the state (get + serialize), steps; every saved state is
deserialized into a second instance made with the same flags (a fresh one
per run, its first restore into a just-instantiated instance), which then
takes the same calls up to and including the next fmi2DoStep/fmi3DoStep
(event-mode calls and input sets included): statuses, the DoStep flags and
lastSuccessfulTime, and every output (reals as bit patterns, integers,
booleans) must be identical.

FMI 3.0 runs are made with each of the 4 combinations of eventModeUsed and
earlyReturnAllowed. A master with early return steps on from
lastSuccessfulTime to the end of its communication step; with event mode,
after eventHandlingNeeded it saves (step mode, event pending), enters event
mode, saves, calls fmi3UpdateDiscreteStates (saving before each) until no
more is needed, saves, and enters step mode. Each state is also restored
into an instance made with other flags (initialised at the defaults: the
state must bring its parameters), which continues as a master with its
flags would (no event-mode call without eventModeUsed) to the end of the
communication step. There its outputs must be the original's, bit for bit
(but `impulse`, which is over the last DoStep, between instances that
differ in earlyReturnAllowed), or, where the runs made with the two flags
already differ there without any restore, it is counted apart
(`cross_flag_dependent`, not a failure; `flag_runs_differ` counts such
pairs of runs, `flag_dependence` shows examples); so is a continuation
from inside the step whose t + h cannot land on the step's end exactly
(`cross_time_unreachable`: outputs 1 ulp of time apart). A refusal is legal only
for a state saved in event mode, by an instance without eventModeUsed, with
fmi3Error and a message (issue 41, item 4); any other refusal counts as
refused.

The sweep, per FMU and standard (one factor at a time, the rest at the
defaults): the defaults; each parameter whose name holds "tolerance" at
both ends of its range and 10 log-spaced values between; each input at
{min, -1, 0, 1, max} (clipped, no duplicates) and 3 random values, set
before the saves of steps [0, n/3) and [2n/3, n), its start value between
(so an input is also set mid-run, whatever the contact state then is);
h = the experiment's stepSize and 10 h over the same horizon (HORIZON);
a save before every step; cross-flag restores into all three other
instances. `--quick` (CI): the tolerance ends and their geometric middle,
the 5 input values (no random ones) set only where they change, h only, a
horizon cut just after the first contacts, saves before steps 0..9, the
10 steps from each step that sets an input and every step of the window
that holds the contacts, cross-flag restores into one other instance per
state (in turn). `--fuzz N`: N sequences of random values for 1..all
parameters (fuzz_fmi.admitted_value: the ends, the start value,
log-uniform inside wide ranges, uniform), random inputs set before the
saves of random steps, h or 10 h and, for FMI 3.0, random flags (the
cross-flag references are the same sequence run with the other flags
without saves), over the --quick horizon, saves as --quick and before 10 %
of the other steps. `--param NAME=VALUE`
(repeatable): that setting alone (an input as the sweep sets inputs), every
flag and step of the sweep: the reproduction of a failure.

Prints (or writes, --out) a JSON summary: per FMU and standard, the counts
(runs; states saved, restored OK, refused, mismatched; cross-flag
restores OK, refused as allowed, refused and mismatched; runs refused at
initialisation, runs cut short by a step that did not complete) and the
failures by class (kind and message with its numbers masked), each with
its count and the first examples, with what reproduces them: FMU,
standard, setting, parameters, the inputs set before that step, flags
(and the other instance's), h, step index, time (and its hex), where the
state was saved, the message or the outputs that differ (original,
restored, in hex).
"""

from __future__ import annotations

import argparse
import ctypes
import json
import math
import random
import re
import shutil
import sys
import tempfile
import time
import zipfile
from ctypes import byref, c_double, c_int, c_int32, c_size_t, c_uint, c_uint8, c_void_p
from pathlib import Path
from types import SimpleNamespace

from fmpy import read_model_description
from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

from fuzz_fmi import DISCARD, ERROR, OK, WARNING, Harness, admitted_value
from fuzz_fmi3 import INTERMEDIATE_CALLBACK, LOG_CALLBACK, Harness3

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
DIRS = {2: ROOT / "target" / "fmu", 3: ROOT / "target" / "fmu3"}
FLAGS = [(False, False), (False, True), (True, False), (True, True)]  # (eventModeUsed, earlyReturnAllowed)

# FMU: (the horizon of a run, the --quick horizon, the time from which
# --quick saves before every step), in simulated time from 0, chosen so that
# each holds contacts or impacts at the defaults (first events: HertzStop
# and SpringStopVeryHard 0.0705 s, then a dozen within 1.5 ms;
# SpringStopHard 0.0705, 0.0742; SpringStopSoft 0.0825 onset, 0.0963
# separation; PinnedBeamStop starts stuck, events at 3.18 and from 6.377
# on; RotatingBeamImpact 9e-5, 5.8e-4, 6.7e-4, 1.29e-3;
# SteelCantileverStop from 0.0433; WaggBishopCantilever1/4 22.235, 23.92;
# WaggBishopChain 1.563, 8.02, 14.59; SpinUpBeam has no stop; TappingArm
# 0.1133 onset, 0.1248 separation). --quick
# saves before steps 0..9, before the 10 steps from each step that sets an
# input and before every step from the third number on; the full sweep
# before every step.
HORIZON = {
    "HertzStop": (0.075, 0.0735, 0.0700),
    "PinnedBeamStop": (7.0, 6.5, 6.35),
    "RotatingBeamImpact": (0.02, 0.0007, 0.0),
    "SpinUpBeam": (1.5, 0.3, 0.0),
    "SpringStopHard": (0.08, 0.0745, 0.0700),
    "SpringStopSoft": (0.1, 0.0835, 0.0820),
    "SpringStopVeryHard": (0.075, 0.0722, 0.0700),
    "SteelCantileverStop": (0.1, 0.048, 0.0),
    "TappingArm": (0.13, 0.116, 0.112),
    "WaggBishopCantilever1": (24.0, 22.4, 22.1),
    "WaggBishopCantilever4": (24.0, 22.4, 22.1),
    "WaggBishopChain": (15.0, 1.8, 0.0),
}
N_EXAMPLES = 2  # failures reported per class (kind and message), per FMU and standard
N_CLASSES = 20


def load(lib_path: str, fmi: int):
    """The FMU's shared library with the fmi2/fmi3 signatures of the fuzzers."""
    lib = ctypes.CDLL(lib_path)
    (Harness if fmi == 2 else Harness3)._types(SimpleNamespace(lib=lib))
    return lib


class Fmu:
    """One FMU file: its modelDescription, unzipped, its library loaded."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.md = read_model_description(str(path))
        self.fmi = 3 if self.md.fmiVersion.startswith("3") else 2
        self.name = self.md.coSimulation.modelIdentifier
        self.dir = Path(tempfile.mkdtemp(prefix="rollback"))
        with zipfile.ZipFile(path) as z:
            z.extractall(self.dir)
        platform = "x86_64-linux" if self.fmi == 3 else "linux64"
        self.lib = load(str(self.dir / "binaries" / platform / f"{self.name}.so"), self.fmi)
        mv = self.md.modelVariables
        real = "Float64" if self.fmi == 3 else "Real"
        integer = "Int32" if self.fmi == 3 else "Integer"
        self.vars = {v.name: v for v in mv}
        outs = [v for v in mv if v.causality == "output"]
        self.out_reals = [v for v in outs if v.type == real]
        if self.fmi == 3:
            self.out_reals += [v for v in mv if v.causality == "independent"]  # time
        self.out_ints = [v for v in outs if v.type == integer]
        self.out_bools = [v for v in outs if v.type == "Boolean"]
        self.out_names = [v.name for v in self.out_reals + self.out_ints + self.out_bools]
        self.parameters = [v for v in mv if v.causality == "parameter" and v.type == real]
        self.inputs = [v for v in mv if v.causality == "input" and v.type == real]
        self.tolerances = [v for v in self.parameters if "tolerance" in v.name]
        ex = self.md.defaultExperiment
        self.h = float(ex.stepSize)
        self.stop_time = float(ex.stopTime) if ex.stopTime is not None else None
        self._vr = {k: (ctypes.c_uint * max(1, len(vs)))(*[v.valueReference for v in vs])
                    for k, vs in (("r", self.out_reals), ("i", self.out_ints), ("b", self.out_bools))}

    def instance(self, label: str, flags=(False, False)):
        return (Instance2 if self.fmi == 2 else Instance3)(self, label, flags)


class Instance:
    """One instance: name-based sets, bitwise outputs, save and restore."""

    def __init__(self, fmu: Fmu, label: str, flags):
        self.fmu, self.lib, self.label, self.flags = fmu, fmu.lib, label, tuple(flags)
        self.messages: list[tuple[int, str]] = []
        self.c = None

    def _log(self, status: int, message: bytes | None):
        m = message.decode("utf-8", "replace") if message is not None else ""
        self.messages.append((int(status), m))
        if len(self.messages) > 50:
            del self.messages[:25]

    def last_error(self) -> str:
        for s, m in reversed(self.messages):
            if s >= ERROR:
                return m
        return self.messages[-1][1] if self.messages else ""

    def outputs(self) -> tuple[bytes, bytes, bytes]:
        f = self.fmu
        nr, ni, nb = len(f.out_reals), len(f.out_ints), len(f.out_bools)
        r = (c_double * max(1, nr))()
        i = (c_int32 * max(1, ni))()
        b = ((c_uint8 if f.fmi == 3 else c_int) * max(1, nb))()
        if nr:
            self._get("r", nr, r)
        if ni:
            self._get("i", ni, i)
        if nb:
            self._get("b", nb, b)
        return bytes(r), bytes(i), bytes(b)

    def decode(self, out) -> dict:
        """The named values of outputs() (for reports)."""
        f = self.fmu
        r = list((c_double * max(1, len(f.out_reals))).from_buffer_copy(out[0]))
        i = list((c_int32 * max(1, len(f.out_ints))).from_buffer_copy(out[1]))
        b = list(bytearray(out[2])) if f.fmi == 3 else list((c_int * max(1, len(f.out_bools))).from_buffer_copy(out[2]))
        vals = r[:len(f.out_reals)] + i[:len(f.out_ints)] + [bool(x) for x in b[:len(f.out_bools)]]
        return dict(zip(f.out_names, vals))


class Instance2(Instance):
    def __init__(self, fmu, label, flags):
        super().__init__(fmu, label, flags)
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(
            lambda env, name, status, cat, msg: self._log(status, msg.replace(b"%%", b"%") if msg else msg))
        md = fmu.md
        self.c = self.lib.fmi2Instantiate(label.encode(), 1, md.guid.encode(), (fmu.dir / "resources").as_uri().encode(),
                                          byref(self.callbacks), 0, 0)
        if not self.c:
            raise RuntimeError(f"fmi2Instantiate returned NULL: {self.last_error()}")

    def _get(self, kind, n, arr):
        f = {"r": self.lib.fmi2GetReal, "i": self.lib.fmi2GetInteger, "b": self.lib.fmi2GetBoolean}[kind]
        f(self.c, self.fmu._vr[kind], n, arr)

    def init(self, params: dict) -> int:
        L, c = self.lib, self.c
        r = L.fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0)
        if r == OK:
            r = L.fmi2EnterInitializationMode(c)
        if r == OK:
            r = self.set(params)
        if r == OK:
            r = L.fmi2ExitInitializationMode(c)
        return r

    def set(self, values: dict) -> int:
        r = OK
        for name, x in values.items():
            vr = (c_uint * 1)(self.fmu.vars[name].valueReference)
            r = max(r, self.lib.fmi2SetReal(self.c, vr, 1, (c_double * 1)(x)))
        return r

    def save(self):
        L, c = self.lib, self.c
        s = c_void_p()
        if L.fmi2GetFMUstate(c, byref(s)) != OK:
            return None
        size = c_size_t()
        buf = None
        if L.fmi2SerializedFMUstateSize(c, s, byref(size)) == OK:
            buf = ctypes.create_string_buffer(size.value)
            if L.fmi2SerializeFMUstate(c, s, buf, size.value) != OK:
                buf = None
        L.fmi2FreeFMUstate(c, byref(s))
        return bytes(buf.raw) if buf is not None else None

    def restore(self, data: bytes):
        """(status, message): the deserialization's and the set's."""
        L, c = self.lib, self.c
        s = c_void_p()
        r = L.fmi2DeSerializeFMUstate(c, data, len(data), byref(s))
        if r != OK:
            return r, "fmi2DeSerializeFMUstate: " + self.last_error()
        r = L.fmi2SetFMUstate(c, s)
        L.fmi2FreeFMUstate(c, byref(s))
        return r, ("" if r == OK else "fmi2SetFMUstate: " + self.last_error())

    def do_step(self, t, h):
        r = self.lib.fmi2DoStep(self.c, t, h, 0)
        lst = t + h
        if r == DISCARD:
            x = c_double()
            self.lib.fmi2GetRealStatus(self.c, 2, byref(x))
            lst = x.value
        return r, False, False, False, lst

    def free(self):
        if self.c:
            self.lib.fmi2FreeInstance(self.c)
            self.c = None


class Instance3(Instance):
    def __init__(self, fmu, label, flags):
        super().__init__(fmu, label, flags)
        self.log_cb = LOG_CALLBACK(lambda env, status, cat, msg: self._log(status, msg))
        self.c = self.lib.fmi3InstantiateCoSimulation(
            label.encode(), fmu.md.instantiationToken.encode(), (str(fmu.dir / "resources") + "/").encode(), 0, 0,
            int(flags[0]), int(flags[1]), None, 0, None, self.log_cb, INTERMEDIATE_CALLBACK())
        if not self.c:
            raise RuntimeError(f"fmi3InstantiateCoSimulation returned NULL: {self.last_error()}")

    def _get(self, kind, n, arr):
        f = {"r": self.lib.fmi3GetFloat64, "i": self.lib.fmi3GetInt32, "b": self.lib.fmi3GetBoolean}[kind]
        f(self.c, self.fmu._vr[kind], n, arr, n)

    def init(self, params: dict) -> int:
        L, c = self.lib, self.c
        r = L.fmi3EnterInitializationMode(c, 0, 0.0, 0.0, 0, 0.0)
        if r == OK:
            r = self.set(params)
        if r == OK:
            r = L.fmi3ExitInitializationMode(c)
        if r == OK and self.flags[0]:
            # eventModeUsed: ExitInitializationMode leaves the instance in event mode.
            r = self.event_updates()[0]
            if r == OK:
                r = L.fmi3EnterStepMode(c)
        return r

    def event_updates(self):
        """fmi3UpdateDiscreteStates until no more is needed: (status, calls)."""
        n = 0
        for n in range(1, 101):
            r, need, _ = self.update()
            if r != OK or not need:
                return r, n
        return ERROR, n

    def update(self):
        flags = [c_uint8() for _ in range(5)]
        nxt = c_double()
        r = self.lib.fmi3UpdateDiscreteStates(self.c, *[byref(f) for f in flags], byref(nxt))
        return r, bool(flags[0].value), bool(flags[1].value)

    def set(self, values: dict) -> int:
        r = OK
        for name, x in values.items():
            vr = (c_uint * 1)(self.fmu.vars[name].valueReference)
            r = max(r, self.lib.fmi3SetFloat64(self.c, vr, 1, (c_double * 1)(x), 1))
        return r

    def save(self):
        L, c = self.lib, self.c
        s = c_void_p()
        if L.fmi3GetFMUState(c, byref(s)) != OK:
            return None
        size = c_size_t()
        buf = None
        if L.fmi3SerializedFMUStateSize(c, s, byref(size)) == OK:
            buf = ctypes.create_string_buffer(size.value)
            if L.fmi3SerializeFMUState(c, s, buf, size.value) != OK:
                buf = None
        L.fmi3FreeFMUState(c, byref(s))
        return bytes(buf.raw) if buf is not None else None

    def restore(self, data: bytes):
        L, c = self.lib, self.c
        s = c_void_p()
        r = L.fmi3DeserializeFMUState(c, data, len(data), byref(s))
        if r != OK:
            return r, "fmi3DeserializeFMUState: " + self.last_error()
        r = L.fmi3SetFMUState(c, s)
        L.fmi3FreeFMUState(c, byref(s))
        return r, ("" if r == OK else "fmi3SetFMUState: " + self.last_error())

    def do_step(self, t, h):
        event, terminate, early = c_uint8(), c_uint8(), c_uint8()
        lst = c_double(math.nan)
        r = self.lib.fmi3DoStep(self.c, t, h, 0, byref(event), byref(terminate), byref(early), byref(lst))
        return r, bool(event.value), bool(terminate.value), bool(early.value), lst.value

    def free(self):
        if self.c:
            self.lib.fmi3FreeInstance(self.c)
            self.c = None


def land(t: float, target: float) -> float:
    """The step h from t with t + h == target exactly, as a master that lands
    on its communication points computes it (target - t may miss by an ulp,
    and a state 1 ulp later in time has other outputs)."""
    h = target - t
    for _ in range(4):
        end = t + h
        if end == target:
            break
        h = math.nextafter(h, math.inf if end < target else -math.inf)
    return h if t + h == target else target - t


def hexf(x: float) -> str:
    return x.hex() if isinstance(x, float) else str(x)


class Stats:
    KEYS = ("runs", "init_refused", "discarded_runs", "dosteps", "early_returns", "events", "saved", "restored_ok",
            "refused", "mismatched", "cross_restored_ok", "cross_refused_allowed", "cross_refused", "cross_mismatched",
            "cross_time_unreachable", "cross_flag_dependent", "flag_runs_differ")

    def __init__(self):
        self.n = dict.fromkeys(self.KEYS, 0)
        self.classes: dict[str, dict] = {}  # class -> {"count", "examples"}
        self.n_failures = 0
        self.allowed_messages: dict[str, int] = {}

    @staticmethod
    def mask(m: str) -> str:
        """A message with its numbers masked: the class of a refusal."""
        return re.sub(r"-?\d+(\.\d+)?(e-?\d+)?", "#", m)[:200]

    def fail(self, kind: str, info: dict, counted: str | None = None):
        """A failure: counted under `counted` (Stats.n) if given; classed by kind and message."""
        if counted:
            self.n[counted] += 1
        self.n_failures += 1
        key = kind
        if "message" in info:
            key += ": " + self.mask(info["message"])
        elif "differences" in info:
            key += ": " + ", ".join(sorted(info["differences"]))[:200]
        c = self.classes.get(key)
        if c is None:
            if len(self.classes) >= N_CLASSES:
                key = "(other classes)"
                c = self.classes.setdefault(key, {"count": 0, "examples": []})
            else:
                c = self.classes[key] = {"count": 0, "examples": []}
        c["count"] += 1
        if len(c["examples"]) < N_EXAMPLES:
            c["examples"].append({"kind": kind, **info})

    def allowed(self, m: str):
        k = self.mask(m)
        self.allowed_messages[k] = self.allowed_messages.get(k, 0) + 1


class Run:
    """One run of one FMU: a master stepping an original instance, saving
    before every step, every state restored into a twin (same flags) and,
    for FMI 3.0, into instances with the other flags."""

    def __init__(self, fmu: Fmu, stats: Stats, params: dict, inputs: list[dict], h: float, n: int, flags,
                 cross: str, setting: str, rng: random.Random, save_from: float | None = None, p_save: float = 0.0):
        self.fmu, self.stats, self.params, self.inputs, self.h, self.n = fmu, stats, params, inputs, h, n
        self.save_from, self.p_save = save_from, p_save
        self.plain = save_from == math.inf  # a reference run: no saves, no restores
        self.cross_results: list = []
        self.flags, self.cross, self.setting, self.rng = tuple(flags), cross, setting, rng
        self.ops: list = []  # ("set", values) | ("step", t, h) | ("enter_event",) | ("update",) | ("enter_step",)
        self.pending: list = []  # saves waiting for the end of the next DoStep: (index into ops, info, data)
        self.cross_pending: list = []  # (grid index, info, data, target flags, where saved)
        self.grid_out: dict[int, tuple] = {}
        self.grid_time: dict[int, float] = {}

    def info(self, k, t, where, extra=None):
        d = {"fmu": self.fmu.name, "fmi": self.fmu.fmi, "setting": self.setting, "params": self.params,
             "inputs_at_step": self.inputs[k] if k < len(self.inputs) else {}, "h": self.h, "step": k,
             "time": t, "time_hex": hexf(t), "saved": where}
        if self.fmu.fmi == 3:
            d["flags"] = {"eventModeUsed": self.flags[0], "earlyReturnAllowed": self.flags[1]}
        if extra:
            d.update(extra)
        return d

    # ------------------------------------------------------------ the original
    def execute(self, inst, op):
        """Runs one op on an instance: a comparable record of its result."""
        kind = op[0]
        if kind == "set":
            return (kind, inst.set(op[1]))
        if kind == "step":
            r, event, terminate, early, lst = inst.do_step(op[1], op[2])
            return (kind, r, event, terminate, early, hexf(lst), inst.outputs())
        if kind == "enter_event":
            return (kind, inst.lib.fmi3EnterEventMode(inst.c))
        if kind == "update":
            r, need, terminate = inst.update()
            return (kind, r, need, terminate, inst.outputs())
        if kind == "enter_step":
            return (kind, inst.lib.fmi3EnterStepMode(inst.c))
        raise ValueError(kind)

    def op(self, op):
        rec = self.execute(self.a, op)
        self.ops.append((op, rec))
        return rec

    def save(self, k, t, where, grid):
        if not self.saving:
            return
        data = self.a.save()
        self.stats.n["saved"] += 1
        info = self.info(k, t, where)
        if data is None:
            self.stats.fail("save failed", {**info, "message": self.a.last_error()}, "refused")
            return
        self.pending.append((len(self.ops), info, data))
        if self.fmu.fmi == 3 and self.cross != "none":
            others = [f for f in FLAGS if f != self.flags]
            targets = others if self.cross == "all" else [others[self.stats.n["saved"] % 3]]
            for f in targets:
                self.cross_pending.append((grid, info, data, f, where))

    def run(self):
        fmu, st = self.fmu, self.stats
        st.n["runs"] += 1
        self.a = fmu.instance(f"{fmu.name}-original", self.flags)
        self.b = fmu.instance(f"{fmu.name}-twin", self.flags)
        self.c = {f: fmu.instance(f"{fmu.name}-cross{int(f[0])}{int(f[1])}", f)
                  for f in FLAGS if f != self.flags} if fmu.fmi == 3 and self.cross != "none" and not self.plain else {}
        try:
            r = self.a.init(self.params)
            if r not in (OK, WARNING):
                st.n["init_refused"] += 1
                return
            for inst in self.c.values():
                inst.init({})  # at the defaults: a restore must bring the parameters
            self.stepping()
        finally:
            for inst in (self.a, self.b, *self.c.values()):
                inst.free()

    def stepping(self):
        t = 0.0
        fmi3 = self.fmu.fmi == 3
        ev, early_ok = self.flags
        last_set = 0  # --quick saves before step 0, the 10 steps from each input set and the window
        for k in range(self.n):
            target = t + self.h
            sets = k < len(self.inputs) and self.inputs[k]
            if sets:
                last_set = k
            self.saving = not self.plain and (self.save_from is None or k < last_set + 10 or t >= self.save_from
                                              or self.rng.random() < self.p_save)
            if sets:
                self.op(("set", self.inputs[k]))
            first = True
            stalled = 0
            for _ in range(100000):
                self.save(k, t, "before DoStep" if first else "before DoStep after an early return", k + 1)
                rec = self.op(("step", t, land(t, target)))
                self.stats.n["dosteps"] += 1
                self.check_pending()
                r, event, terminate, early, lst = rec[1], rec[2], rec[3], rec[4], float.fromhex(rec[5]) if rec[5] != "nan" else math.nan
                if r not in (OK, WARNING):
                    self.stats.n["discarded_runs"] += 1
                    if r != DISCARD and not self.plain:
                        self.stats.fail(f"DoStep returned {r}", {**self.info(k, t, "-"), "message": self.a.last_error()})
                    return
                if early:
                    self.stats.n["early_returns"] += 1
                t_now = lst if early else target
                if fmi3 and event and ev:
                    self.stats.n["events"] += 1
                    self.save(k, t_now, "after DoStep, event pending (step mode)", k + 1 if early else k + 2)
                    self.op(("enter_event",))
                    for _ in range(100):
                        self.save(k, t_now, "event mode, before fmi3UpdateDiscreteStates", k + 1 if early else k + 2)
                        u = self.op(("update",))
                        if u[1] != OK or not u[2]:
                            break
                    self.save(k, t_now, "event mode, after the updates", k + 1 if early else k + 2)
                    self.op(("enter_step",))
                if terminate:
                    return
                if not early:
                    t = target
                    self.grid_out[k + 1] = self.a.outputs()
                    self.grid_time[k + 1] = target
                    self.check_cross(k + 1)
                    break
                stalled = stalled + 1 if not lst > t else 0
                if stalled >= 10 or lst < t:
                    # (one return at the step's own start is an event there; ten are a stall)
                    self.stats.fail("early returns without progress", {**self.info(k, t, "-"), "lastSuccessfulTime": hexf(lst)})
                    return
                t = lst
                first = False
            else:
                self.stats.fail("100000 early returns in one communication step", self.info(k, t, "-"))
                return
        self.check_pending()

    # ------------------------------------------------------------ the twin
    def check_pending(self):
        """Every pending save: restored into the twin, the ops since replayed."""
        if not self.pending:
            return
        end = len(self.ops)
        for start, info, data in self.pending:
            r, msg = self.b.restore(data)
            if r != OK:
                self.stats.fail("refused", {**info, "status": r, "message": msg}, "refused")
                continue
            self.stats.n["restored_ok"] += 1
            for j in range(start, end):
                op, want = self.ops[j]
                got = self.execute(self.b, op)
                if got != want:
                    self.stats.fail("mismatch", {**info, "call": repr(op), "after": j - start + 1,
                                                 "differences": self.differences(op, want, got)}, "mismatched")
                    break
        self.pending.clear()
        self.ops.clear()

    def differences(self, op, want, got):
        if op[0] in ("step", "update") and want[:-1] == got[:-1]:
            a, b = self.a.decode(want[-1]), self.a.decode(got[-1])
            return {k: [hexf(a[k]), hexf(b[k])] for k in a if hexf(a[k]) != hexf(b[k])}
        return {"original": repr(want[:-1] if op[0] in ("step", "update") else want),
                "restored": repr(got[:-1] if op[0] in ("step", "update") else got)}

    # ------------------------------------------------------------ other flags
    def check_cross(self, g):
        """States restored into instances with other flags, continued to grid point g
        (judged by judge_cross once the runs with those flags are made)."""
        todo = [p for p in self.cross_pending if p[0] == g]
        if not todo:
            return
        self.cross_pending = [p for p in self.cross_pending if p[0] != g]
        t_end = self.grid_time[g]
        for _, info, data, flags, where in todo:
            inst = self.c[flags]
            xinfo = {**info, "into": {"eventModeUsed": flags[0], "earlyReturnAllowed": flags[1]}}
            r, msg = inst.restore(data)
            in_event = where.startswith("event mode")
            if r != OK:
                if r == ERROR and msg.split(": ")[-1].strip() and in_event and not flags[0]:
                    self.stats.n["cross_refused_allowed"] += 1
                    self.stats.allowed(msg)
                else:
                    self.stats.fail("refused by an instance with other flags", {**xinfo, "status": r, "message": msg},
                                    "cross_refused")
                continue
            self.stats.n["cross_restored_ok"] += 1
            got, err = self.continue_to(inst, float(info["time"]), t_end, where)
            if err:
                self.stats.fail("other flags: the continuation failed", {**xinfo, "message": err}, "cross_mismatched")
                continue
            self.cross_results.append((g, flags, got, xinfo))

    def continue_to(self, inst, t, t_end, where):
        """A master with the instance's flags, from the restored state to t_end
        (without eventModeUsed it never calls an event-mode function)."""
        ev, _ = inst.flags
        L = inst.lib
        if ev and where.startswith("after DoStep"):
            if L.fmi3EnterEventMode(inst.c) != OK:
                return None, "fmi3EnterEventMode: " + inst.last_error()
            where = "event mode"
        if ev and where.startswith("event mode"):
            r, _ = inst.event_updates()
            if r != OK:
                return None, "fmi3UpdateDiscreteStates: " + inst.last_error()
            if L.fmi3EnterStepMode(inst.c) != OK:
                return None, "fmi3EnterStepMode: " + inst.last_error()
        for _ in range(100000):
            if t >= t_end:
                break
            r, event, terminate, early, lst = inst.do_step(t, land(t, t_end))
            if r not in (OK, WARNING):
                return None, f"fmi3DoStep(t = {t!r}, h = {land(t, t_end)!r}) returned {r}: {inst.last_error()}"
            if event and ev:
                if L.fmi3EnterEventMode(inst.c) != OK or inst.event_updates()[0] != OK or L.fmi3EnterStepMode(inst.c) != OK:
                    return None, "event mode: " + inst.last_error()
            if terminate or not early:
                break
            t = lst
        return inst.outputs(), None


def output_differences(inst: Instance, want, got, skip_impulse: bool) -> dict:
    a, b = inst.decode(want), inst.decode(got)
    return {k: [hexf(a[k]), hexf(b[k])] for k in a
            if hexf(a[k]) != hexf(b[k]) and not (skip_impulse and k.endswith("impulse"))}


def judge(stats: Stats, runs: dict, examples: dict):
    """The cross-flag continuations of runs made with the same setting, one
    run per flags (the runs' own grid outputs are the references): equal to
    the original's outputs at the end of the communication step, or (counted
    apart, not a failure) different where the runs with the two flags already
    differ there without any restore. `impulse` (over the last DoStep) is
    left out between runs that differ in earlyReturnAllowed."""
    for run in runs.values():
        for g, flags, got, xinfo in run.cross_results:
            want = run.grid_out.get(g)
            skip = flags[1] != run.flags[1]
            diff = output_differences(run.a, want, got, skip)
            if not diff:
                continue
            if "time" in diff:
                # From a time inside the communication step, no step lands exactly on its end
                # (t + h skips that number): outputs 1 ulp of time apart are not compared.
                stats.n["cross_time_unreachable"] += 1
                continue
            ref = runs[flags].grid_out.get(g) if flags in runs else None
            if ref is not None and output_differences(run.a, want, ref, skip):
                stats.n["cross_flag_dependent"] += 1
                continue
            stats.fail("other flags: mismatch at the end of the communication step",
                       {**xinfo, "grid_time": hexf(run.grid_time[g]), "differences": diff}, "cross_mismatched")
    # without any restore: do the runs with different flags agree at every communication point?
    flags = sorted(runs)
    for i, f1 in enumerate(flags):
        for f2 in flags[i + 1:]:
            r1, r2 = runs[f1], runs[f2]
            for g in sorted(set(r1.grid_out) & set(r2.grid_out)):
                diff = output_differences(r1.a, r1.grid_out[g], r2.grid_out[g], f1[1] != f2[1])
                if "time" in diff:
                    break  # the runs' clocks parted by an ulp (an early return's time + h): no longer compared
                if diff:
                    stats.n["flag_runs_differ"] += 1
                    key = f"{r1.setting}, h = {r1.h!r}"
                    if len(examples) < 10 and key not in examples:
                        examples[key] = {"fmu": r1.fmu.name, "params": r1.params, "flags": [f1, f2], "step": g,
                                         "time": r1.grid_time[g], "differences": diff}
                    break


# ---------------------------------------------------------------- settings

def log_spaced(lo: float, hi: float, n: int) -> list[float]:
    """n values from lo to hi, ends included, evenly spaced in log."""
    a, b = math.log(lo), math.log(hi)
    vals = [math.exp(a + (b - a) * j / (n - 1)) for j in range(n)]
    vals[0], vals[-1] = lo, hi
    return vals


def input_values(v, rng: random.Random, quick: bool) -> list[float]:
    lo, hi = float(v.min), float(v.max)
    base = [lo, -1.0, 0.0, 1.0, hi]
    out = []
    for x in base:
        x = min(max(x, lo), hi)
        if x not in out:
            out.append(x)
    if not quick:
        for _ in range(3):
            out.append(admitted_value(v, rng, kinds=("uniform", "log")))
    return out


def input_schedule(v, x, n, quick=False) -> list[dict]:
    """x set before the saves of steps [0, n/3) and [2n/3, n), the start value
    between; --quick: only where the value changes (0, n/3, 2n/3)."""
    start = float(v.start) if v.start is not None else 0.0
    out = [{v.name: (x if (k < n // 3 or k >= (2 * n) // 3) else start)} for k in range(n)]
    if quick:
        out = [d if k in (0, n // 3, (2 * n) // 3) else {} for k, d in enumerate(out)]
    return out


def plan(fmu: Fmu, h: float, quick: bool):
    """(steps of a run, the time saves start before every step: None for all)."""
    full, short, save_from = HORIZON.get(fmu.name, (100 * fmu.h, 30 * fmu.h, 0.0))
    return max(3, int(round((short if quick else full) / h))), (save_from if quick else None)


def sweep(fmu: Fmu, quick: bool, rng: random.Random, stats: Stats, cross: str, examples: dict, only: dict | None = None):
    flag_sets = FLAGS if fmu.fmi == 3 else [(False, False)]
    hs = [fmu.h] if quick else [fmu.h, 10 * fmu.h]
    if only is not None:  # --param: that setting alone
        label = ", ".join(f"{k} = {x!r}" for k, x in only.items())
        settings = [(label, {k: x for k, x in only.items() if k in fmu.vars and fmu.vars[k].causality != "input"},
                     None)]
        inputs = {k: x for k, x in only.items() if k in fmu.vars and fmu.vars[k].causality == "input"}
        if inputs:
            settings = [(label, settings[0][1], (fmu.vars[k], x)) for k, x in inputs.items()]
    else:
        settings = [("defaults", {}, None)]
    for v in fmu.tolerances if only is None else []:
        vals = log_spaced(float(v.min), float(v.max), 3 if quick else 12)
        settings += [(f"{v.name} = {x!r}", {v.name: x}, None) for x in vals]
    for v in fmu.inputs if only is None else []:
        settings += [(f"input {v.name} = {x!r}", {}, (v, x)) for x in input_values(v, rng, quick)]
    for h in hs:
        n, save_from = plan(fmu, h, quick)
        for label, params, inp in settings:
            inputs = input_schedule(inp[0], inp[1], n, quick) if inp else []
            runs = {}
            for flags in flag_sets:
                runs[flags] = Run(fmu, stats, params, inputs, h, n, flags, cross, label, rng, save_from)
                runs[flags].run()
            judge(stats, runs, examples)


def fuzz(fmu: Fmu, sequences: int, rng: random.Random, stats: Stats, cross: str, examples: dict):
    for s in range(sequences):
        params = {}
        pool = fmu.parameters
        n_params = rng.choice([1, 1, 2, 3, 5, len(pool)])
        for v in rng.sample(pool, min(n_params, len(pool))):
            params[v.name] = admitted_value(v, rng)
        h = rng.choice([fmu.h, 10 * fmu.h])
        n, save_from = plan(fmu, h, True)
        inputs = []
        for k in range(n):
            inputs.append({v.name: admitted_value(v, rng) for v in fmu.inputs if rng.random() < 0.2})
        flags = rng.choice(FLAGS) if fmu.fmi == 3 else (False, False)
        label = f"fuzz sequence {s}"
        run = Run(fmu, stats, params, inputs, h, n, flags, cross, label, rng, save_from, 0.1)
        run.run()
        runs = {flags: run}
        if fmu.fmi == 3 and cross != "none":
            # references for the cross-flag restores: the same sequence with the other flags, no saves
            for f in FLAGS:
                if f != flags:
                    runs[f] = Run(fmu, Stats(), params, inputs, h, n, f, "none", label, rng, math.inf)
                    runs[f].run()
        judge(stats, runs, examples)


def find_fmus(spec: list[str] | None, fmis: list[int], dirs: dict) -> list[Path]:
    out = []
    for fmi in fmis:
        if not spec:
            out += sorted(Path(dirs[fmi]).glob("*.fmu"))
    for s in spec or []:
        p = Path(s)
        if p.suffix == ".fmu" and p.exists():
            out.append(p)
        else:
            out += [Path(dirs[fmi]) / f"{s}.fmu" for fmi in fmis]
    return [p for p in out if p.stem != "PDController"]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fmu", action="append", help="an FMU name or .fmu path (repeatable; default: every FMU)")
    ap.add_argument("--fmi", type=int, choices=(2, 3), help="one standard only (default: both)")
    ap.add_argument("--quick", action="store_true", help="the bounded subset (CI)")
    ap.add_argument("--fuzz", type=int, default=0, metavar="N", help="N random-parameter sequences instead of the sweep")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--cross", choices=("all", "one", "none"), help="restores into instances with other flags "
                    "(FMI 3.0): into all three, one in turn, none (default: one with --quick or --fuzz, else all)")
    ap.add_argument("--dir2", default=str(DIRS[2]), help="where FMI 2.0 FMUs are looked up by name")
    ap.add_argument("--dir3", default=str(DIRS[3]), help="where FMI 3.0 FMUs are looked up by name")
    ap.add_argument("--out", help="write the JSON summary here (default: stdout)")
    ap.add_argument("--progress", action="store_true", help="a line per FMU and standard on stderr")
    ap.add_argument("--param", action="append", metavar="NAME=VALUE", help="sweep this setting alone (repeatable; "
                    "an input is set as the sweep sets inputs): every flag and step of the sweep, to reproduce a failure")
    a = ap.parse_args(argv)
    fmis = [a.fmi] if a.fmi else [2, 3]
    cross = a.cross or ("one" if a.quick or a.fuzz else "all")
    summary = {"mode": "fuzz" if a.fuzz else "quick" if a.quick else "sweep", "seed": a.seed, "cross": cross,
               "sequences": a.fuzz or None, "results": []}
    totals = dict.fromkeys(Stats.KEYS, 0)
    t00 = time.process_time()
    for path in find_fmus(a.fmu, fmis, {2: a.dir2, 3: a.dir3}):
        fmu = Fmu(path)
        if fmu.fmi not in fmis:
            shutil.rmtree(fmu.dir, ignore_errors=True)
            continue
        rng = random.Random(f"{a.seed}-{fmu.name}-{fmu.fmi}")
        stats = Stats()
        examples: dict = {}
        t0 = time.process_time()
        if a.fuzz:
            fuzz(fmu, a.fuzz, rng, stats, cross, examples)
        else:
            only = {k: float(x) for k, x in (p.split("=", 1) for p in a.param)} if a.param else None
            sweep(fmu, a.quick, rng, stats, cross, examples, only)
        for k in Stats.KEYS:
            totals[k] += stats.n[k]
        shutil.rmtree(fmu.dir, ignore_errors=True)
        summary["results"].append({"fmu": fmu.name, "fmi": fmu.fmi, "cpu_s": round(time.process_time() - t0, 2),
                                   **stats.n, "n_failures": stats.n_failures,
                                   "allowed_refusals": stats.allowed_messages, "failures": stats.classes,
                                   "flag_dependence": examples})
        if a.progress:
            r = summary["results"][-1]
            print(f"{fmu.name} FMI {fmu.fmi}: {r['cpu_s']} s, {r['saved']} saved, {r['refused']} refused, "
                  f"{r['mismatched']} mismatched, cross {r['cross_refused']} refused {r['cross_mismatched']} mismatched",
                  file=sys.stderr, flush=True)
    summary["totals"] = totals
    summary["cpu_s"] = round(time.process_time() - t00, 2)
    text = json.dumps(summary, indent=1)
    if a.out:
        Path(a.out).write_text(text)
    else:
        print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
