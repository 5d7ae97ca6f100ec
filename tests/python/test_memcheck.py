"""scripts/memcheck: tests/c/drive_fmu.c (a realistic and a hostile FMI
2.0 session: 600 steps, states got, set, serialized, corrupted slot by slot
and deserialized, bad arguments, reset) under valgrind memcheck, and
tests/c/drive_fmu3.c, the same through FMI 3.0 (event mode used, early
returns allowed, an intermediate-update callback that calls back into the
instance, about 600 steps): in the test command for the binaries whose
source covers every kind and law (the modal variant, which carries the
rigid, spring and Hertz laws' code that the rigid and compliant variants
compile a part of; the spring variant's mode transfer; the rotating
variant) through each standard, with scripts/test --full for every FMU in
target/fmu as well. Any invalid read or write, use of uninitialised memory
or leak fails."""

import shutil
import subprocess

import pytest

from conftest import FMU_DIR, FULL, ROOT

FMUS = sorted(p.name for p in FMU_DIR.glob("*.fmu"))
FMU3_DIR = ROOT / "target" / "fmu3"
FMUS3 = sorted(p.name for p in FMU3_DIR.glob("*.fmu"))
# One scene per variant of the binary whose source is not a part of
# another's (`beamstop variants`: the rigid and compliant variants are the
# modal one's code without some laws; the shell's code is the same for
# every variant); HertzStop and PinnedBeamStop with --full.
ONE_PER_VARIANT = ["SpringStopSoft.fmu", "RigidAndHertzStops.fmu", "RotatingBeamImpact.fmu"]
FMUS_CHECKED = FMUS if FULL else ONE_PER_VARIANT
FMUS3_CHECKED = ONE_PER_VARIANT + (["WaggBishopChain.fmu"] if FULL else [])
NEEDS_TOOLS = pytest.mark.skipif(shutil.which("valgrind") is None or shutil.which("gcc") is None,
                                 reason="needs valgrind and gcc")


@NEEDS_TOOLS
@pytest.mark.parametrize("fmu", FMUS_CHECKED)
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
    assert set(FMUS3_CHECKED) <= set(FMUS3) and set(FMUS_CHECKED) <= set(FMUS)
