"""What the work-precision studies against the compiled DOP853 peer and
scipy (hertz, rotating_peers) have in common: the solvers and their plot
styles, the matching of contact onsets, the fastest clean run within an
error bound, the budgeted scipy ladder, the command line and the
work-precision panel."""
from __future__ import annotations

import math
import statistics
import time

from .common import log, out_dir

SOLVERS = ("beamstop", "dop853", "dop853cap", "scipy-Radau", "scipy-BDF")
STYLE = {
    "beamstop": dict(color="C3", marker="o"),
    "dop853": dict(color="C0", marker="s"),
    "dop853cap": dict(color="C2", marker="D"),
    "scipy-Radau": dict(color="C1", marker="^"),
    "scipy-BDF": dict(color="C4", marker="v"),
}
MATCH = 1e-5  # s: an onset farther than this from every reference onset is missed / extra
LONG_RUN = 2.0  # s: scipy runs longer than this are timed once


def match_onsets(reference, run) -> tuple[int, int, float]:
    """(missed, extra, largest difference of the matched onsets): a reference
    onset with no run onset within MATCH is missed, a run onset with no
    reference onset within MATCH is extra."""
    def nearest(t, s):
        return min((abs(x - t) for x in s), default=math.inf)
    missed = sum(1 for t in reference if nearest(t, run) > MATCH)
    extra = sum(1 for t in run if nearest(t, reference) > MATCH)
    dts = [nearest(t, run) for t in reference if nearest(t, run) <= MATCH]
    return missed, extra, max(dts, default=math.nan)


def clean(r: dict, err: str) -> bool:
    """No onset missed or extra, and a finite error `r[err]` (numbers or CSV strings)."""
    return int(r["missed"]) == 0 and int(r["extra"]) == 0 and math.isfinite(float(r[err]))


def fastest_within(rows, solver, bound, err: str):
    """The fastest timed run of `solver` that is clean with `r[err]` <= bound."""
    ok = [r for r in rows if r["solver"] == solver and r.get("ms") not in (None, "") and clean(r, err)
          and float(r[err]) <= bound]
    return min(ok, key=lambda r: float(r["ms"]), default=None)


def scipy_ladder(run, tols, reps: int, budget: float, skipped: list, stat=statistics.median,
                 methods=("Radau", "BDF")):
    """The scipy sweep of a report against the compiled peer (hertz,
    rotating_peers): for each of `methods` (Radau, then BDF; a smoke run
    passes Radau alone, the same code path), each rtol of `tols` run `reps`
    times by `run(method, rtol)` (once more only while a run takes at most
    LONG_RUN), a method stopped at a tolerance whose predicted time (the
    last time times the last growth factor) would exceed its half of
    `budget` seconds; skipped and failed (RuntimeError) settings are
    appended to `skipped`. Yields (method, rtol, the first run's result,
    the run times [s], 1e3 * stat(run times) [ms])."""
    for method in methods:
        spent, times = 0.0, []
        for rtol in tols:
            if len(times) >= 2:
                predicted = times[-1] * max(times[-1] / times[-2], 1.0)
                if spent + predicted > 0.5 * budget:
                    skipped.append(f"scipy-{method} rtol {rtol:.0e} (predicted {predicted:.0f} s; "
                                   f"{spent:.0f} s of its {0.5 * budget:.0f} s share spent)")
                    log(f"scipy {method} {rtol:.0e}: skipped, predicted {predicted:.0f} s")
                    continue
            el, first = [], None
            try:
                for _ in range(reps):
                    t0 = time.perf_counter()
                    res = run(method, rtol)
                    el.append(time.perf_counter() - t0)
                    first = first or res
                    if el[-1] > LONG_RUN:
                        break
            except RuntimeError as e:
                log(f"scipy {method} {rtol:.0e}: failed: {e}")
                skipped.append(f"scipy-{method} rtol {rtol:.0e} (failed: {e})")
                continue
            spent += sum(el)
            ms = 1e3 * stat(el)
            times.append(ms / 1e3)
            yield method, rtol, first, el, ms


def peer_arguments(argv, doc: str, name: str, reps: int, budget: float):
    """The command line of a report against the compiled peer and scipy
    (hertz, rotating_peers), with its defaults resolved: `out` (a Path),
    `reps` and `scipy_budget` (smaller with --quick)."""
    import argparse

    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", help=f"output folder (default report/{name}, target/report-quick/{name} with --quick)")
    ap.add_argument("--reps", type=int, help=f"timed runs per setting (default {reps}, 1 with --quick)")
    ap.add_argument("--scipy-budget", type=float,
                    help=f"seconds for the scipy sweep (default {budget:g}, 10 with --quick)")
    ap.add_argument("--work-dir", help="keep the intermediate files here (default: a temporary directory)")
    ap.add_argument("--summary-only", action="store_true",
                    help="rewrite the CSV, PNG and markdown from --work-dir, running nothing")
    ap.add_argument("--quick", action="store_true",
                    help="a smoke run: one timed run, one scipy tolerance; not the report's numbers")
    args = ap.parse_args(argv)
    args.out = out_dir(args.out, name, args.quick)
    if args.reps is None:
        args.reps = 1 if args.quick else reps
    if args.scipy_budget is None:
        args.scipy_budget = 10.0 if args.quick else budget
    if args.summary_only and not args.work_dir:
        ap.error("--summary-only needs --work-dir")
    return args


def work_precision_panel(ax, rows, key: str, err: str, tol: str) -> None:
    """Error `r[key]` against run time, one line per solver, log-log: each
    point labelled with its tolerance `r[tol]`, ringed where the run is not
    clean (an onset missed or extra, or no finite `r[err]`)."""
    for s in SOLVERS:
        pts = [r for r in rows if r["solver"] == s and r.get("ms") not in (None, "") and float(r[key]) > 0]
        if not pts:
            continue
        pts.sort(key=lambda r: -float(r[tol]))
        x = [float(r["ms"]) for r in pts]
        y = [float(r[key]) for r in pts]
        ax.plot(x, y, label=s, lw=1.3, ms=5, **STYLE[s])
        for r, xi, yi in zip(pts, x, y):
            if not clean(r, err):
                ax.plot(xi, yi, "o", mfc="none", mec="k", ms=11, mew=1.2)
            ax.annotate(f"{float(r[tol]):.0e}".replace("e-0", "e-"), (xi, yi), textcoords="offset points",
                        xytext=(4, 3), fontsize=6, color=STYLE[s]["color"])
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)


def equal_error_table(rows, bounds, err: str, describe) -> tuple[dict, list[list]]:
    """The fastest clean run of each solver within each bound on `r[err]`,
    and its time over beamstop's within the same bound: (beamstop's runs by
    bound, the table's rows: solver, then `describe(run)` and the ratio per
    bound)."""
    bs = {b: fastest_within(rows, "beamstop", b, err) for b in bounds}
    table = []
    for s in SOLVERS:
        cells = [s]
        for b in bounds:
            r = fastest_within(rows, s, b, err)
            if r is None:
                cells += ["not reached", "-"]
            else:
                ratio = float(r["ms"]) / float(bs[b]["ms"]) if bs[b] else math.nan
                cells += [describe(r), f"{ratio:.3g}"]
        table.append(cells)
    return bs, table
