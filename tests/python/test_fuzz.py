"""A bounded run of the FMI fuzzer (tests/python/fuzz_fmi.py) over every
FMU: random call sequences and corrupted serialized states, each run in a
subprocess so that a crash or a hang is a failure, not a dead test session.
The long run is a command of its own:

    python tests/python/fuzz_fmi.py --fmu target/fmu/PinnedBeamStop.fmu --seed 7 --calls 1000000
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import FMU_DIR, python_env

HERE = Path(__file__).resolve().parent
FMUS = sorted(FMU_DIR.glob("*.fmu"))
SEEDS = (11, 12)
CALLS = 1500


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("fmu", FMUS, ids=[f.stem for f in FMUS])
def test_random_call_sequences_keep_every_promise(fmu, seed):
    proc = subprocess.run([sys.executable, str(HERE / "fuzz_fmi.py"), "--fmu", str(fmu), "--seed", str(seed),
                           "--calls", str(CALLS)], env=python_env(), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, f"crashed (exit {proc.returncode}):\n{proc.stderr[-3000:]}"
    assert proc.stderr == "", f"the FMU wrote to stderr:\n{proc.stderr[-3000:]}"
    summary = json.loads(proc.stdout)
    assert summary["calls"] >= CALLS and summary["states"] > 10
    assert summary["n_broken"] == 0, "\n".join(summary["broken"])
