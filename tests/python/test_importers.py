"""Every FMU stepped by three importers (fmpy, OSP libcosim through
libcosimpy, and ecos through ecospy) gives the same outputs at every
communication point.

Each importer runs in its own process (tests/python/importers.py): ecos
needs the tbb wheel's lib directory on LD_LIBRARY_PATH before it loads.
ecos keeps time as fmpy does (t += h) and must agree bit for bit. libcosim
keeps time in integer nanoseconds and converts it to the FMU's double time
its own way, so its communication points may differ from fmpy's by an ulp:
its Integer and Boolean outputs (impact counts, sticking) and the exact
event times must agree exactly, continuous outputs to 1e-9 of their scale
(a time shift of one ulp moves them by |dy/dt| * 1e-16 t).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from fmpy import read_model_description

from conftest import FMU_DIR, python_env

HERE = Path(__file__).resolve().parent
FMUS = sorted(Path(os.environ.get("BEAMSTOP_FMU_DIR", FMU_DIR)).glob("*.fmu"))
MAX_STEPS = 1500


def run(importer: str, fmu: Path, step: float, n: int, tmp_path: Path) -> list[dict]:
    out = tmp_path / f"{importer}.json"
    env = python_env()
    # The tbb wheel puts libtbb.so.12 into <venv>/lib.
    env["LD_LIBRARY_PATH"] = os.pathsep.join([str(Path(sys.prefix) / "lib"), env.get("LD_LIBRARY_PATH", "")])
    proc = subprocess.run([sys.executable, str(HERE / "importers.py"), importer, str(fmu), repr(step), str(n), str(out)],
                          env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"{importer} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    rows = json.loads(out.read_text())
    assert len(rows) == n
    return rows


def horizon(fmu: Path) -> tuple[float, int]:
    e = read_model_description(str(fmu)).defaultExperiment
    step = float(e.stepSize)
    return step, min(MAX_STEPS, int(round((float(e.stopTime) - float(e.startTime)) / step)))


def events_happen(rows: list[dict]) -> bool:
    return any(v for k, v in rows[-1].items() if k.endswith("impacts"))


@pytest.mark.parametrize("fmu", FMUS, ids=[f.stem for f in FMUS])
def test_ecos_agrees_with_fmpy_bit_for_bit(fmu, tmp_path):
    step, n = horizon(fmu)
    ref = run("fmpy", fmu, step, n, tmp_path)
    assert events_happen(ref), "the comparison should cover impacts"
    ecos = run("ecos", fmu, step, n, tmp_path)
    for k, (a, b) in enumerate(zip(ref, ecos)):
        assert a == b, f"step {k + 1}: " + ", ".join(f"{v}: {a[v]!r} vs {b[v]!r}" for v in a if a[v] != b[v])


@pytest.mark.parametrize("fmu", FMUS, ids=[f.stem for f in FMUS])
def test_libcosim_agrees_with_fmpy(fmu, tmp_path):
    step, n = horizon(fmu)
    ref = run("fmpy-ns", fmu, step, n, tmp_path)
    assert events_happen(ref), "the comparison should cover impacts"
    osp = run("libcosim", fmu, step, n, tmp_path)
    md = read_model_description(str(fmu))
    kinds = {v.name: v.type for v in md.modelVariables if v.causality == "output"}
    scale = {name: max(abs(r[name]) for r in ref) for name, t in kinds.items() if t == "Real"}
    # Displacements at a stop sit at zero while stuck: compare them on the
    # scale of the whole motion.
    motion = max(scale.values())
    for k, (a, b) in enumerate(zip(ref, osp)):
        for name, t in kinds.items():
            if t != "Real" or name.endswith("t_last_impact"):
                assert a[name] == b[name], f"step {k + 1}: {name}: {a[name]!r} vs {b[name]!r}"
            else:
                tol = 1e-9 * max(scale[name], 1e-6 * motion)
                assert abs(a[name] - b[name]) <= tol, f"step {k + 1}: {name}: {a[name]!r} vs {b[name]!r}"
