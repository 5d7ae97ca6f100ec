#!/usr/bin/env python3
"""The project's main job, run after packaging (scripts/main):

1. validate every FMU in target/fmu (FMI 2.0) and target/fmu3 (FMI 3.0)
   with fmpy,
2. simulate target/fmu/PinnedBeamStop.fmu over its default experiment
   (output interval = the default step size), and its FMI 3.0 twin with
   early return and event mode (a sample just before and just after every
   event, at the event's own time),
3. write target/results/PinnedBeamStop_fmpy.csv, PinnedBeamStop_fmi3.csv
   and a plot target/results/PinnedBeamStop.png (w_stop over time,
   sticking intervals shaded, impacts marked at the FMI 3.0 samples),
4. print a short summary.

Exit status 1 if a validation problem is found or the simulation fails.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fmpy import read_model_description, simulate_fmu  # noqa: E402
from fmpy.util import write_csv  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FMU_DIR = ROOT / "target" / "fmu"
FMU3_DIR = ROOT / "target" / "fmu3"
FMU = FMU_DIR / "PinnedBeamStop.fmu"
FMU3 = FMU3_DIR / "PinnedBeamStop.fmu"
RESULTS = ROOT / "target" / "results"

EVENT = re.compile(r"t = ([-+0-9.eE]+): (impact|sticking starts|release)")


def validate_all() -> bool:
    fmus = sorted(FMU_DIR.glob("*.fmu")) + sorted(FMU3_DIR.glob("*.fmu"))
    if not fmus:
        print(f"no FMU in {FMU_DIR}: run `cargo run --release -- package` (and `-- package --fmi3`) first", file=sys.stderr)
        return False
    ok = True
    for fmu in fmus:
        problems = validate_fmu(str(fmu))
        if problems:
            ok = False
            print(f"{fmu.relative_to(ROOT)}: {len(problems)} problem(s)")
            for p in problems:
                print(f"  - {p}")
        else:
            print(f"{fmu.relative_to(ROOT)}: valid")
    return ok


def sticking_intervals(events, sticking, time, start, stop):
    """Exact [begin, end] intervals from the logged events; if none were
    logged, from the sampled 'sticking' output."""
    intervals = []
    begin = None
    for t, kind in events:
        if kind == "sticking starts" and begin is None:
            begin = t
        elif kind == "release" and begin is not None:
            intervals.append((begin, t))
            begin = None
    if begin is not None:
        intervals.append((begin, stop))
    if intervals or not np.any(sticking):
        return intervals, "events"
    # fallback: sample-based (resolution of the output interval)
    s = np.asarray(sticking, dtype=bool)
    edges = np.flatnonzero(np.diff(s.astype(int)))
    idx = [0] if s[0] else []
    for e in edges:
        idx.append(e + 1)
    if s[-1]:
        idx.append(len(s) - 1)
    return [(float(time[a]), float(time[b])) for a, b in zip(idx[0::2], idx[1::2])], "samples"


def main(argv: list[str]) -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=RESULTS, help=f"output directory (default {RESULTS})")
    args = parser.parse_args(argv)
    results_dir = args.results.resolve()

    ok = validate_all()
    if not FMU.is_file():
        print(f"{FMU} not found", file=sys.stderr)
        return 1

    md = read_model_description(str(FMU))
    ex = md.defaultExperiment
    start, stop, step = float(ex.startTime), float(ex.stopTime), float(ex.stepSize)

    messages: list[tuple[int, str, str]] = []

    def logger(component, instance_name, status, category, message):
        messages.append((int(status), category.decode("utf-8", "replace"), message.decode("utf-8", "replace")))

    result = simulate_fmu(str(FMU), start_time=start, stop_time=stop, output_interval=step,
                          debug_logging=True, logger=logger)

    for status, category, text in messages:
        if status >= 2:  # discard, error, fatal
            print(f"FMU [{category}] {text}", file=sys.stderr)
            ok = False

    # FMI 3.0: early return at every event, the change made in event mode.
    result3 = simulate_fmu(str(FMU3), start_time=start, stop_time=stop, output_interval=step,
                           early_return_allowed=True, use_event_mode=True)
    t3 = result3["time"]
    at_event = np.flatnonzero(t3[1:] == t3[:-1])
    impacts3 = [(float(t3[i]), float(result3["w_stop"][i])) for i in at_event if result3["impacts"][i + 1] > result3["impacts"][i]]

    results_dir.mkdir(parents=True, exist_ok=True)
    csv_path = results_dir / "PinnedBeamStop_fmpy.csv"
    csv3_path = results_dir / "PinnedBeamStop_fmi3.csv"
    png_path = results_dir / "PinnedBeamStop.png"
    write_csv(str(csv_path), result)
    write_csv(str(csv3_path), result3)

    events = []
    for _, category, text in messages:
        if category == "logEvents":
            m = EVENT.match(text)
            if m:
                events.append((float(m.group(1)), m.group(2)))
    impact_times = [t for t, k in events if k == "impact"]

    t = result["time"]
    w = result["w_stop"]
    intervals, source = sticking_intervals(events, result["sticking"], t, start, stop)
    stuck_time = sum(b - a for a, b in intervals)
    impacts = int(result["impacts"][-1])
    d = float(next(v.start for v in md.modelVariables if v.name == "d"))

    fig, (ax, ax2) = plt.subplots(2, 1, sharex=True, figsize=(10, 6), height_ratios=[3, 1])
    for k, (a, b) in enumerate(intervals):
        ax.axvspan(a, b, color="tab:orange", alpha=0.25, lw=0, label="sticking" if k == 0 else None)
        ax2.axvspan(a, b, color="tab:orange", alpha=0.25, lw=0)
    ax.plot(t, w, color="tab:blue", lw=1.0, label="w_stop")
    ax.axhline(d, color="k", lw=0.8, ls="--", label=f"stop (d = {d:g})")
    if impacts3:
        ax.plot(*zip(*impacts3), ".", color="tab:red", ms=4, label="impacts (FMI 3.0 early return)")
    ax.set_ylabel("w_stop")
    ax.set_title(f"{md.modelName}: default experiment, {impacts} impacts, sticking {stuck_time:.3f} of {stop - start:g}")
    ax.legend(loc="lower left", fontsize="small")
    ax2.plot(t, result["lambda"], color="tab:green", lw=1.0)
    ax2.set_ylabel("lambda")
    ax2.set_xlabel("time")
    ax2.set_xlim(start, stop)
    fig.tight_layout()
    fig.savefig(png_path, dpi=120)
    plt.close(fig)

    print(f"FMU:          {FMU}")
    print(f"experiment:   t = {start:g} .. {stop:g}, output interval {step:g} ({len(result)} points)")
    print(f"impacts:      {impacts}")
    exact = len(impacts3) == len(impact_times) and all(a == b for (a, _), b in zip(impacts3, impact_times))
    print(f"FMI 3.0:      {len(impacts3)} impacts returned early at their own times "
          f"({'equal to' if exact else 'DIFFERENT from'} the FMI 2.0 event log), {len(result3)} samples")
    ok = ok and exact
    print(f"sticking:     {stuck_time:.6f} time units in {len(intervals)} interval(s) (from {source})")
    for a, b in intervals:
        print(f"              [{a:.6f}, {b:.6f}]")
    print(f"max w_stop:   {float(np.max(w)):.3e} (stop at d = {d:g})")
    print(f"results:      {csv_path}, {csv3_path}")
    print(f"plot:         {png_path}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
