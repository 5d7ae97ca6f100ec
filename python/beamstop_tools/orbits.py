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
with --sweep-points N. --cover starts again from every periodic sweep
point on no branch, in --pieces runs on Dask (`cover`; docs/orbits.md).

From Python: `continue_orbits(scene, "d", 0, 1.8, start=1.2, sets={...},
out=...)` returns the two tables and the run's time; `plot(...)` draws them.
"""
from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import threading
import time
from contextlib import nullcontext
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


#: --cover's runs by default (--pieces): one, the single run. More give the
#: same diagram (and some of it twice) but cost more wall time than one on
#: the Fig. 9 example even on two workers (docs/orbits.md "--cover on Dask").
PIECES = 1


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
                    transient: int = 200, max_period: int = 8, phase: float = 0.0, exe: str | Path | None = None,
                    progress: str | None = None) -> Orbits:
    """Runs `beamstop orbits` (`exe`, default engine.binary()) and returns its
    tables (also written as Parquet to `out`). `progress`: the command's
    progress lines (stderr) go on to this process's stderr as they come,
    each after that prefix ("" for none); None: kept quiet (in the error
    if the command fails, as always)."""
    exe = Path(exe) if exe else engine.binary()
    if not exe.exists():
        raise OrbitsError(f"{exe} is missing: run scripts/orbits (or cargo build --release) first")
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
    done = engine.beamstop(args, exe=exe) if progress is None else _streamed([str(exe), *args], progress)
    seconds = time.perf_counter() - began
    if done.returncode != 0:
        raise OrbitsError(done.stderr.strip() or f"beamstop orbits failed ({done.returncode})")
    branch, special = read_csv(out / "branch.csv"), read_csv(out / "special.csv")
    pq.write_table(branch, out / "branch.parquet")
    pq.write_table(special, out / "special.parquet")
    return Orbits(branch, special, param, seconds, done.stdout)


def _streamed(cmd: list[str], prefix: str) -> subprocess.CompletedProcess:
    """`cmd` run in the root, its stdout captured, each line of its stderr
    written to sys.stderr at once after `prefix` (and kept, for the error
    message)."""
    with subprocess.Popen(cmd, cwd=engine.root(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) as p:
        kept: list[str] = []

        def forward():
            for line in p.stderr:
                kept.append(line)
                sys.stderr.write(prefix + line)
                sys.stderr.flush()

        reader = threading.Thread(target=forward, daemon=True)
        reader.start()
        stdout = p.stdout.read()
        p.wait()
        reader.join()
    return subprocess.CompletedProcess(cmd, p.returncode, stdout, "".join(kept))


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


class _Sections:
    """The section samples of branches' rows, for the question "does this
    periodic response lie on one of them": consecutive rows of a branch as
    pairs (and each row alone), indexed by period and parameter interval."""

    def __init__(self, param: str, rows: list[dict] = ()):
        self.param, self.rows, self.pairs = param, [], []
        self._arrays = None
        self.add(rows)

    def add(self, rows: list[dict]) -> None:
        first = len(self.rows)
        self.rows += rows
        rs = self.rows
        self.pairs += [(i, i + 1) for i in range(max(first - 1, 0), len(rs) - 1) if rs[i]["branch"] == rs[i + 1]["branch"]]
        self.pairs += [(i, i) for i in range(first, len(rs))]
        self._arrays = None

    def covers(self, p: float, period: int, impacts: float, samples, tolerance: float) -> bool:
        """Same period, same impacts per period (at either row of the pair),
        and every sample within `tolerance` of the pair's section interpolated
        linearly at `p`."""
        import numpy as np

        if self._arrays is None:
            rs, param = self.rows, self.param
            ia = np.array([a for a, _ in self.pairs], dtype=np.int64)
            ib = np.array([b for _, b in self.pairs], dtype=np.int64)
            x = np.array([r[param] for r in rs], dtype=float)
            periods = np.array([r["periods"] for r in rs], dtype=np.int64)
            self._arrays = (ia, ib, np.minimum(x[ia], x[ib]) if len(rs) else x, np.maximum(x[ia], x[ib]) if len(rs) else x,
                            periods[ia] if len(rs) else periods)
        ia, ib, lo, hi, periods = self._arrays
        for k in np.flatnonzero((periods == period) & (lo <= p) & (p <= hi)):
            a, b = self.rows[ia[k]], self.rows[ib[k]]
            if abs(a["impacts_per_period"] - impacts) > 0.01 and abs(b["impacts_per_period"] - impacts) > 0.01:
                continue
            w = 0.0 if b[self.param] == a[self.param] else (p - a[self.param]) / (b[self.param] - a[self.param])
            section = [(1 - w) * x + w * y for x, y in zip(a["section"], b["section"])]
            if all(min(abs(s - x) for x in section) <= tolerance for s in samples):
                return True
        return False


def _scale(rows: list[dict]) -> float:
    return max((abs(v) for r in rows for v in r["section"]), default=1.0) or 1.0


def _sweep_matches(orbits: Orbits, sweep: pa.Table, periods=(1, 2), tolerance: float = 1e-3):
    """The sweep's rows of period 1 or 2 (in its order) and whether each lies on a branch (on_branches)."""
    rows = orbits.branch.to_pylist()
    index, limit = _Sections(orbits.param, rows), tolerance * _scale(rows)
    candidates = [r for r in sweep.to_pylist() if not r.get("error") and r.get("period") in periods]
    return [(r, index.covers(r[orbits.param], r["period"], r["impacts_per_period"], r["poincare"], limit))
            for r in candidates]


