"""Run time against the number of modes (GitHub issue 10, item 5).

`python -m beamstop_tools.report.scaling [--run] [--quick] [--out DIR]` reads
report/scaling/scaling.csv (written by `cargo run --release --example scaling
-- --csv FILE`; `--run` runs it first, about a minute, and writes the CSV to
--out) and writes report/scaling/scaling.png (log-log run time against N,
rigid and spring stop, with slope-1 and slope-2 guides) and
report/scaling/summary.md (the table and the fitted slopes between 32 and
500 modes). `--quick` writes to target/report-quick/scaling and runs only
N = 4, 8, 32, 64 (a few seconds).
"""
from __future__ import annotations

import argparse
import csv
import math
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .. import engine  # noqa: E402
from .common import REPORT, out_dir  # noqa: E402

OUT = REPORT / "scaling"
QUICK_MODES = ["4", "8", "32", "64"]
COMMAND = "cargo run --release --example scaling -- --csv report/scaling/scaling.csv"
LABELS = {
    "rigid": "rigid stop: S2, pinned beam, 60 periods (impacts, chatter, sticking)",
    "spring": "spring stop: the RMTM paper's cantilever, hard stop, 60 periods",
}


def read(path: pathlib.Path) -> list[dict]:
    with path.open() as f:
        return [
            {**r, "modes": int(r["modes"]), "build_s": float(r["build_s"]), "run_s": float(r["run_s"]),
             "first_s": float(r.get("first_s") or r["run_s"]),
             "probes": int(r["probes"]), "events": int(r["events"]), "contacts": int(r["contacts"])}
            for r in csv.DictReader(f)
        ]


def slope(rows: list[dict], lo: int, hi: int, key: str = "run_s") -> float | None:
    """Least-squares slope of log(time) against log(N) over lo <= N <= hi."""
    pts = [(math.log(r["modes"]), math.log(r[key])) for r in rows if lo <= r["modes"] <= hi and r[key] > 0]
    if len(pts) < 2:
        return None
    mx = sum(x for x, _ in pts) / len(pts)
    my = sum(y for _, y in pts) / len(pts)
    sxx = sum((x - mx) ** 2 for x, _ in pts)
    return sum((x - mx) * (y - my) for x, y in pts) / sxx


def plot(rows: list[dict], path: pathlib.Path) -> None:
    fig, ax = plt.subplots(figsize=(7.5, 5))
    for case, style in (("rigid", dict(color="black", marker="o")), ("spring", dict(color="tab:red", marker="s"))):
        rs = sorted((r for r in rows if r["case"] == case), key=lambda r: r["modes"])
        if not rs:
            continue
        ax.loglog([r["modes"] for r in rs], [r["run_s"] for r in rs], label=LABELS[case], **style)
        ax.loglog([r["modes"] for r in rs], [r["first_s"] for r in rs], linestyle="--",
                  color=style["color"], linewidth=0.8, label=f"{case}: first run (with the contact decompositions)")
        ax.loglog([r["modes"] for r in rs], [r["build_s"] for r in rs], linestyle=":", color=style["color"],
                  label=f"{case}: model build (modes, projections)")
    # Guides through the rigid case at N = 32.
    anchor = next((r for r in rows if r["case"] == "rigid" and r["modes"] == 32), None)
    if anchor:
        ns = [32, 500]
        for p, ls in ((1, "--"), (2, "-.")):
            ax.loglog(ns, [anchor["run_s"] * (n / 32) ** p for n in ns], ls, color="gray", linewidth=0.8,
                      label=f"slope {p}")
    ax.axhline(0.5, color="tab:green", linewidth=0.6)
    ax.axhline(10.0, color="tab:green", linewidth=0.6)
    ax.set_xlabel("number of modes N")
    ax.set_ylabel("run time [s] (minimum over repeats)")
    ax.set_title("beamstop: run time against the number of modes")
    ax.grid(True, which="both", linewidth=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def summary(rows: list[dict]) -> str:
    lines = [
        "# Run time against the number of modes",
        "",
        f"Command: `{COMMAND}` then `python -m beamstop_tools.report.scaling` (or `python -m beamstop_tools.report.scaling --run`).",
        "Run time = `Simulation::new` + `advance_to` over 60 forcing periods, minimum over repeats "
        "(at least 3 and 0.3 s below 3 s per run); first run = the first of those repeats, which also decomposes "
        "the contact phases' coupled systems (the model keeps them for its later simulations, so the repeats after "
        "it do not pay for them); build = `Model::build` (modes and projections, once per FMU instance).",
        "",
        "![run time against N](scaling.png)",
        "",
        "| case | N | run [ms] | first run [ms] | build [ms] | event-search points | events | contacts | us per point |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in sorted(rows, key=lambda r: (r["case"], r["modes"])):
        lines.append(
            f"| {r['case']} | {r['modes']} | {r['run_s'] * 1e3:.3f} | {r['first_s'] * 1e3:.3f} | "
            f"{r['build_s'] * 1e3:.2f} | {r['probes']} | "
            f"{r['events']} | {r['contacts']} | {r['run_s'] * 1e6 / max(r['probes'], 1):.2f} |"
        )
    lines.append("")
    for case in ("rigid", "spring"):
        rs = [r for r in rows if r["case"] == case]
        s = slope(rs, 32, 500)
        if s is not None:
            lines.append(f"- {case}: fitted slope of log(run time) against log(N) between 32 and 500 modes: {s:.2f}")
        s_first = slope(rs, 32, 500, "first_s")
        if s_first is not None:
            lines.append(f"- {case}: the same for the first run: {s_first:.2f}")
    lines.append("")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", action="store_true", help="run the benchmark first (about 1 minute)")
    parser.add_argument("--quick", action="store_true",
                        help=f"write to target/report-quick/scaling; with --run only N = {', '.join(QUICK_MODES)}")
    parser.add_argument("--csv", type=pathlib.Path,
                        help="the benchmark's CSV (default: OUT/scaling.csv with --run, else report/scaling/scaling.csv)")
    parser.add_argument("--out", type=pathlib.Path)
    args = parser.parse_args(argv)
    args.out = out_dir(args.out, "scaling", args.quick)
    args.csv = args.csv or (args.out if args.run else OUT) / "scaling.csv"
    args.out.mkdir(parents=True, exist_ok=True)
    if args.run:
        engine.example("scaling", ["--csv", args.csv] + (QUICK_MODES if args.quick else []))
    rows = read(args.csv)
    plot(rows, args.out / "scaling.png")
    (args.out / "summary.md").write_text(summary(rows))
    print((args.out / "summary.md").read_text())


if __name__ == "__main__":
    main()
