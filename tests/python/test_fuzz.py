"""A bounded run of the FMI fuzzers over every FMU: tests/python/fuzz_fmi.py
through the fmi2 functions (target/fmu/*.fmu) and tests/python/fuzz_fmi3.py
through the fmi3 functions (target/fmu3/*.fmu; event mode, early return and
the intermediate-update callback chosen at random per instance): random
call sequences and corrupted serialized states, each run in a subprocess so
that a crash or a hang is a failure, not a dead test session. The test
command runs 600 (FMI 2.0) and 400 (FMI 3.0) calls per FMU, scripts/test
--full 1500 and 1000. The long runs are commands of their own:

    python tests/python/fuzz_fmi.py --fmu target/fmu/PinnedBeamStop.fmu --seed 7 --calls 1000000
    python tests/python/fuzz_fmi3.py --fmu target/fmu3/PinnedBeamStop.fmu --seed 7 --calls 1000000
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import FMU_DIR, FULL, ROOT, python_env

HERE = Path(__file__).resolve().parent
FMUS = sorted(FMU_DIR.glob("*.fmu"))
FMU3_DIR = ROOT / "target" / "fmu3"
FMUS3 = sorted(FMU3_DIR.glob("*.fmu"))
SEEDS = (11, 12)
CALLS = 1500 if FULL else 600
# FMI 3.0 sequences are dearer per call (early returns, event-mode rounds).
CALLS3 = 1000 if FULL else 400


def fuzz(script: str, fmu: Path, seed: int, calls: int = CALLS) -> dict:
    cmd = [sys.executable, str(HERE / script), "--fmu", str(fmu), "--seed", str(seed), "--calls", str(calls)]
    try:
        proc = subprocess.run(cmd, env=python_env(), capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        pytest.fail(f"no answer within 120 s (a call that hangs): {' '.join(cmd[1:])}")
    assert proc.returncode == 0, f"crashed (exit {proc.returncode}):\n{proc.stderr[-3000:]}"
    assert proc.stderr == "", f"the FMU wrote to stderr:\n{proc.stderr[-3000:]}"
    return json.loads(proc.stdout)


# One seed per FMU and interface, the two interfaces taking the two seeds in
# turn: both shells run on one core (src/fmi/), so every FMU meets both
# seeds, once through each shell.
@pytest.mark.parametrize("fmu,seed", [(f, SEEDS[(k + 1) % 2]) for k, f in enumerate(FMUS)], ids=[f.stem for f in FMUS])
def test_random_call_sequences_keep_every_promise(fmu, seed):
    summary = fuzz("fuzz_fmi.py", fmu, seed)
    assert summary["calls"] >= CALLS and summary["states"] > CALLS // 150
    assert summary["n_broken"] == 0, "\n".join(summary["broken"])


@pytest.mark.parametrize("fmu,seed", [(f, SEEDS[k % 2]) for k, f in enumerate(FMUS3)], ids=[f.stem for f in FMUS3])
def test_random_fmi3_call_sequences_keep_every_promise(fmu, seed):
    summary = fuzz("fuzz_fmi3.py", fmu, seed, CALLS3)
    assert summary["n_broken"] == 0, "\n".join(summary["broken"] + ["the calls before the first:"]
                                               + summary["first_trace"])
    assert summary["calls"] >= CALLS3 and summary["states"] > CALLS3 // 200


def test_every_fmu_is_fuzzed_in_both_versions():
    assert [f.name for f in FMUS3] == [f.name for f in FMUS], "target/fmu3 and target/fmu differ: package both"