def on_branches(orbits: Orbits, sweep: pa.Table, periods=(1, 2), tolerance: float = 1e-3):
    """Which of the sweep's period-1 and period-2 points lie on a continued
    branch: same period, same impacts per period, and every Poincare sample
    within `tolerance` (of the samples' range) of the branch's section,
    interpolated linearly between the branch's two points around the
    parameter value. Returns (matched, total, the unmatched parameter values)."""
    found = _sweep_matches(orbits, sweep, periods, tolerance)
    missed = [r[orbits.param] for r, on in found if not on]
    return len(found) - len(missed), len(found), missed


class _Branches:
    """Branches' rows for the continuation's own question "does this orbit
    lie on a branch found before" (`on_points` in
    src/orbits/continuation/mod.rs): consecutive rows of a branch as pairs,
    indexed by period and parameter interval."""

    def __init__(self, param: str):
        import numpy as np

        self.param = param
        self.lo, self.hi = np.empty(0), np.empty(0)
        self.periods = np.empty(0, dtype=np.int64)
        self.xa, self.xb = np.empty(0), np.empty(0)
        self.a, self.b = np.empty((0, 0)), np.empty((0, 0))

    def add(self, rows: list[dict]) -> None:
        """One branch's rows, in its order."""
        import numpy as np

        if len(rows) < 2:
            return
        x = np.array([r[self.param] for r in rows], dtype=float)
        states = np.array([r["state"] for r in rows], dtype=float)
        if self.a.size and states.shape[1] != self.a.shape[1]:
            raise OrbitsError("merge: the runs' states differ in length")
        self.lo = np.concatenate([self.lo, np.minimum(x[:-1], x[1:])])
        self.hi = np.concatenate([self.hi, np.maximum(x[:-1], x[1:])])
        self.periods = np.concatenate([self.periods, np.array([r["periods"] for r in rows[:-1]], dtype=np.int64)])
        self.xa, self.xb = np.concatenate([self.xa, x[:-1]]), np.concatenate([self.xb, x[1:]])
        self.a = states[:-1] if not self.a.size else np.concatenate([self.a, states[:-1]])
        self.b = states[1:] if not self.b.size else np.concatenate([self.b, states[1:]])

    def holds(self, row: dict, scale: float, tolerance: float = 1e-3) -> bool:
        """The same period, and the row's state within `tolerance` * `scale`
        (2-norm) of the state interpolated linearly, at its parameter value,
        between two consecutive rows of a branch around it."""
        import numpy as np

        p = row[self.param]
        k = np.flatnonzero((self.periods == row["periods"]) & (self.lo <= p) & (p <= self.hi))
        if not k.size:
            return False
        xa, xb = self.xa[k], self.xb[k]
        span = xb - xa
        w = np.clip(np.divide(p - xa, span, out=np.zeros_like(span), where=span != 0), 0.0, 1.0)[:, None]
        between = self.a[k] * (1 - w) + self.b[k] * w
        return bool((np.linalg.norm(between - np.asarray(row["state"]), axis=1) < tolerance * scale).any())


