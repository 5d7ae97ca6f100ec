"""The report's figure modules: the rotating beam's figures from the committed
CSVs (issue 9) and the run-time-against-N summary (issue 10)."""
from __future__ import annotations

import csv
import math
import pathlib
import shutil

from tools.report import rotating_plots, scaling

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_rotating_figures_from_the_committed_csvs(tmp_path):
    for name in ("seed_history.csv", "modes.csv", "spin_up.csv"):
        shutil.copy(ROOT / "report" / "rotating" / name, tmp_path / name)
    figures = rotating_plots.main(["--dir", str(tmp_path)])
    for png in ("seed_history.png", "modes.png", "spin_up.png"):
        assert (tmp_path / png).stat().st_size > 10_000, png
    # The numbers the figures quote, against the CSVs read here independently.
    with open(tmp_path / "seed_history.csv") as f:
        force = [float(r["force"]) for r in csv.DictReader(f)]
    onsets = sum(1 for a, b in zip(force, force[1:]) if a <= 0 < b)
    assert figures["seed_history"]["contacts"] == onsets == 12  # as summary.md states
    with open(tmp_path / "modes.csv") as f:
        rows = [(int(r["modes"]), float(r["peak_force"])) for r in csv.DictReader(f)]
    ref = rows[-1][1]
    n1 = figures["modes"]["within_1_percent_from"]
    assert all(abs(p / ref - 1) <= 0.01 for n, p in rows if n >= n1)
    assert any(abs(p / ref - 1) > 0.01 for n, p in rows if n < n1)
    assert figures["spin_up"]["zeroth_max"] > 100 * figures["spin_up"]["first_max"]


def test_scaling_slope_and_summary():
    rows = [{"case": "rigid", "modes": n, "run_s": 3e-5 * n ** 1.5, "build_s": 1e-6 * n * n, "probes": 100 * n,
             "events": 10, "contacts": 5} for n in (4, 16, 32, 64, 128, 500)]
    assert math.isclose(scaling.slope(rows, 32, 500), 1.5, rel_tol=1e-12)
    text = scaling.summary(rows)
    assert "between 32 and 500 modes: 1.50" in text
    assert "| rigid | 500 |" in text
