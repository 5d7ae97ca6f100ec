"""Every FMU stepped by three importers, fmpy, OSP libcosim (libcosimpy) and
ecos (ecospy), gives the same outputs at every communication point; every
FMI 3.0 FMU (target/fmu3) stepped by fmpy and ecos likewise.

Each FMU runs its whole DefaultExperiment (t = 0 to stopTime with the fixed
communication step stepSize: 2000 to 20000 steps; about 70 s for the file on
one core, 20 s of it FMI 3.0), every importer once per FMU, each in its own
process
(tests/python/importers.py): ecos's library needs the tbb wheel's lib
directory on LD_LIBRARY_PATH before it is loaded, which only a new process
can have, so run() sets it for every importer's process.

- ecos keeps time as fmpy does (t += h): its time points and every output
  are equal to fmpy's bit for bit, through FMI 2.0 and through FMI 3.0 (the
  FMI 3.0 FMU stepped by fmpy as ecos steps it: no event mode, no early
  return).
- libcosim keeps time in integer nanoseconds and hands the FMU
  t_k = (k h_ns) / 1e9 and h_k = t_(k+1) - t_k (importers.py), which for
  h = 0.01 differs from t += h by an ulp or so at almost every point. Stepped
  by fmpy on that same grid, the FMU gives libcosim's outputs bit for bit;
  that is the comparison. The FMU's outputs are a function of the
  communication points, not of who calls doStep.
- The two grids against each other (a property of the FMU, not of an
  importer): counts, flags and impact times equal, continuous outputs equal to
  1e-8 of each output's largest magnitude over the run. An ulp-shifted
  communication point moves the state by |dy/dt| 1e-16 t, and the motion
  between impacts carries and amplifies that: measured at most 1.8e-9
  (qd[4] of WaggBishopCantilever4 near t = 196 s; 7.2e-10 for tip.v of
  SteelCantileverStop within 2 s); an output read at the shifted time also
  differs by its rate times the shift (a sticking reaction: 1.6e-8 N from
  2.6e5 N/s times 6.4e-14 s), which the tolerance adds. A relative tolerance like 1e-12 cannot
  work here: outputs that pass through zero (a stop's displacement) differ
  by more than 100 % relative near 1e-19.

An importer (or the FMU through it) that logs anything, e.g. a conformance
complaint about the modelDescription or an fmi2Warning, fails the test: the
importers log at warning level and nothing may reach stdout or stderr, but
for the two lines ecos 0.7.2 prints for every FMI 3.0 FMU whatever the FMU
(ECOS_FMI3_LINES).

BEAMSTOP_FMU_DIR and BEAMSTOP_FMU3_DIR override the FMU directories (default
target/fmu and target/fmu3).
"""

from __future__ import annotations

import functools
import json
import math
import zipfile
import os
import subprocess
import sys
import tempfile
from importlib import metadata
from pathlib import Path

import pytest
from fmpy import read_model_description

from conftest import FMU_DIR, ROOT, python_env
from importers import KIND

HERE = Path(__file__).resolve().parent
FMUS = sorted(Path(os.environ.get("BEAMSTOP_FMU_DIR", FMU_DIR)).glob("*.fmu"))
IDS = [f.stem for f in FMUS]
FMU3_DIR = Path(os.environ.get("BEAMSTOP_FMU3_DIR", ROOT / "target" / "fmu3"))
FMUS3 = sorted(FMU3_DIR.glob("*.fmu"))
IDS3 = [f.stem for f in FMUS3]
MAX_STEPS = 50_000  # caps the run time; above every DefaultExperiment now (20000 at most)

# What ecos 0.7.2 prints on stdout for every FMI 3.0 FMU, whatever the FMU;
# run() drops exactly these lines, once each, from ecos's output for an
# FMI 3.0 FMU. Both come from the FMI loader ecos links, fmi4c (ecos's
# CMakeLists.txt: Ecos-platform/fmi4c at 55c5aa5297212ae3895582dc9c370a050344cb57):
# - ecos reads the model description (src/fmilibcpp/fmi3/fmi3_model_description.cpp:143,
#   `md.fmiVersion = fmi3_getVersion(handle) ? ... : "3.0"`, called from the
#   fmi3_fmu constructor, fmi3_fmu.cpp:14) before it instantiates the FMU.
#   fmi4c's fmi3_getVersion (src/fmi4c.c:2515) calls the function pointer
#   fmu->fmi3.getVersion, which until then is the placeholder set when the
#   FMU is loaded (src/fmi4c.c:4768); the shared object is opened and its
#   symbols looked up only in fmi3_instantiateCoSimulation
#   (loadFunctionsFmi3, src/fmi4c.c:2463 and 2347). The placeholder prints
#   this line (src/fmi4c_placeholders.h:20 and 817) and returns NULL, and ecos
#   takes "3.0". Our binary exports fmi3GetVersion, which returns "3.0";
#   FMI 2.0 is not affected (fmi4c's fmi2_getVersion reads the
#   modelDescription).
# - loadFunctionsFmi3 prints the second line unconditionally when it opens the
#   shared object (src/fmi4c.c:2325; the printf is gone from robbr48/fmi4c's
#   master).
ECOS_FMI3_LINES = ('Function "fmi3GetVersion" is not provided by this FMU.', "Loading FMI version 3...")