def _size(rows: list[dict]) -> float:
    """A branch's scale as the continuation's walk ends it: its largest
    orbit's size (the `norm` column, or the state's norm where that is 0)."""
    import numpy as np

    return max((r["norm"] or float(np.linalg.norm(r["state"])) for r in rows), default=1.0) or 1e-300


def merge(runs: list[Orbits], tolerance: float = 1e-3) -> tuple[Orbits, int]:
    """One diagram from continuations run apart, in the order given: each
    run's branches in their own order, numbered on, except a branch every
    row of which lies on a branch an earlier run kept (a run's own branches
    are as it found them; `_Branches.holds`, the continuation's own test
    whether a start lies on a branch: the same period, the state within
    `tolerance` of the state interpolated between two rows around it,
    scaled by the branch's largest orbit). The special points follow their
    branches. Returns the diagram (seconds and summary left to the caller)
    and how many branches were dropped."""
    param = runs[0].param
    earlier = _Branches(param)
    branch_parts, special_parts, dropped = [], [], 0
    for run in runs:
        if run.branch is None:
            continue
        rows, special = run.branch.to_pylist(), run.special.to_pylist()
        kept = []
        for b in sorted({r["branch"] for r in rows}):
            mine = [r for r in rows if r["branch"] == b]
            scale = _size(mine)
            if all(earlier.holds(r, scale, tolerance) for r in mine):
                dropped += 1
                continue
            new = len(branch_parts)
            branch_parts.append([dict(r, branch=new) for r in mine])
            special_parts += [dict(s, branch=new) for s in special if s["branch"] == b]
            kept.append(mine)
        for mine in kept:
            earlier.add(mine)
    flat = [r for part in branch_parts for r in part]
    tables = next(run for run in runs if run.branch is not None)
    branch = pa.Table.from_pylist(flat, schema=tables.branch.schema)
    special = pa.Table.from_pylist(special_parts, schema=tables.special.schema)
    return Orbits(branch, special, param, 0.0, ""), dropped


def describe(orbits: Orbits) -> str:
    """The command's own summary of a diagram: each branch, each special point."""
    param, lines = orbits.param, []
    rows, special = orbits.branch.to_pylist(), orbits.special.to_pylist()
    for b in sorted({r["branch"] for r in rows}):
        rs = [r for r in rows if r["branch"] == b]
        xs = [r[param] for r in rs]
        lines.append(f"branch {b}: period {rs[0]['periods']} T, {len(rs)} points ({sum(r['stable'] for r in rs)} stable), "
                     f"{param} = {min(xs)!r} .. {max(xs)!r}")
        lines += [f"  {s['type']} on branch {b} at {param} = {s[param]!r}: {s['note']}" for s in special if s["branch"] == b]
    return "".join(line + "\n" for line in lines)


def _continue(job: dict) -> Orbits:
    """One continuation, a Dask task: continue_orbits(**job). Where its first
    start finds no orbit (which ends `beamstop orbits`; a later one's is a
    note), again without it; with no start left, tables None and the
    summary says why."""
    job, notes = dict(job), []
    while True:
        try:
            run = continue_orbits(**job)
            run.summary = "".join(notes) + run.summary
            return run
        except OrbitsError as err:
            starts = job["start"] or []
            notes.append(f"  note: the start at {job['param']} = {starts[0] if starts else job['frm']!r}: {err}\n")
            if len(starts) < 2:
                return Orbits(None, None, job["param"], 0.0, "".join(notes))
            job["start"] = starts[1:]


