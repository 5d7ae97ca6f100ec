"""Command line: python -m beamstop_tools.sweep FMU --param NAME=FROM:TO:POINTS ... (scripts/sweep)."""
from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from .errors import SweepError

EPILOG = """examples:
  scripts/sweep target/fmu/PinnedBeamStop.fmu --param d=0:1.8:181 \\
      --set F=72 --set omega='0.7*pi**2' --set eps=1e-3 --discard 100 --record 100 --out target/sweeps/gap
  scripts/sweep target/fmu/SpringStopSoft.fmu --param shaker.omega=80:130:101 \\
      --set 'shaker.amplitude=-2e-4*shaker.omega**2' --continuation both --discard 200 --record 20 --out target/sweeps/soft
"""


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="scripts/sweep", description=(
        "Sweep one or two parameters of a beamstop FMU on Dask workers: per point the Poincare samples "
        "(stroboscopic at the forcing period), impacts per period, sticking, peak of an output and the "
        "period of the response; DIR/points.parquet and PNG plots. An interrupted run resumes when the "
        "same command is run again."), epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("fmu", help="the .fmu file (scripts/main builds them into target/fmu/)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=FROM:TO:POINTS",
                   help="a swept parameter (once or twice: a grid); FROM and TO may be expressions (0.5*pi**2)")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="a parameter held at VALUE, a number or an expression of the other parameters "
                        "(shaker.amplitude=-2e-4*shaker.omega**2); repeatable")
    p.add_argument("--discard", type=float, required=True, metavar="PERIODS",
                   help="forcing periods skipped before recording (one fmi2DoStep)")
    p.add_argument("--record", type=int, required=True, metavar="PERIODS", help="forcing periods recorded")
    p.add_argument("--samples-per-period", type=int, default=16, metavar="N",
                   help="samples per recorded period (sample 0 of each is the Poincare sample); default 16")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (points.parquet, plots, parts/)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a running dask scheduler (tcp://host:8786); "
                   "default: a local cluster")
    p.add_argument("--workers", type=int, metavar="N", help="local worker processes (default: one per core)")
    p.add_argument("--forcing", metavar="NAME", help="the parameter holding the forcing frequency "
                   "(default: the FMU's first load frequency); the period is 2 pi / its value")
    p.add_argument("--output", metavar="NAME", help="the output for Poincare samples, peak and maxima "
                   "(default: the first stop's displacement)")
    p.add_argument("--rate", metavar="NAME", help="the output's time derivative, for the period test and "
                   "the peak's interpolation ('none' to go without; default: the first stop's velocity)")
    p.add_argument("--continuation", default="none", choices=["none", "up", "down", "both"],
                   help="start each point from the previous point's state along the first --param "
                        "(a tunable parameter), sweeping up, down or both; default none (every point from rest)")
    p.add_argument("--period-tol", type=float, default=1e-4, metavar="TOL",
                   help="the period test's tolerance, relative to the recorded range (default 1e-4)")
    p.add_argument("--max-period", type=int, default=16, metavar="P", help="longest period looked for (default 16)")
    p.add_argument("--points-per-task", type=int, metavar="N", help="points per Dask task (default: automatic)")
    p.add_argument("--restart", action="store_true", help="discard the finished parts in DIR and start over")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-plots", action="store_true", help="no PNGs")
    return p


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args = parser().parse_args(argv)
    from . import spec as spec_mod
    from .engine import dask_client, run_sweep
    from .fmu import read_fmu

    try:
        info = read_fmu(args.fmu)
        spec = spec_mod.build(info, args.param, args.set, args.discard, args.record, args.samples_per_period,
                              args.forcing, args.output, args.rate, args.continuation, args.period_tol,
                              args.max_period)
        if args.points_per_task is not None and args.points_per_task < 1:
            raise SweepError(f"--points-per-task: {args.points_per_task}; allowed: 1 or more")
        if args.workers is not None and args.workers < 1:
            raise SweepError(f"--workers: {args.workers}; allowed: 1 or more")
        out = Path(args.out)
        with dask_client(args.scheduler, args.workers) as client:
            meta = run_sweep(spec, out, client, args.points_per_task, args.restart, not args.no_progress,
                             "scripts/sweep " + shlex.join(argv))
        if not args.no_plots:
            from .plots import plot_sweep
            for png in plot_sweep(out / "points.parquet"):
                print(f"wrote {png}")
    except SweepError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\ninterrupted: the finished points are kept in {args.out}/parts; run the same command "
              f"again to resume", file=sys.stderr)
        return 130
    n, wall = meta["points_computed"], meta["wall_seconds"]
    print(f"wrote {out / 'points.parquet'}: {n} points computed in {wall:.1f} s on {meta['workers']} worker(s)"
          + (f" ({n / wall:.1f} points/s)" if n and wall > 0 else "")
          + (f"; {meta['failed_points']} point(s) failed (column 'error')" if meta["failed_points"] else ""))
    return 0
