"""Shared helpers for the fmpy test suite of the PinnedBeamStop FMU.

Paths are computed from this file, so the suite runs from any working
directory. Value references are always looked up by name in the FMU's
modelDescription.xml, never hard-coded.
"""

from __future__ import annotations

import math
import os
import shutil
import zipfile
from ctypes import byref
from pathlib import Path

import pytest

import fmpy
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2CoSimulation,
    fmi2Error,
    fmi2OK,
)

# ---------------------------------------------------------------- paths

ROOT = Path(__file__).resolve().parents[2]
# The heavier checks at full length (every FMU under valgrind, the fuzzers'
# longer runs): scripts/test --full sets it; the test command runs them
# shortened (docs/verification.md).
FULL = os.environ.get("BEAMSTOP_FULL_TESTS") == "1"
FMU_DIR = ROOT / "target" / "fmu"
FMU_PATH = FMU_DIR / "PinnedBeamStop.fmu"
SO_PATH = ROOT / "target" / "release" / "libbeamstop_fmu.so"
HEADER_PATH = ROOT / "include" / "beamstop_fmi2.h"
SCENE_PATH = ROOT / "scenes" / "pinned_beam.json"
C_TESTS = ROOT / "tests" / "c"
FMPY_DIR = Path(fmpy.__file__).resolve().parent
FMPY_C_CODE = FMPY_DIR / "c-code"
FMPY_SCHEMA_FMI2 = FMPY_DIR / "schema" / "fmi2"

# The variables the FMU must expose, exactly (task specification).
EXPECTED_VARIABLES = {
    "F", "omega", "zeta", "R", "eps", "d", "x_stop", "x_force",
    *(f"q0[{j}]" for j in range(1, 5)),
    *(f"qd0[{j}]" for j in range(1, 5)),
    "force",
    "w_stop", "v_stop", "impacts", "t_last_impact", "sticking", "sticks", "stuck_time", "lambda",
    *(f"q[{j}]" for j in range(1, 5)),
    *(f"qd[{j}]" for j in range(1, 5)),
    "energy",
}

# Closed forms of the pinned-pinned beam (VSM12's scaled units).
N_MODES = 4


def omega_mode(j: int) -> float:
    """Natural circular frequency of mode j (1-based): (j pi)^2."""
    return (j * math.pi) ** 2


def mode_shape(j: int, x: float) -> float:
    """Mass-normalised mode shape W_j(x) = sqrt(2) sin(j pi x)."""
    return math.sqrt(2.0) * math.sin(j * math.pi * x)


def modal_energy(q, qd) -> float:
    """sum_j (qd_j^2 + omega_j^2 q_j^2) / 2, computed independently of the FMU."""
    return sum(0.5 * (qd[j] ** 2 + omega_mode(j + 1) ** 2 * q[j] ** 2) for j in range(len(q)))


def w_at(x: float, q) -> float:
    """Displacement at x from the modal coordinates."""
    return sum(mode_shape(j + 1, x) * q[j] for j in range(len(q)))


# Free vibration from rest below the stop: first impact after a quarter
# period of mode 1, energy conserved (R = 1, no damping, no load).
FREE_VIBRATION = {
    "F": 0.0,
    "R": 1.0,
    "zeta": 0.0,
    "d": 0.0,
    "q0[1]": -3.0 / math.sqrt(2.0),
}
FREE_FIRST_IMPACT = 1.0 / (2.0 * math.pi)
FREE_ENERGY = 0.5 * omega_mode(1) ** 2 * FREE_VIBRATION["q0[1]"] ** 2  # = 9 pi^4 / 4

ALL_OUTPUTS = [
    "w_stop", "v_stop", "impacts", "t_last_impact", "sticking", "lambda",
    *(f"q[{j}]" for j in range(1, 5)),
    *(f"qd[{j}]" for j in range(1, 5)),
    "energy",
]


# ---------------------------------------------------------------- model description

_MD = None


def model_description():
    global _MD
    if _MD is None:
        _MD = read_model_description(str(FMU_PATH))
    return _MD


def variables():
    return {v.name: v for v in model_description().modelVariables}


def vr(name: str) -> int:
    """Value reference of a variable, looked up by name."""
    return variables()[name].valueReference


def unused_value_reference() -> int:
    used = {v.valueReference for v in model_description().modelVariables}
    r = 9999
    while r in used:
        r += 1
    return r


# ---------------------------------------------------------------- logging

class LogCapture:
    """An fmi2CallbackFunctions whose logger records every message.

    The logger of FMI 2.0 takes a printf format; ctypes cannot receive the
    variadic arguments, but this FMU never passes any and escapes '%' as
    '%%', so the message is the format with '%%' turned back into '%'.
    """

    def __init__(self):
        self.records: list[tuple[str, int, str, str]] = []
        self._logger = fmi2CallbackLoggerTYPE(self._log)
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = self._logger
        # allocateMemory / freeMemory / stepFinished stay NULL:
        # canNotUseMemoryManagementFunctions = true.

    def _log(self, env, instance_name, status, category, message):
        def dec(b):
            return b.decode("utf-8", "replace") if b is not None else ""

        self.records.append((dec(instance_name), int(status), dec(category), dec(message).replace("%%", "%")))

    def messages(self, category: str | None = None, status: int | None = None) -> list[str]:
        return [m for (_, s, c, m) in self.records
                if (category is None or c == category) and (status is None or s == status)]

    def errors(self) -> list[str]:
        return self.messages(status=fmi2Error)

    def clear(self):
        self.records.clear()

    def text(self) -> str:
        return "\n".join(f"[{s}] {c}: {m}" for (_, s, c, m) in self.records)


# ---------------------------------------------------------------- instances

