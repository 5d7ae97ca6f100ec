"""Periodic orbits continued in one parameter, for Python users (scripts/orbits).

    scripts/orbits scenes/pinned_beam.json --param d=0:1.8 --start 1.2 \\
        --set F=72 --set 'omega=0.7*pi**2' --set eps=1e-3 --sweep target/sweeps/gap --out target/orbits/gap

runs the library's continuation (`beamstop orbits`: Newton shooting with the
exact monodromy matrix, pseudo-arclength steps, special points; see
docs/orbits.md), then writes DIR/branch.parquet and DIR/special.parquet
(the multipliers and the section samples as list columns) and DIR/orbits.png:
stable branches solid, unstable dashed, special points marked, over the
brute-force sweep of the same parameter when --sweep names its directory
(a `scripts/sweep` run; its points.parquet), or over one it runs first
with --sweep-points N.

From Python: `continue_orbits(scene, "d", 0, 1.8, start=1.2, sets={...},
out=...)` returns the two tables and the run's time; `plot(...)` draws them.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from . import ROOT, engine
from .sweep.errors import SweepError
from .sweep.expr import Expression

#: The command line built by scripts/orbits (cargo build --release).
LIST_COLUMNS = {"multipliers_re", "multipliers_im", "section", "state"}
BOOL_COLUMNS = {"stable"}
INT_COLUMNS = {"branch", "n_unstable", "sticks", "periods"}
TEXT_COLUMNS = {"type", "note"}


class OrbitsError(Exception):
    """The continuation refused its input or failed; the message says why."""


@dataclass
class Orbits:
    branch: pa.Table     # one row per continuation point
    special: pa.Table    # one row per special point (SN, BP, PD, NS, GR, ST, EP)
    param: str
    seconds: float       # the continuation's wall time (the command's own run)
    summary: str         # what the command printed


def _column(name: str, values: list[str]) -> pa.Array:
    if name in LIST_COLUMNS:
        return pa.array([json.loads(v) for v in values], pa.list_(pa.float64()))
    if name in BOOL_COLUMNS:
        return pa.array([v == "true" for v in values], pa.bool_())
    if name in INT_COLUMNS:
        return pa.array([int(v) for v in values], pa.int64())
    if name in TEXT_COLUMNS:
        return pa.array(values, pa.string())
    return pa.array([float(v) if v != "" else None for v in values], pa.float64())


def read_csv(path: Path) -> pa.Table:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    return pa.table({name: _column(name, [r[i] for r in body]) for i, name in enumerate(header)})


def continue_orbits(scene: str | Path, param: str, frm: float, to: float, *, out: str | Path,
                    start: float | list[float] | None = None, sets: dict[str, float] | None = None,
                    ties: list[str] | None = None, points: int = 200, max_branches: int = 8,
                    transient: int = 200, max_period: int = 8, phase: float = 0.0) -> Orbits:
    """Runs `beamstop orbits` and returns its tables (also written as Parquet to `out`)."""
    if not engine.binary().exists():
        raise OrbitsError(f"{engine.binary()} is missing: run scripts/orbits (or cargo build --release) first")
    out = Path(out)
    args = ["orbits", str(scene), "--param", f"{param}={float(frm)!r}:{float(to)!r}", "--out", str(out),
            "--points", str(int(points)), "--max-branches", str(int(max_branches)), "--transient", str(int(transient)),
            "--max-period", str(int(max_period)), "--phase", repr(float(phase))]
    for s in ([] if start is None else [start] if isinstance(start, (int, float)) else start):
        args += ["--start", repr(float(s))]
    for name, value in (sets or {}).items():
        args += ["--set", f"{name}={value!r}"]
    for tie in ties or []:
        args += ["--tie", tie]
    began = time.perf_counter()
    done = engine.beamstop(args)
    seconds = time.perf_counter() - began
    if done.returncode != 0:
        raise OrbitsError(done.stderr.strip() or f"beamstop orbits failed ({done.returncode})")
    branch, special = read_csv(out / "branch.csv"), read_csv(out / "special.csv")
    pq.write_table(branch, out / "branch.parquet")
    pq.write_table(special, out / "special.parquet")
    return Orbits(branch, special, param, seconds, done.stdout)


def _segments(rows: list[dict]):
    """Consecutive points of one branch with one stability (its first point
    the last of the segment before on the same branch, so the line goes on),
    for polylines per section sample (a period-m orbit has m samples)."""
    run: list[dict] = []
    for r in rows + [None]:
        same_branch = r is not None and run and r["branch"] == run[-1]["branch"] and len(r["section"]) == len(run[-1]["section"])
        if same_branch and r["stable"] == run[-1]["stable"]:
            run.append(r)
            continue
        if run:
            yield run
        run = ([run[-1]] if same_branch else []) + ([r] if r is not None else [])


def plot(orbits: Orbits, path: str | Path, sweep: pa.Table | None = None, title: str = "",
         output_label: str = "first stop's displacement") -> None:
    """Section samples and impacts per period against the parameter: stable branches solid,
    unstable dashed, special points marked (not the branches' ends), the
    sweep's samples in grey."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    param = orbits.param
    rows = orbits.branch.to_pylist()
    fig, ax = plt.subplots(2, 1, figsize=(9, 8), sharex=True)
    if sweep is not None:
        for r in sweep.to_pylist():
            if r.get("error"):
                continue
            ax[0].plot([r[param]] * len(r["poincare"]), r["poincare"], ".", ms=1.5, color="0.6", zorder=1)
            ax[1].plot(r[param], r["impacts_per_period"], ".", ms=2, color="0.6", zorder=1)
        ax[0].plot([], [], ".", color="0.6", label="brute-force sweep")
    labelled = set()
    for seg in _segments(rows):
        stable = seg[-1]["stable"]
        style = dict(color="k" if stable else "tab:red", ls="-" if stable else "--", lw=1.0 if stable else 1.2, zorder=2)
        label = "stable" if stable else "unstable"
        x = [r[param] for r in seg]
        for k in range(len(seg[0]["section"])):
            ax[0].plot(x, [r["section"][k] for r in seg], label=None if label in labelled else label, **style)
            labelled.add(label)
        ax[1].plot(x, [r["impacts_per_period"] for r in seg], **style)
    markers = {"SN": ("v", "tab:blue"), "BP": ("x", "tab:purple"), "PD": ("s", "tab:orange"),
               "NS": ("D", "tab:green"), "GR": ("o", "tab:cyan"), "ST": ("^", "tab:brown")}
    for s in orbits.special.to_pylist():
        if s["type"] == "EP":
            continue  # every branch has two: the table says where and why
        marker, color = markers[s["type"]]
        kw = dict(marker=marker, color=color, ms=5, ls="none", zorder=3, mfc="none")
        ax[0].plot([s[param]] * len(s["section"]), s["section"], label=None if s["type"] in labelled else s["type"], **kw)
        ax[1].plot(s[param], s["impacts_per_period"], **kw)
        labelled.add(s["type"])
    ax[0].set_ylabel(f"{output_label} at phase 0")
    ax[1].set_ylabel("impacts per forcing period")
    ax[1].set_xlabel(param)
    ax[0].legend(fontsize=7, ncol=4, loc="best")
    if title:
        ax[0].set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def on_branches(orbits: Orbits, sweep: pa.Table, periods=(1, 2), tolerance: float = 1e-3):
    """Which of the sweep's period-1 and period-2 points lie on a continued
    branch: same period, same impacts per period, and every Poincare sample
    within `tolerance` (of the samples' range) of the branch's section,
    interpolated linearly between the branch's two points around the
    parameter value. Returns (matched, total, the unmatched parameter values)."""
    param = orbits.param
    rows = orbits.branch.to_pylist()
    scale = max((abs(v) for r in rows for v in r["section"]), default=1.0) or 1.0
    matched, missed = 0, []
    candidates = [r for r in sweep.to_pylist() if not r.get("error") and r.get("period") in periods]
    for r in candidates:
        p, samples = r[param], r["poincare"]
        found = False
        # consecutive points of a branch, and each point alone (a branch
        # of one point, or a sample exactly at a point)
        pairs = [(a, b) for a, b in zip(rows, rows[1:]) if a["branch"] == b["branch"]] + [(a, a) for a in rows]
        for a, b in pairs:
            if a["periods"] != r["period"] or not (min(a[param], b[param]) <= p <= max(a[param], b[param])):
                continue
            if abs(a["impacts_per_period"] - r["impacts_per_period"]) > 0.01 and abs(b["impacts_per_period"] - r["impacts_per_period"]) > 0.01:
                continue
            w = 0.0 if b[param] == a[param] else (p - a[param]) / (b[param] - a[param])
            section = [(1 - w) * x + w * y for x, y in zip(a["section"], b["section"])]
            if all(min(abs(s - x) for x in section) <= tolerance * scale for s in samples):
                found = True
                break
        if found:
            matched += 1
        else:
            missed.append(p)
    return matched, len(candidates), missed


def cover(scene, param: str, frm: float, to: float, sweep: pa.Table, *, out: str | Path, start=None,
          transient: int = 100, max_branches: int = 200, **kw) -> Orbits:
    """Continues from `start`, then again with every period-1 or period-2
    point of `sweep` not yet on a branch as a start of its own (each from a
    transient of `transient` periods, the sweep's own discard, so that it
    settles where the sweep did). Returns the second run (or the first, if
    it already covers the sweep)."""
    starts = [] if start is None else [start] if isinstance(start, (int, float)) else list(start)
    first = continue_orbits(scene, param, frm, to, out=out, start=starts or None, transient=transient, **kw)
    _, _, missed = on_branches(first, sweep)
    if not missed:
        return first
    second = continue_orbits(scene, param, frm, to, out=out, start=(starts or [frm]) + missed, transient=transient,
                             max_branches=max_branches, **kw)
    second.seconds += first.seconds
    return second


def sweep_for(scene: str | Path, param: str, frm: str, to: str, points: int, sets: list[str], ties: list[str], out: Path,
              discard: float = 100, record: int = 50, workers: int | None = None) -> pa.Table:
    """The brute-force sweep of the same range (`scripts/sweep` on the
    scene's FMU in target/fmu/): `points` values, the
    same --set values, each --tie as a --set expression. Returns its table
    (also in out/points.parquet)."""
    from .sweep import spec as spec_mod
    from .sweep.engine import dask_client, run_sweep
    from .sweep.fmu import read_fmu
    from .sweep.store import read_points

    name = json.loads(Path(scene).read_text()).get("name")
    fmu = ROOT / "target" / "fmu" / f"{name}.fmu"
    if not fmu.exists():
        raise OrbitsError(f"--sweep-points: {fmu} is missing: package the scene first "
                          f"(target/release/beamstop package {scene}), or give a sweep with --sweep DIR")
    set_exprs = list(sets) + [t.replace("^", "**") for t in ties]
    spec = spec_mod.build(read_fmu(fmu), [f"{param}={frm}:{to}:{points}"], set_exprs, discard, record)
    with dask_client(None, workers) as client:
        run_sweep(spec, out, client, progress=sys.stderr.isatty(), restart=True, command="scripts/orbits --sweep-points")
    return read_points(out / "points.parquet")[0]


def _pairs(items: list[str], flag: str) -> dict[str, str]:
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise OrbitsError(f"{flag} {item}: NAME=VALUE")
        out[name] = value
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="scripts/orbits", description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", help="a scene file (scenes/*.json)")
    ap.add_argument("--param", required=True, help="NAME=FROM:TO (FROM and TO may be expressions: 0.7*pi**2)")
    ap.add_argument("--start", action="append", default=[],
                    help="where an orbit is found to start a branch from (default FROM; repeat for more); an expression")
    ap.add_argument("--set", action="append", default=[], help="NAME=VALUE (an expression of numbers, pi, e, sqrt ...)")
    ap.add_argument("--tie", action="append", default=[], help="NAME=SCALE*PARAM^POWER: follows the continued parameter")
    ap.add_argument("--points", type=int, default=200, help="the longest step is 1/POINTS of the scaled arclength")
    ap.add_argument("--max-branches", type=int, default=8)
    ap.add_argument("--transient", type=int, default=200, help="forcing periods simulated before the first orbit")
    ap.add_argument("--max-period", type=int, default=8)
    ap.add_argument("--sweep", help="a scripts/sweep output directory of the same parameter, drawn under the branches")
    ap.add_argument("--sweep-points", type=int, metavar="N",
                    help="run the brute-force sweep of the same range first (N values; its FMU from target/fmu/), "
                         "to DIR/sweep, and draw the branches over it")
    ap.add_argument("--cover", action="store_true",
                    help="with --sweep: start again from every period-1 or period-2 sweep point not on a branch")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    try:
        name, sep, ends = a.param.partition("=")
        frm, sep2, to = ends.partition(":")
        if not sep or not sep2:
            raise OrbitsError(f"--param {a.param}: NAME=FROM:TO")
        value = lambda text, field: Expression(text, field, set()).value({})  # noqa: E731
        sets = {k: value(v, f"--set {k}") for k, v in _pairs(a.set, "--set").items()}
        if a.sweep and a.sweep_points:
            raise OrbitsError("--sweep DIR and --sweep-points N: one or the other")
        if a.sweep_points:
            sweep = sweep_for(a.scene, name, frm, to, a.sweep_points, a.set, a.tie, Path(a.out) / "sweep")
        else:
            sweep = pq.read_table(Path(a.sweep) / "points.parquet") if a.sweep else None
        if a.cover and sweep is None:
            raise OrbitsError("--cover needs --sweep DIR or --sweep-points N")
        common = dict(out=a.out, start=[value(s, "--start") for s in a.start] or None, sets=sets, ties=a.tie,
                      points=a.points, max_period=a.max_period)
        lo, hi = value(frm, "--param FROM"), value(to, "--param TO")
        if a.cover:
            discard = json.loads((sweep.schema.metadata or {}).get(b"beamstop.sweep", b"{}")).get("settings", {}).get("discard_periods")
            orbits = cover(a.scene, name, lo, hi, sweep, transient=int(discard or a.transient), **common)
        else:
            orbits = continue_orbits(a.scene, name, lo, hi, max_branches=a.max_branches, transient=a.transient, **common)
        plot(orbits, Path(a.out) / "orbits.png", sweep, title=f"{Path(a.scene).stem}: {a.param}")
    except (OrbitsError, SweepError) as err:
        print(f"scripts/orbits: {err}", file=sys.stderr)
        return 2
    sys.stdout.write(orbits.summary)
    if sweep is not None:
        matched, total, missed = on_branches(orbits, sweep)
        print(f"sweep points of period 1 or 2 on a continued branch: {matched} of {total}"
              + (f" (not: {name} = {', '.join(f'{p:g}' for p in missed[:10])}{' ...' if len(missed) > 10 else ''})" if missed else ""))
    print(f"tables: {Path(a.out) / 'branch.parquet'}, {Path(a.out) / 'special.parquet'}; plot: {Path(a.out) / 'orbits.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