def pieces(missed: list[float], starts: list[float], count: int = PIECES) -> list[list[float]]:
    """cover's division of its restarts: `count` runs (fewer if there are
    fewer `missed` points), each with as many of the missed points as the
    others, in the parameter's order. Returns each run's starts: `starts`
    (the first run's), then its share of the missed points in order."""
    missed = sorted(missed)
    n = max(1, min(count, len(missed)))
    shares = [missed[i * len(missed) // n:(i + 1) * len(missed) // n] for i in range(n)]
    return [list(starts) + [p for p in share if p not in starts] for share in shares]


def cover(scene, param: str, frm: float, to: float, sweep: pa.Table, *, out: str | Path, start=None,
          transient: int = 100, max_branches: int = 200, pieces_count: int = PIECES, client=None, progress: bool = False,
          **kw) -> Orbits:
    """Continues from `start` (default `frm`; at most 8 branches), then
    again from `start` and every period-1 or period-2 point of `sweep` not
    yet on a branch as a start of its own (each from a transient of
    `transient` periods, the sweep's own discard, so that it settles where
    the sweep did; a start on a branch its run found before starts none;
    at most `max_branches` branches per run). Those restarts are shared out
    among `pieces_count` independent runs (`pieces`: as many missed points
    each, in the parameter's order), each over the whole range with the
    whole range's steps and `start` first, on the Dask `client`'s workers
    (None: one after the other here). The tables are merged in a fixed
    order whatever order the runs end in (`merge`: the runs in the order of
    their shares, a branch lying on one an earlier run kept dropped), so
    they depend on `pieces_count`, never on the workers. One piece is the
    run of before alone. `progress`: each run's progress lines on stderr,
    after "cover first:" or "cover K/N:". DIR/runs/first and DIR/runs/K
    hold the first run's and run K's CSVs (rows written as each branch
    ends); DIR/branch.parquet and DIR/special.parquet the merged tables.
    Returns the merged diagram (the first run's, if it covers the sweep
    already); `seconds` is the wall time of both stages."""
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    lo, hi = min(frm, to), max(frm, to)
    starts = [] if start is None else [start] if isinstance(start, (int, float)) else list(start)
    base = dict(scene=str(Path(scene).resolve()), param=param, frm=frm, to=to, transient=transient,
                exe=str(engine.binary().resolve()), **kw)
    began = time.perf_counter()
    first = continue_orbits(out=out / "runs" / "first", start=starts or None, progress="cover first: " if progress else None,
                            **base)
    missed = [p for p in on_branches(first, sweep)[2] if lo <= p <= hi]
    if not missed:
        first.seconds = time.perf_counter() - began
        pq.write_table(first.branch, out / "branch.parquet")
        pq.write_table(first.special, out / "special.parquet")
        return first
    shares = pieces(missed, starts or [frm], pieces_count)
    n = len(shares)
    jobs = [dict(base, start=s, max_branches=max_branches, out=str(out / "runs" / f"{k:03d}"),
                 progress=f"cover {k + 1}/{n}: " if progress else None) for k, s in enumerate(shares)]
    done = 0

    def ended(k: int, run: Orbits) -> None:
        nonlocal done
        done += 1
        if progress:
            print(f"cover: run {k + 1}/{n} done ({done} of {n}): "
                  f"{0 if run.branch is None else len(set(run.branch.column('branch').to_pylist()))} branches, "
                  f"{run.seconds:.1f} s", file=sys.stderr, flush=True)

    if client is None:
        runs = []
        for k, job in enumerate(jobs):
            runs.append(_continue(job))
            ended(k, runs[-1])
    else:
        from distributed import as_completed

        futures = [client.submit(_continue, job, pure=False) for job in jobs]
        for future in as_completed(futures):
            ended(futures.index(future), future.result())
        runs = [f.result() for f in futures]  # the shares' order, not the order they ended in
    merged, dropped = merge(runs)
    merged.seconds = time.perf_counter() - began
    pq.write_table(merged.branch, out / "branch.parquet")
    pq.write_table(merged.special, out / "special.parquet")
    notes = [f"  note (run {k + 1}/{n}): {line.strip().removeprefix('note: ')}"
             for k, run in enumerate(runs) for line in run.summary.splitlines() if line.strip().startswith("note:")]
    merged.summary = (describe(merged) + "".join(line + "\n" for line in notes)
                      + f"cover: the first run and {len(missed)} starts in {n} run(s) on "
                      + (f"{_workers(client)} Dask worker(s)" if client is not None else "this process")
                      + f": {len(merged.branch)} points on {len(set(merged.branch.column('branch').to_pylist()))} branches"
                      + f" ({dropped} lying on one kept before dropped) in {merged.seconds:.1f} s; {out}\n")
    return merged


def _workers(client) -> int:
    from .sweep.engine import worker_count
    return worker_count(client)


def sweep_spec(scene: str | Path, param: str, frm: str, to: str, points: int, sets: list[str], ties: list[str],
               discard: float = 100, record: int = 50):
    """The brute-force sweep of the same range (`scripts/sweep` on the
    scene's FMU in target/fmu/): `points` values, the same --set values,
    each --tie as a --set expression; checked before any worker starts."""
    from .sweep import spec as spec_mod
    from .sweep.fmu import read_fmu

    name = json.loads(Path(scene).read_text()).get("name")
    fmu = ROOT / "target" / "fmu" / f"{name}.fmu"
    if not fmu.exists():
        raise OrbitsError(f"--sweep-points: {fmu} is missing: package the scene first "
                          f"(target/release/beamstop package {scene}), or give a sweep with --sweep DIR")
    set_exprs = list(sets) + [t.replace("^", "**") for t in ties]
    return spec_mod.build(read_fmu(fmu), [f"{param}={frm}:{to}:{points}"], set_exprs, discard, record)


def sweep_for(spec, out: Path, client) -> pa.Table:
    """Runs the sweep `spec` (sweep_spec) on the Dask `client`. Returns its
    table (also in out/points.parquet)."""
    from .sweep.engine import run_sweep
    from .sweep.store import read_points

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
    ap.add_argument("--max-branches", type=int, help="8; with --cover, per run: 200")
    ap.add_argument("--transient", type=int, default=200, help="forcing periods simulated before the first orbit")
    ap.add_argument("--max-period", type=int, default=8)
    ap.add_argument("--sweep", help="a scripts/sweep output directory of the same parameter, drawn under the branches")
    ap.add_argument("--sweep-points", type=int, metavar="N",
                    help="run the brute-force sweep of the same range first (N values; its FMU from target/fmu/), "
                         "to DIR/sweep, and draw the branches over it")
    ap.add_argument("--cover", action="store_true",
                    help="with --sweep: start again from every period-1 or period-2 sweep point on no branch "
                         "(in --pieces runs on Dask, merged)")
    ap.add_argument("--pieces", type=int, default=PIECES, metavar="K",
                    help=f"--cover's restarts shared out among K runs over the whole range, merged "
                         f"(default {PIECES}; 1: the single run, no cluster; more took longer on 2 cores: docs/orbits.md)")
    ap.add_argument("--scheduler", metavar="ADDRESS", help="for --cover --pieces K and --sweep-points: a running dask scheduler "
                    "(tcp://host:8786); default: a local cluster")
    ap.add_argument("--workers", type=int, metavar="N", help="local worker processes (default: one per core)")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    from .sweep.engine import dask_client

    try:
        name, sep, ends = a.param.partition("=")
        frm, sep2, to = ends.partition(":")
        if not sep or not sep2:
            raise OrbitsError(f"--param {a.param}: NAME=FROM:TO")
        value = lambda text, field: Expression(text, field, set()).value({})  # noqa: E731
        sets = {k: value(v, f"--set {k}") for k, v in _pairs(a.set, "--set").items()}
        if a.sweep and a.sweep_points:
            raise OrbitsError("--sweep DIR and --sweep-points N: one or the other")
        if a.cover and not (a.sweep or a.sweep_points):
            raise OrbitsError("--cover needs --sweep DIR or --sweep-points N")
        if a.workers is not None and a.workers < 1:
            raise OrbitsError(f"--workers: {a.workers}; allowed: 1 or more")
        if a.pieces < 1:
            raise OrbitsError(f"--pieces: {a.pieces}; allowed: 1 or more")
        common = dict(out=a.out, start=[value(s, "--start") for s in a.start] or None, sets=sets, ties=a.tie,
                      points=a.points, max_period=a.max_period)
        lo, hi = value(frm, "--param FROM"), value(to, "--param TO")
        spec = sweep_spec(a.scene, name, frm, to, a.sweep_points, a.set, a.tie) if a.sweep_points else None
        # one --cover run needs no cluster: it runs here, its progress on this stderr
        with (dask_client(a.scheduler, a.workers) if (a.cover and a.pieces > 1) or a.sweep_points
              else nullcontext()) as client:
            if spec is not None:
                sweep = sweep_for(spec, Path(a.out) / "sweep", client)
            else:
                sweep = pq.read_table(Path(a.sweep) / "points.parquet") if a.sweep else None
            if a.cover:
                discard = json.loads((sweep.schema.metadata or {}).get(b"beamstop.sweep", b"{}")).get("settings", {}).get("discard_periods")
                orbits = cover(a.scene, name, lo, hi, sweep, transient=int(discard or a.transient),
                               max_branches=a.max_branches or 200, pieces_count=a.pieces, client=client,
                               progress=True, **common)
            else:
                orbits = continue_orbits(a.scene, name, lo, hi, transient=a.transient, max_branches=a.max_branches or 8,
                                         progress="", **common)
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
