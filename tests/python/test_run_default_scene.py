"""scripts/run_default_scene.py (the main job) into a temporary directory:
it validates, writes the CSV and the plot, and its summary agrees with the
CSV it wrote."""

import csv
import re
import subprocess
import sys

from conftest import ROOT, model_description


def test_main_job_script(tmp_path):
    script = ROOT / "scripts" / "run_default_scene.py"
    proc = subprocess.run([sys.executable, str(script), "--results", str(tmp_path)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    out = proc.stdout
    assert "PinnedBeamStop.fmu: valid" in out
    csv_path = tmp_path / "PinnedBeamStop_fmpy.csv"
    png_path = tmp_path / "PinnedBeamStop.png"
    assert str(csv_path) in out and str(png_path) in out
    assert png_path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with open(csv_path) as f:
        rows = list(csv.DictReader(f))
    ex = model_description().defaultExperiment
    n = round((float(ex.stopTime) - float(ex.startTime)) / float(ex.stepSize)) + 1
    assert len(rows) == n
    assert float(rows[1]["time"]) - float(rows[0]["time"]) == float(ex.stepSize)
    impacts = int(re.search(r"impacts:\s+(\d+)", out).group(1))
    assert impacts == int(rows[-1]["impacts"]) > 0
    stuck = float(re.search(r"sticking:\s+([0-9.]+)", out).group(1))
    dt = float(ex.stepSize)
    sampled = sum(dt for r in rows[1:] if r["sticking"] == "True")
    assert abs(stuck - sampled) <= 10 * dt, (stuck, sampled)
