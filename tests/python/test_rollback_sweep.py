"""Every state an FMU serializes deserializes and continues bit for bit
(issue 41): the bounded sweep of tests/python/rollback_sweep.py (--quick)
per FMU and standard, in a subprocess (a crash or a hang is a failure, not
a dead session). Per FMU: the defaults, each tolerance parameter at its
ends and their geometric middle, each input at {min, -1, 0, 1, max} set
just before a save, the experiment's step, over a horizon that ends just
after the first contacts (saves before the first 10 steps, the 10 steps
after each input set and every step of the contacts' window); FMI 3.0
with the 4 combinations of eventModeUsed and earlyReturnAllowed, states
saved in event mode and with an event pending too, each also restored
into an instance with other flags. About 22 s of CPU over the 22 runs.
The full sweep (about 20 min of CPU) and the random one are commands:

    python tests/python/rollback_sweep.py                 # every FMU, both standards
    python tests/python/rollback_sweep.py --fuzz 200 --seed 3
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT, python_env

HERE = Path(__file__).resolve().parent
FMUS = [p for fmi in ("fmu", "fmu3") for p in sorted((ROOT / "target" / fmi).glob("*.fmu")) if p.stem != "PDController"]
TIMEOUT = 180  # s: each run takes 0.3 to 5 s of CPU


def failures(result: dict) -> str:
    lines = []
    for kind, c in result["failures"].items():
        lines.append(f"{c['count']} x {kind}")
        for e in c["examples"][:1]:
            lines.append("    e.g. " + json.dumps(e)[:1500])
    return "\n".join(lines)


@pytest.mark.parametrize("fmu", FMUS, ids=[f"{p.stem}-fmi{3 if p.parent.name == 'fmu3' else 2}" for p in FMUS])
def test_every_saved_state_restores_and_continues_bit_for_bit(fmu):
    cmd = [sys.executable, str(HERE / "rollback_sweep.py"), "--quick", "--fmu", str(fmu)]
    try:
        proc = subprocess.run(cmd, env=python_env(), capture_output=True, text=True, timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"no answer within {TIMEOUT} s (a call that hangs): {' '.join(cmd[1:])}")
    assert proc.returncode == 0, f"crashed (exit {proc.returncode}):\n{proc.stderr[-3000:]}"
    assert proc.stderr == "", f"the FMU wrote to stderr:\n{proc.stderr[-3000:]}"
    (r,) = json.loads(proc.stdout)["results"]
    assert r["init_refused"] == 0, f"an admitted setting was refused at initialisation:\n{failures(r)}"
    assert r["saved"] > 0 and r["restored_ok"] + r["refused"] == r["saved"]
    assert r["refused"] == 0 and r["cross_refused"] == 0, (
        f"{r['refused']} of {r['saved']} saved states refused by an instance with the same flags, "
        f"{r['cross_refused']} by one with other flags (not a legal refusal):\n{failures(r)}")
    assert r["mismatched"] == 0 and r["cross_mismatched"] == 0, (
        f"{r['mismatched']} restored states continued differently, {r['cross_mismatched']} with other flags:\n{failures(r)}")
    assert r["n_failures"] == 0, failures(r)
