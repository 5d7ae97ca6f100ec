"""scripts/report --quick, the smoke run of every report (the same code
paths as scripts/report with few settings and short runs, to the
git-ignored target/report-quick/), must pass: a report that breaks fails
the test command instead of waiting for the next full report.

--no-package: target/fmu/ is packed by the test command before the tests,
and other tests read it meanwhile."""
from __future__ import annotations

import subprocess

from conftest import ROOT


def test_report_quick():
    p = subprocess.run([str(ROOT / "scripts" / "report"), "--quick", "--no-package"], cwd=ROOT,
                       capture_output=True, text=True, timeout=1200)
    assert p.returncode == 0, f"scripts/report --quick failed:\n{p.stdout[-6000:]}\n{p.stderr[-3000:]}"
    summary = [line for line in p.stdout.splitlines() if line.startswith("scripts/report --quick:")]
    assert summary and " 0 failed" in summary[-1], p.stdout[-3000:]