def tbb_lib_dir() -> str:
    """The directory of libtbb.so.12 as the installed tbb wheel placed it
    (<venv>/lib), found from the wheel's own file list."""
    files = metadata.distribution("tbb").files or []
    libs = [f for f in files if f.name == "libtbb.so.12"]
    assert libs, "the tbb wheel has no libtbb.so.12"
    return str(Path(libs[0].locate()).resolve().parent)


@functools.lru_cache(maxsize=None)
def run(importer: str, fmu: Path) -> tuple[list[float], list[dict]]:
    """(time after each step, outputs after each step) of `fmu` stepped by
    `importer`; every importer runs once per FMU in this session."""
    step, n = horizon(fmu)
    env = python_env()
    env["LD_LIBRARY_PATH"] = os.pathsep.join(p for p in [tbb_lib_dir(), env.get("LD_LIBRARY_PATH")] if p)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out.json"
        proc = subprocess.run(
            [sys.executable, str(HERE / "importers.py"), importer, str(fmu), repr(step), str(n), str(out)],
            env=env, cwd=tmp, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, f"{importer} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
        stdout = proc.stdout
        if importer == "ecos" and fmi_version(fmu) == "3.0":
            lines = stdout.splitlines(keepends=True)
            for known in ECOS_FMI3_LINES:
                if known + "\n" in lines:
                    lines.remove(known + "\n")
            stdout = "".join(lines)
        assert stdout == "" and proc.stderr == "", \
            f"{importer} logged on {fmu.name}:\n{stdout[-3000:]}\n{proc.stderr[-3000:]}"
        result = json.loads(out.read_text())
    times, rows = result["time"], result["rows"]
    assert len(times) == len(rows) == n
    return times, rows


def fmi_version(fmu: Path) -> str:
    return read_model_description(str(fmu)).fmiVersion


def horizon(fmu: Path) -> tuple[float, int]:
    e = read_model_description(str(fmu)).defaultExperiment
    assert e is not None and e.stepSize and e.stopTime, f"{fmu.name}: no DefaultExperiment"
    # libcosimpy's execution starts at 0 (cosim_execution_create(0, step)).
    assert float(e.startTime or 0) == 0.0, f"{fmu.name}: DefaultExperiment starts at {e.startTime}"
    step = float(e.stepSize)
    n = int(round(float(e.stopTime) / step))
    assert abs(n * step - float(e.stopTime)) <= 1e-9 * float(e.stopTime), f"{fmu.name}: stopTime is not a whole number of steps"
    return step, min(n, MAX_STEPS)


def kinds(fmu: Path) -> dict[str, str]:
    """Every output's kind, Real, Integer or Boolean (FMI 3.0's Float64 is a
    Real, its Int32 an Integer)."""
    return {v.name: KIND[v.type] for v in read_model_description(str(fmu)).modelVariables if v.causality == "output"}


def nontrivial(fmu: Path, rows: list[dict]) -> None:
    """The run covers impacts and motion, and no output is NaN or infinite."""
    types = kinds(fmu)
    assert set(rows[0]) == set(types), "every output is read"
    counts = [name for name in types if name.endswith(("impacts", "contacts"))]
    with zipfile.ZipFile(fmu) as z:
        scene = json.loads(z.read("resources/scene.json"))
    if scene.get("stops") or scene.get("surface"):
        assert counts, f"{fmu.name}: no impact count among the outputs"
    assert all(rows[-1][c] >= 1 for c in counts), f"{fmu.name}: a stop never hit: {[(c, rows[-1][c]) for c in counts]}"
    reals = [name for name, t in types.items() if t == "Real"]
    assert all(math.isfinite(r[name]) for r in rows for name in reals)
    moving = [name for name in reals if len({r[name] for r in rows}) > len(rows) // 2]
    assert len(moving) >= len(reals) // 2, f"{fmu.name}: most outputs hardly change: only {moving}"


def assert_identical(fmu: Path, ref: list[dict], other: list[dict], what: str) -> None:
    """Every output at every communication point equal bit for bit (the
    repr of a float shows every bit; no output is NaN, nontrivial())."""
    assert len(ref) == len(other)
    for k, (a, b) in enumerate(zip(ref, other)):
        if a != b:
            bad = [f"{name}: {a[name]!r} vs {b.get(name)!r}" for name in a if a[name] != b.get(name)]
            pytest.fail(f"{fmu.name}, {what}, step {k + 1}: {len(bad)} outputs differ: " + "; ".join(bad[:8]))


def test_there_are_fmus():
    assert FMUS, f"no FMU in {os.environ.get('BEAMSTOP_FMU_DIR', FMU_DIR)}"


@pytest.mark.parametrize("fmu", FMUS, ids=IDS)
def test_ecos_equals_fmpy_bit_for_bit(fmu):
    t_ref, ref = run("fmpy", fmu)
    nontrivial(fmu, ref)
    t_ecos, ecos = run("ecos", fmu)
    assert t_ecos == t_ref, "ecos's time grid is fmpy's t += h"
    assert_identical(fmu, ref, ecos, "fmpy vs ecos")


def test_there_are_fmi3_fmus():
    assert FMUS3, f"no FMU in {FMU3_DIR}"
    assert all(fmi_version(f) == "3.0" for f in FMUS3)


@pytest.mark.parametrize("fmu", FMUS3, ids=IDS3)
def test_ecos_equals_fmpy_bit_for_bit_fmi3(fmu):
    t_ref, ref = run("fmpy", fmu)
    nontrivial(fmu, ref)
    t_ecos, ecos = run("ecos", fmu)
    assert t_ecos == t_ref, "ecos's time grid is fmpy's t += h"
    assert_identical(fmu, ref, ecos, "fmpy vs ecos, FMI 3.0")


@pytest.mark.parametrize("fmu", FMUS, ids=IDS)
def test_libcosim_equals_fmpy_bit_for_bit(fmu):
    t_ref, ref = run("fmpy-libcosim", fmu)
    nontrivial(fmu, ref)
    t_osp, osp = run("libcosim", fmu)
    assert t_osp == t_ref, "libcosim's time grid is k h_ns / 1e9"
    assert_identical(fmu, ref, osp, "fmpy on libcosim's grid vs libcosim")


@pytest.mark.parametrize("fmu", FMUS, ids=IDS)
def test_libcosim_grid_agrees_with_fmpy_grid(fmu):
    t_sum, ref = run("fmpy", fmu)
    t_ns, osp = run("libcosim", fmu)
    assert t_sum != t_ns, "the grids differ (else this test is the one above)"
    assert max(abs(a - b) for a, b in zip(t_sum, t_ns)) <= 1e-15 * t_sum[-1] * len(t_sum)
    types = kinds(fmu)
    scale = {name: max(abs(r[name]) for r in ref) for name, t in types.items() if t == "Real"}
    # An output that sits at zero for a while (a stop's reaction) is compared
    # on the scale of the whole motion.
    motion = max(scale.values())
    # The grids' points differ by up to ~1e-13 s, and an output read at a
    # shifted time differs by its rate times the shift: a sticking reaction
    # carries the stiffest modes and changes at up to ~1e5 N/s (measured
    # 2.6e5 N/s on SteelCantileverStop), faster than the grid resolves. The
    # rate is bounded by 1000 times the largest change per step seen on the grid.
    rate = {name: 1e3 * max(abs(ref[k + 1][name] - ref[k][name]) / (t_sum[k + 1] - t_sum[k]) for k in range(len(ref) - 1))
            for name in scale}
    for k, (a, b) in enumerate(zip(ref, osp)):
        shift = abs(t_sum[k] - t_ns[k])
        for name, t in types.items():
            if t != "Real" or name.endswith("t_last_impact"):
                assert a[name] == b[name], f"step {k + 1}: {name}: {a[name]!r} vs {b[name]!r}"
            else:
                tol = 1e-8 * max(scale[name], 1e-6 * motion) + shift * rate[name]
                assert abs(a[name] - b[name]) <= tol, f"step {k + 1}: {name}: {a[name]!r} vs {b[name]!r} (grid shift {shift:.1e} s)"
