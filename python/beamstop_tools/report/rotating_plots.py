"""Figures of the rotating hub beam report (GitHub issue 9).

`python -m beamstop_tools.report.rotating_plots [--dir report/rotating] [--out DIR] [--quick]`
reads the CSVs that `cargo run --release --example rotating_report` writes
(into report/rotating, committed) and draws, into --out (default: --dir;
with --quick target/report-quick/rotating):

- `dwz_history.png`: the DWZ scene's contact force, hub speed and tip
  deflection over the first 25 ms (contacts counted from the force);
- `modes.png`: the first contact's peak force against the number of modes,
  with the 1 % band around the largest N and DWZ's N = 6 marked;
- `spin_up.png`: the Kane-Ryan-Banerjee spin-up, tip deflection of the
  zeroth-order model (no geometric stiffening) against the first-order one.
"""
from __future__ import annotations

import argparse
import csv
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .common import QUICK, REPORT  # noqa: E402



def read(path: pathlib.Path) -> dict[str, list[float]]:
    with path.open() as f:
        rows = list(csv.DictReader(f))
    # An empty cell (the zeroth-order spin-up after it diverged) is NaN.
    return {k: [float(r[k]) if r[k] else float("nan") for r in rows] for k in rows[0]}


def contacts(force: list[float]) -> int:
    """Contact onsets in a sampled force history (zero to positive)."""
    return sum(1 for a, b in zip(force, force[1:]) if a <= 0.0 < b)


def dwz_history(d: pathlib.Path, out: pathlib.Path) -> dict:
    h = read(d / "dwz_history.csv")
    t_ms = [t * 1e3 for t in h["t"]]
    end = next((i for i, t in enumerate(t_ms) if t > 25.0), len(t_ms))
    n = contacts(h["force"])
    fig, axes = plt.subplots(3, 1, figsize=(7.5, 7), sharex=True)
    axes[0].plot(t_ms[:end], h["force"][:end], color="tab:red", linewidth=0.8)
    axes[0].set_ylabel("contact force [N]")
    axes[0].set_title(f"DWZ scene (6 modes): {n} contacts (force sampled every 10 us)")
    axes[1].plot(t_ms[:end], h["theta_dot"][:end], color="black", linewidth=0.8)
    axes[1].set_ylabel("hub speed theta' [rad/s]")
    axes[2].plot(t_ms[:end], [w * 1e3 for w in h["tip_w"][:end]], color="tab:blue", linewidth=0.8)
    axes[2].set_ylabel("tip deflection w(L) [mm]")
    axes[2].set_xlabel("t [ms]")
    for ax in axes:
        ax.grid(True, linewidth=0.3)
    fig.tight_layout()
    fig.savefig(out / "dwz_history.png", dpi=120)
    plt.close(fig)
    return {"contacts": n, "first_peak": max(h["force"][:200])}


def modes(d: pathlib.Path, out: pathlib.Path) -> dict:
    m = read(d / "modes.csv")
    ns, peaks = [int(x) for x in m["modes"]], m["peak_force"]
    ref = peaks[-1]
    within = next((n for n, p in zip(ns, peaks) if all(abs(q / ref - 1) <= 0.01 for q in peaks[ns.index(n):])), None)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(ns, peaks, "o-", color="black", label="first contact: peak Hertz force")
    ax.axhspan(ref * 0.99, ref * 1.01, color="tab:green", alpha=0.25, label=f"1 % of N = {ns[-1]}")
    if 6 in ns:
        p6 = peaks[ns.index(6)]
        ax.plot([6], [p6], "s", color="tab:red", markersize=9, label=f"DWZ's N = 6: {p6:.0f} N ({p6 / ref - 1:+.0%})")
    ax.set_xlabel("number of modes N")
    ax.set_ylabel("peak force [N]")
    ax.set_title(f"first contact force against N: within 1 % from N = {within}")
    ax.grid(True, linewidth=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "modes.png", dpi=120)
    plt.close(fig)
    return {"within_1_percent_from": within, "reference": ref}


def spin_up(d: pathlib.Path, out: pathlib.Path) -> dict:
    s = read(d / "spin_up.csv")
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    ax.plot(s["t"], [abs(w) for w in s["tip_w_zeroth"]], color="tab:red", label="zeroth order (no stiffening)")
    ax.plot(s["t"], [abs(w) for w in s["tip_w_first"]], color="black", label="first order (geometric stiffening)")
    ax.set_yscale("log")
    ax.set_ylim(1e-6, None)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("|tip deflection| [m]")
    ax.set_title("Kane-Ryan-Banerjee spin-up (omega_s = 6 rad/s, T = 15 s, 4 modes)")
    ax.grid(True, which="both", linewidth=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "spin_up.png", dpi=120)
    plt.close(fig)
    finite = [abs(w) for w in s["tip_w_zeroth"] if w == w]
    return {"first_max": max(abs(w) for w in s["tip_w_first"]), "zeroth_max": max(finite)}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", type=pathlib.Path, default=REPORT / "rotating", help="where the CSVs are")
    parser.add_argument("--out", type=pathlib.Path, help="where the PNGs go (default: --dir)")
    parser.add_argument("--quick", action="store_true", help="draw into target/report-quick/rotating")
    args = parser.parse_args(argv)
    out = args.out or (QUICK / "rotating" if args.quick else args.dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = {"dwz_history": dwz_history(args.dir, out), "modes": modes(args.dir, out),
               "spin_up": spin_up(args.dir, out)}
    print(figures)
    return figures


if __name__ == "__main__":
    main()
