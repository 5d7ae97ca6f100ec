"""scripts/memcheck: tests/c/drive_fmu.c (a realistic and a hostile FMI
2.0 session: 600 steps, states got, set, serialized, corrupted slot by slot
and deserialized, bad arguments, reset) under valgrind memcheck, for every
FMU in target/fmu; tests/c/drive_fmu3.c, the same through FMI 3.0 (event
mode used, early returns allowed, an intermediate-update callback that
calls back into the instance, about 600 steps), for one FMU of each kind
and law in target/fmu3. Any invalid read or write, use of uninitialised
memory or leak fails."""

import shutil
import subprocess

import pytest

from conftest import FMU_DIR, ROOT

FMUS = sorted(p.name for p in FMU_DIR.glob("*.fmu"))
FMU3_DIR = ROOT / "target" / "fmu3"
FMUS3 = sorted(p.name for p in FMU3_DIR.glob("*.fmu"))
# Through FMI 3.0, one scene per kind and law (the shell's code is the same
# for every scene; every scene runs under valgrind through FMI 2.0 above).
FMUS3_CHECKED = ["PinnedBeamStop.fmu", "SpringStopSoft.fmu", "HertzStop.fmu", "RotatingBeamImpact.fmu", "WaggBishopChain.fmu"]
NEEDS_TOOLS = pytest.mark.skipif(shutil.which("valgrind") is None or shutil.which("gcc") is None,
                                 reason="needs valgrind and gcc")


@NEEDS_TOOLS
@pytest.mark.parametrize("fmu", FMUS)
def test_valgrind_finds_no_error(fmu):
    proc = subprocess.run([str(ROOT / "scripts" / "memcheck"), str(FMU_DIR / fmu)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-5000:] + proc.stderr[-3000:]
    assert proc.stdout.count("valgrind clean") == 1, proc.stdout


@NEEDS_TOOLS
@pytest.mark.parametrize("fmu", FMUS3_CHECKED)
def test_valgrind_finds_no_error_through_fmi3(fmu):
    proc = subprocess.run([str(ROOT / "scripts" / "memcheck"), str(FMU3_DIR / fmu)], capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stdout[-5000:] + proc.stderr[-3000:]
    assert proc.stdout.count("valgrind clean") == 1, proc.stdout
    assert "(FMI 3.0): valgrind clean (2 runs)" in proc.stdout, proc.stdout


def test_every_fmu_is_checked():
    assert len(FMUS) >= 11, FMUS
    assert FMUS3 == FMUS, "target/fmu3 and target/fmu differ: package both"
    assert set(FMUS3_CHECKED) <= set(FMUS3)
