"""The report's figure modules: the rotating beam's figures from the committed
CSVs (issue 9) and the run-time-against-N summary (issue 10)."""
from __future__ import annotations

import csv
import math
import pathlib
import shutil

from beamstop_tools.report import rotating_plots, scaling

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_rotating_figures_from_the_committed_csvs(tmp_path):
    for name in ("dwz_history.csv", "modes.csv", "spin_up.csv"):
        shutil.copy(ROOT / "report" / "rotating" / name, tmp_path / name)
    figures = rotating_plots.main(["--dir", str(tmp_path)])
    for png in ("dwz_history.png", "modes.png", "spin_up.png"):
        assert (tmp_path / png).stat().st_size > 10_000, png
    # The numbers the figures quote, against the CSVs read here independently.
    with open(tmp_path / "dwz_history.csv") as f:
        force = [float(r["force"]) for r in csv.DictReader(f)]
    onsets = sum(1 for a, b in zip(force, force[1:]) if a <= 0 < b)
    assert figures["dwz_history"]["contacts"] == onsets == 12  # as summary.md states
    with open(tmp_path / "modes.csv") as f:
        rows = [(int(r["modes"]), float(r["peak_force"])) for r in csv.DictReader(f)]
    ref = rows[-1][1]
    n1 = figures["modes"]["within_1_percent_from"]
    assert all(abs(p / ref - 1) <= 0.01 for n, p in rows if n >= n1)
    assert any(abs(p / ref - 1) > 0.01 for n, p in rows if n < n1)
    assert figures["spin_up"]["zeroth_max"] > 100 * figures["spin_up"]["first_max"]


def test_scaling_slope_and_summary():
    rows = [{"case": "rigid", "modes": n, "run_s": 3e-5 * n ** 1.5, "first_s": 2e-6 * n ** 2, "build_s": 1e-6 * n * n,
             "probes": 100 * n, "events": 10, "contacts": 5} for n in (4, 16, 32, 64, 128, 500)]
    assert math.isclose(scaling.slope(rows, 32, 500), 1.5, rel_tol=1e-12)
    text = scaling.summary(rows)
    assert "between 32 and 500 modes: 1.50" in text
    assert "the same for the first run: 2.00" in text
    assert "| rigid | 500 |" in text


def _levels_from_runs(runs, scene, level):
    """The fastest peer and beamstop runs within `level`, recomputed here."""
    def best(solver):
        ok = [r for r in runs if r["scene"] == scene and r["solver"] == solver
              and math.isfinite(float(r["err_events"])) and float(r["err_events"]) <= level]
        return min(ok, key=lambda r: float(r["ms"])) if ok else None
    return best("dop853"), best("beamstop")


def test_rigid_peer_level_table_matches_its_runs():
    """report/rigid_peer/levels.csv against the fastest runs recomputed from
    runs.csv; the peer's tightest runs agree with beamstop's event times."""
    with open(ROOT / "report" / "rigid_peer" / "runs.csv") as f:
        runs = list(csv.DictReader(f))
    with open(ROOT / "report" / "rigid_peer" / "levels.csv") as f:
        levels = list(csv.DictReader(f))
    assert {r["scene"] for r in levels} == {"S2", "S3"}
    for row in levels:
        peer, bs = _levels_from_runs(runs, row["scene"], float(row["level"]))
        if peer is None:
            assert row["peer_setting"] == ""
            continue
        assert peer["setting"] == row["peer_setting"] and bs["setting"] == row["beamstop_setting"]
        assert math.isclose(float(row["ratio"]), float(peer["ms"]) / float(bs["ms"]), rel_tol=1e-3)
    for scene, tight in (("S2", 1e-13), ("S3", 1e-12)):
        errors = [float(r["err_events"]) for r in runs if r["scene"] == scene and r["solver"] == "dop853"]
        assert min(e for e in errors if math.isfinite(e)) < tight, scene


def test_compiled_peer_agrees_with_beamstop_on_every_event(tmp_path):
    """A live run of the compiled DOP853 peer (another integrator, its own
    event loop) on S3: at rtol 1e-13 and 1e-14 it reproduces beamstop's 177
    impacts, 7 sticks and 6 releases to 1e-11."""
    import subprocess

    exe = ROOT / "target" / "release" / "examples" / "rigid_peer"
    runs_csv = tmp_path / "runs.csv"
    subprocess.run([str(exe), "--quick", "--scene", "S3", "--csv", str(runs_csv)], check=True, cwd=ROOT,
                   capture_output=True, timeout=300)
    with open(runs_csv) as f:
        runs = [r for r in csv.DictReader(f) if r["solver"] == "dop853" and r["setting"].startswith(("rtol=1e-13", "rtol=1e-14"))]
    assert runs
    for r in runs:
        assert (r["impacts"], r["sticks"], r["releases"]) == ("177", "7", "6"), r
        assert float(r["err_events"]) < 1e-11, r