class Instance:
    """An FMU2Slave plus a log capture, with name-based get/set."""

    def __init__(self, unzipdir: str | Path, name: str = "beam", logging_on: bool = False,
                 resource_location: str | None = None, guid: str | None = None,
                 library_path: str | None = None):
        md = model_description()
        self.log = LogCapture()
        self.unzipdir = str(unzipdir)
        self.slave = FMU2Slave(
            guid=md.guid if guid is None else guid,
            unzipDirectory=self.unzipdir,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=name,
            libraryPath=library_path,
        )
        self._freed = False
        if resource_location is None:
            resource_location = Path(self.unzipdir, "resources").as_uri()
        self.resource_location = resource_location
        s = self.slave
        s.callbacks = self.log.callbacks
        s.component = s.fmi2Instantiate(
            name.encode("utf-8"),
            fmi2CoSimulation,
            s.guid.encode("utf-8"),
            resource_location.encode("utf-8"),
            byref(s.callbacks),
            0,
            1 if logging_on else 0,
        )
        if not s.component:
            s.freeLibrary()
            self._freed = True
            raise RuntimeError("fmi2Instantiate returned NULL:\n" + self.log.text())

    # -- life cycle
    def initialize(self, start_values: dict | None = None, start_time: float = 0.0,
                   stop_time: float | None = None):
        s = self.slave
        s.setupExperiment(startTime=start_time, stopTime=stop_time)
        s.enterInitializationMode()
        if start_values:
            self.set(start_values)
        s.exitInitializationMode()
        self.time = start_time
        return self

    def free(self):
        if not self._freed:
            self._freed = True
            self.slave.freeInstance()

    # -- variables by name
    def set(self, values: dict):
        for name, value in values.items():
            v = variables()[name]
            if v.type == "Real":
                self.slave.setReal([v.valueReference], [float(value)])
            elif v.type == "Integer":
                self.slave.setInteger([v.valueReference], [int(value)])
            elif v.type == "Boolean":
                self.slave.setBoolean([v.valueReference], [bool(value)])
            else:
                raise TypeError(v.type)

    def get(self, name: str):
        v = variables()[name]
        if v.type == "Real":
            return self.slave.getReal([v.valueReference])[0]
        if v.type == "Integer":
            return self.slave.getInteger([v.valueReference])[0]
        if v.type == "Boolean":
            return bool(self.slave.getBoolean([v.valueReference])[0])
        raise TypeError(v.type)

    def outputs(self, names=ALL_OUTPUTS) -> dict:
        return {n: self.get(n) for n in names}

    def q(self):
        return [self.get(f"q[{j}]") for j in range(1, N_MODES + 1)]

    def qd(self):
        return [self.get(f"qd[{j}]") for j in range(1, N_MODES + 1)]

    # -- stepping
    def advance_to(self, t: float):
        """One doStep from the current time to t."""
        self.slave.doStep(currentCommunicationPoint=self.time, communicationStepSize=t - self.time)
        self.time = t

    def step(self, h: float):
        self.slave.doStep(currentCommunicationPoint=self.time, communicationStepSize=h)
        self.time = self.time + h

    def step_to(self, t_end: float, h: float, record=None):
        """Steps of size h, the last one shortened to land exactly on t_end.

        With `record` (a list), appends (time, outputs) after every step.
        """
        n = 0
        t0 = self.time
        while True:
            nxt = t0 + (n + 1) * h
            if nxt > t_end or math.isclose(nxt, t_end, rel_tol=0, abs_tol=1e-12):
                nxt = t_end
            self.advance_to(nxt)
            n += 1
            if record is not None:
                record.append((self.time, self.outputs()))
            if nxt == t_end:
                return


@pytest.fixture(scope="session")
def unzipdir(tmp_path_factory):
    """The FMU extracted once for the whole session."""
    assert FMU_PATH.is_file(), f"{FMU_PATH} missing: run `cargo run --release -- package` first"
    d = tmp_path_factory.mktemp("fmu")
    with zipfile.ZipFile(FMU_PATH) as z:
        z.extractall(d)
    return d


@pytest.fixture
def make_instance(unzipdir):
    """Factory: make_instance(name=..., logging_on=..., ...) -> Instance; freed after the test."""
    made: list[Instance] = []

    def factory(**kwargs):
        kwargs.setdefault("name", f"beam{len(made)}")
        inst = Instance(kwargs.pop("unzipdir", unzipdir), **kwargs)
        made.append(inst)
        return inst

    yield factory
    for inst in made:
        inst.free()


def python_env() -> dict:
    """Environment for subprocesses that import fmpy and this conftest."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).resolve().parent), env.get("PYTHONPATH", "")])
    return env


def native_beamstop() -> list[str]:
    """Command that runs the native `beamstop` executable."""
    exe = ROOT / "target" / "release" / "beamstop"
    if exe.is_file():
        return [str(exe)]
    if shutil.which("cargo"):
        return ["cargo", "run", "--release", "--quiet", "--manifest-path", str(ROOT / "Cargo.toml"), "--"]
    pytest.skip("neither target/release/beamstop nor cargo is available")


__all__ = [
    "ROOT", "FMU_DIR", "FMU_PATH", "SO_PATH", "HEADER_PATH", "SCENE_PATH", "C_TESTS",
    "FMPY_DIR", "FMPY_C_CODE", "FMPY_SCHEMA_FMI2", "EXPECTED_VARIABLES", "N_MODES",
    "omega_mode", "mode_shape", "modal_energy", "w_at", "FREE_VIBRATION", "FREE_FIRST_IMPACT",
    "FREE_ENERGY", "ALL_OUTPUTS", "model_description", "variables", "vr", "unused_value_reference",
    "LogCapture", "Instance", "python_env", "native_beamstop", "FMICallException", "fmi2Error",
    "fmi2OK",
]
