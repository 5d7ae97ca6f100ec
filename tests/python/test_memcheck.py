"""scripts/memcheck: tests/c/drive_fmu.c (a realistic and a hostile FMI
session: 600 steps, states got, set, serialized, corrupted slot by slot and
deserialized, bad arguments, reset) under valgrind memcheck, for every FMU.
Any invalid read or write, use of uninitialised memory or leak fails."""

import shutil
import subprocess

import pytest

from conftest import ROOT


@pytest.mark.skipif(shutil.which("valgrind") is None or shutil.which("gcc") is None, reason="needs valgrind and gcc")
def test_valgrind_finds_no_error_in_any_fmu():
    proc = subprocess.run([str(ROOT / "scripts" / "memcheck")], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-5000:] + proc.stderr[-3000:]
    assert proc.stdout.count("valgrind clean") >= 5, proc.stdout
