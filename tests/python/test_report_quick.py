"""scripts/report --quick, the smoke run of every report (the same code
paths as scripts/report with few settings and short runs, to the
git-ignored target/report-quick/), must pass: a report that breaks fails
the test command instead of waiting for the next full report.

--no-package: target/fmu/ is packed by the test command before the tests,
and other tests read it meanwhile. The five longest smoke runs (about half
the time) run with `scripts/test --full` only (docs/verification.md)."""
from __future__ import annotations

import subprocess

from conftest import FULL, ROOT

# The longest smoke runs; their code paths are the reports' own, and the
# product's behaviour they print is tested elsewhere (test_coupling.py,
# the integration tests).
LONGEST = ["generate", "spring_stop", "rigid_peer", "coupling", "scaling"]


def test_report_quick():
    skip = [] if FULL else [f"--skip={','.join(LONGEST)}"]
    p = subprocess.run([str(ROOT / "scripts" / "report"), "--quick", "--no-package", *skip], cwd=ROOT,
                       capture_output=True, text=True, timeout=1200)
    assert p.returncode == 0, f"scripts/report --quick failed:\n{p.stdout[-6000:]}\n{p.stderr[-3000:]}"
    summary = [line for line in p.stdout.splitlines() if line.startswith("scripts/report --quick:")]
    assert summary and " 0 failed" in summary[-1], p.stdout[-3000:]
