"""scripts/memcheck: tests/c/drive_fmu.c (a realistic and a hostile FMI
session: 600 steps, states got, set, serialized, corrupted slot by slot and
deserialized, bad arguments, reset) under valgrind memcheck, for every FMU.
Any invalid read or write, use of uninitialised memory or leak fails."""

import shutil
import subprocess

import pytest

from conftest import FMU_DIR, ROOT

FMUS = sorted(p.name for p in FMU_DIR.glob("*.fmu"))


@pytest.mark.skipif(shutil.which("valgrind") is None or shutil.which("gcc") is None, reason="needs valgrind and gcc")
@pytest.mark.parametrize("fmu", FMUS)
def test_valgrind_finds_no_error(fmu):
    proc = subprocess.run([str(ROOT / "scripts" / "memcheck"), str(FMU_DIR / fmu)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-5000:] + proc.stderr[-3000:]
    assert proc.stdout.count("valgrind clean") == 1, proc.stdout


def test_every_fmu_is_checked():
    assert len(FMUS) >= 11, FMUS
