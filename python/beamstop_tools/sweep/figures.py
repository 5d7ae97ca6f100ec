"""The papers' figures (keys: docs/references.md), one command each (scripts/sweep-figures NAME):

  fig8   VSM12 Figure 8: Poincare section over omega/omega_1 = 0.5 .. 1.5, F = 72, d = 0
  fig9   VSM12 Figure 9: Poincare section over the gap d = 0 .. 1.8 at omega = 0.7 omega_1
  fig10  VSM12 Figure 10: time series and phase plot at d = 1.2
  soft   the RMTM paper: amplitude-frequency curve, soft impact (SpringStopSoft, up and down sweeps)
  hard   the RMTM paper: bifurcation diagram, hard impact (SpringStopHard, up and down sweeps)
  wagg-bishop  WB00 section 4: where the 4-mode r = 0.75 cantilever impacts once per period,
         and the 1-mode r = 0.2 model at the same point
  fig9-orbits  Figure 9 with its periodic orbits continued in d (stable, unstable, special
         points) over a 500-point sweep, and the cost of both side by side
  soft-orbits, hard-orbits  the RMTM frequency responses continued over up and down sweeps
  tapping-orbits  TappingArm's strikes per swing over the swing frequency Omega: continued
         orbits over a sweep (not in `all --quick`, the test command's smoke run: its map
         integrates, about 0.1 s an evaluation; `tapping-orbits --quick` smokes it alone)

Each sweep writes its table to target/sweeps/NAME/points.parquet and its
figure, a small CSV and NAME.md (the paper's statement and what the sweep
shows, with figures measured in this run) to --out: target/sweeps/ by
default; scripts/report writes them to the tracked report/sweeps/ (all of
them, about three minutes on 2 cores). `--quick` (a smoke run, to
target/report-quick/sweeps/, tables included) sweeps at most 9 points per
axis (5 on a 2-D grid), discarding at most 40 periods and recording 10.
"""
from __future__ import annotations

import argparse
import csv
import math
import re
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from . import spec as spec_mod  # noqa: E402
from .engine import dask_client, run_sweep  # noqa: E402
from .fmu import read_fmu  # noqa: E402
from .store import read_points  # noqa: E402
from .. import ROOT, engine  # noqa: E402
from ..report import common  # noqa: E402
from ..report.common import QUICK_NOTE  # noqa: E402

FMU = ROOT / "target" / "fmu"
WORK = ROOT / "target" / "sweeps"     # the tables (WORK/NAME/points.parquet)
OUT = WORK                            # figures, CSVs and .md: --out
QUICK = False                         # --quick: see the module doc
PI2 = math.pi ** 2                     # omega_1 of the pinned-pinned beam (VSM12's scaled units)
OMEGA1_SI = 104.99411180231543         # omega_1 of the RMTM paper's cantilever, rad/s (scenes/spring_stop_soft.json)
VSM12_SETS = ["F=72", "R=0.7", "eps=1e-3"]   # Figures 8-10; zeta = 0.05, x_stop = 0.4 are the FMU's defaults


def quick_settings(params, discard, record):
    """--quick: at most 9 points per axis (5 on a 2-D grid), 40 periods discarded, 10 recorded."""
    most = 9 if len(params) == 1 else 5
    params = [re.sub(r":(\d+)$", lambda m: f":{min(int(m.group(1)), most)}", p) for p in params]
    return params, min(discard, 40), min(record, 10)


def sweep(client, name, fmu, params, sets, discard, record, **kw):
    if QUICK:
        params, discard, record = quick_settings(params, discard, record)
    info = read_fmu(FMU / f"{fmu}.fmu")
    spec = spec_mod.build(info, params, sets, discard, record, **kw)
    started = time.perf_counter()
    # a figure is computed anew each time (its .md quotes the run's time); `scripts/sweep` resumes
    meta = run_sweep(spec, WORK / name, client, progress=sys.stderr.isatty(), restart=True,
                     command=f"scripts/sweep-figures {name}")
    table, _ = read_points(WORK / name / "points.parquet")
    rows = [r for r in table.to_pylist() if not r["error"]]
    return rows, meta, time.perf_counter() - started


def write_csv(name, rows, columns):
    """OUT/NAME.csv: floats to 10 digits."""
    common.write_csv(OUT / f"{name}.csv", columns, rows,
                     lambda x: "" if x is None else (f"{x:.10g}" if isinstance(x, float) else x))


def write_md(name, title, command, statements, meta, wall):
    lines = [f"# {title}", "", f"Command: `{command}` ({meta['points_computed']} points computed in {wall:.1f} s "
             f"on {meta['workers']} workers; sticking: {meta['sticking_from']}). "
             f"Table: {(WORK / name / 'points.parquet').relative_to(ROOT)} (not committed); "
             f"figure: [{name}.png]({name}.png), per point: [{name}.csv]({name}.csv).", "",
             "| the paper says | the sweep shows |", "|---|---|"]
    lines += [f"| {a} | {b} |" for a, b in statements]
    if QUICK:
        lines[1:1] = ["", QUICK_NOTE.rstrip()]
    (OUT / f"{name}.md").write_text("\n".join(lines) + "\n")


def ranges(xs, flags):
    """Maximal runs of consecutive x with the flag set, as 'a .. b' strings."""
    out, start, prev = [], None, None
    for x, f in zip(xs, flags):
        if f and start is None:
            start = x
        if not f and start is not None:
            out.append((start, prev))
            start = None
        prev = x
    if start is not None:
        out.append((start, prev))
    return out


def fmt_ranges(rs, digits=3):
    return ", ".join(f"{a:.{digits}g}" if a == b else f"{a:.{digits}g} .. {b:.{digits}g}" for a, b in rs) or "none"


def poincare_panel(ax, rows, x, key, scale=1.0):
    for r in rows:
        ax.plot([r[x] / scale] * len(r[key]), r[key], ",", color="k" if not r["sticking"] else "tab:red")


# ---------------------------------------------------------------- VSM12
def fig8(client):
    rows, meta, wall = sweep(client, "fig8", "PinnedBeamStop", ["omega=0.5*pi**2:1.5*pi**2:201"],
                             VSM12_SETS + ["d=0"], 100, 50, samples_per_period=32)
    rows.sort(key=lambda r: r["omega"])
    ratio = [r["omega"] / PI2 for r in rows]
    stick = [r["sticking"] for r in rows]
    fig, ax = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    for r in rows:
        c = "tab:red" if r["sticking"] else "k"
        ax[0].plot([r["omega"] / PI2] * len(r["poincare"]), r["poincare"], ",", color=c)
        ax[1].plot([r["omega"] / PI2] * len(r["poincare_rate"]), r["poincare_rate"], ",", color=c)
    ax[0].set_ylabel("w(x_i) at phase 0")
    ax[1].set_ylabel("w'(x_i) at phase 0")
    ax[2].plot(ratio, [r["stuck_fraction"] for r in rows], ".-", ms=3, lw=0.7, color="tab:red", label="stuck fraction of time")
    ax[2].plot(ratio, [r["impacts_per_period"] / 40 for r in rows], ".", ms=3, color="k", label="impacts per period / 40")
    ax[2].legend(fontsize=8)
    ax[2].set_xlabel("omega / omega_1")
    ax[0].set_title("PinnedBeamStop, F = 72, R = 0.7, d = 0, zeta = 0.05, x_i = 0.4, eps = 1e-3 "
                    "(red: the beam sticks while recording)", fontsize=9)
    fig.tight_layout()
    fig.savefig(OUT / "fig8.png", dpi=110)
    plt.close(fig)
    for r in rows:
        r["omega_over_omega1"] = r["omega"] / PI2
    write_csv("fig8", rows, ["omega_over_omega1", "impacts_per_period", "sticking", "stuck_fraction", "period", "peak"])
    n_stick = sum(stick)
    write_md("fig8", "VSM12 Figure 8: Poincare section over the forcing frequency", "scripts/sweep-figures fig8", [
        ("'In the frequency range of interest 0.5 <= omega/omega_1 <= 1.5, we found a large region where "
         "sticking motions (SMs) were present'",
         f"the beam sticks at {n_stick} of {len(rows)} frequencies: omega/omega_1 in {fmt_ranges(ranges(ratio, stick))}; "
         f"stuck fraction of time up to {max(r['stuck_fraction'] for r in rows):.3f}"),
        ("'Sticking motions are identified as zero rebound velocity impacts with finite time duration'",
         "sticking = the stop's stuck time grew while recording (100 periods discarded, 50 recorded)"),
    ], meta, wall)


def fig9(client):
    rows, meta, wall = sweep(client, "fig9", "PinnedBeamStop", ["d=0:1.8:361"], VSM12_SETS + ["omega=0.7*pi**2"],
                             100, 50, samples_per_period=32)
    rows.sort(key=lambda r: r["d"])
    d = [r["d"] for r in rows]
    stick = [r["sticking"] for r in rows]
    fig, ax = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    for r in rows:
        c = "tab:red" if r["sticking"] else "k"
        ax[0].plot([r["d"]] * len(r["poincare"]), r["poincare"], ",", color=c)
        ax[1].plot([r["d"]] * len(r["poincare_rate"]), r["poincare_rate"], ",", color=c)
    ax[0].set_ylabel("w(x_i) at phase 0")
    ax[1].set_ylabel("w'(x_i) at phase 0")
    ax[2].plot(d, [r["impacts_per_period"] for r in rows], ".", ms=3, color="k", label="impacts per period")
    ax[2].plot(d, [r["period"] or 0 for r in rows], "+", ms=4, color="tab:blue", label="period [T] (0: none up to 16)")
    ax[2].plot(d, [10 * r["stuck_fraction"] for r in rows], "-", lw=0.8, color="tab:red", label="10 x stuck fraction")
    ax[2].set_ylim(-0.5, 25)
    ax[2].legend(fontsize=8)
    ax[2].set_xlabel("gap d")
    ax[0].set_title("PinnedBeamStop, F = 72, R = 0.7, omega = 0.7 omega_1, zeta = 0.05, x_i = 0.4, eps = 1e-3 "
                    "(red: sticks)", fontsize=9)
    fig.tight_layout()
    fig.savefig(OUT / "fig9.png", dpi=110)
    plt.close(fig)
    write_csv("fig9", rows, ["d", "impacts_per_period", "sticking", "stuck_fraction", "period", "peak"])
    last_stick = max((r["d"] for r in rows if r["sticking"]), default=None)
    p1d = [r["period"] == 1 and r["impacts_per_period"] == 2 for r in rows]
    at12 = min(rows, key=lambda r: abs(r["d"] - 1.2))
    kinds = {}
    for r in rows:
        kinds.setdefault(r["period"], []).append(r["d"])
    write_md("fig9", "VSM12 Figure 9: Poincare section over the gap", "scripts/sweep-figures fig9", [
        ("'As we increase the gap the sticking motions disappear around d = 0.6'",
         f"the largest gap with sticking is d = {last_stick}; sticking at d in {fmt_ranges(ranges(d, stick))}"),
        ("'Stable periodic double impact solutions (P-II), showing two impacts for every cycle of motion, were "
         "found over a wide range of gaps'",
         f"period 1 with 2 impacts per period for d in {fmt_ranges(ranges(d, p1d))}; at d = {at12['d']:.3f}: "
         f"period {at12['period']}, {at12['impacts_per_period']:g} impacts per period"),
        ("'Other kinds of motions are also visible in Figure 9, like period-I, period-III, and also some "
         "bifurcations can be seen during sticking motions'",
         "; ".join(f"period {k}: {len(v)} gaps" for k, v in sorted(kinds.items(), key=lambda kv: kv[0] or 99)
                   if k is not None) + f"; none up to 16 (irregular): {len(kinds.get(None, []))} gaps"),
    ], meta, wall)


def fig10(client=None):
    """Not a sweep: one run at d = 1.2 through fmpy, 200 periods from rest, the last 3 plotted."""
    omega = 0.7 * PI2
    session = engine.Session(engine.Fmu(FMU / "PinnedBeamStop.fmu"), "fig10")
    session.start({"F": 72.0, "R": 0.7, "eps": 1e-3, "d": 1.2, "omega": omega})
    s, vr = session.slave, session.fmu.vr
    T = 2 * math.pi / omega
    t0, n, periods = 197 * T, 400, 3
    s.doStep(0.0, t0)
    imp0 = s.getInteger([vr["impacts"]])[0]
    ts, w, v = [t0], *[[x] for x in s.getReal([vr["w_stop"], vr["v_stop"]])]
    now = t0
    for k in range(1, n * periods + 1):
        t = t0 + k * T / n
        s.doStep(now, t - now)
        now = t
        a, b = s.getReal([vr["w_stop"], vr["v_stop"]])
        ts.append(t)
        w.append(a)
        v.append(b)
    impacts = s.getInteger([vr["impacts"]])[0] - imp0
    session.close()
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    ax[0].plot((np.array(ts) - t0) / T, w, "k", lw=0.9)
    ax[0].axhline(1.2, color="tab:red", lw=0.7, ls="--", label="stop, d = 1.2")
    ax[0].set_xlabel("(t - t0) / T, t0 = 197 T")
    ax[0].set_ylabel("w(x_i)")
    ax[0].legend(fontsize=8)
    ax[1].plot(w, v, "k", lw=0.9)
    ax[1].axvline(1.2, color="tab:red", lw=0.7, ls="--")
    ax[1].set_xlabel("w(x_i)")
    ax[1].set_ylabel("w'(x_i)")
    fig.suptitle("PinnedBeamStop, F = 72, R = 0.7, omega = 0.7 omega_1, d = 1.2, zeta = 0.05, eps = 1e-3", fontsize=9)
    fig.tight_layout()
    fig.savefig(OUT / "fig10.png", dpi=110)
    plt.close(fig)
    w = np.array(w)
    strob = w[::n]
    lines = ["# VSM12 Figure 10: time series and phase plot at d = 1.2", "",
             "Command: `scripts/sweep-figures fig10` (one fmpy run: 197 periods in one doStep, then 3 periods at "
             f"{n} samples each); figure: [fig10.png](fig10.png).", "",
             *([QUICK_NOTE.rstrip(), ""] if QUICK else []),
             "| the paper says | the run shows |", "|---|---|",
             f"| 'Figure 10(a) shows the motion of the beam at the location of impact for a double impact motion "
             f"for d = 1.2' | {impacts} impacts in {periods} periods; the Poincare samples of the 3 periods differ by "
             f"{np.ptp(strob):.1e} (period 1); w(x_i) reaches {w.max():.6f} (the stop: 1.2) |"]
    (OUT / "fig10.md").write_text("\n".join(lines) + "\n")


# ---------------------------------------------------------------- the RMTM paper
def _updown_plot(rows, name, title, ylabel, maxima=False):
    fig, ax = plt.subplots(2, 1, figsize=(8, 7.5), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    for d, c in (("up", "tab:blue"), ("down", "tab:red")):
        rs = sorted((r for r in rows if r["direction"] == d), key=lambda r: r["shaker.omega"])
        x = [r["shaker.omega"] / OMEGA1_SI for r in rs]
        if maxima:
            for r in rs:
                pos = [m * 1e3 for m in r["maxima"] if m > 0]
                ax[0].plot([r["shaker.omega"] / OMEGA1_SI] * len(pos), pos, ",", color=c, alpha=0.8)
            ax[0].plot([], [], ".", color=c, label=f"sweep {d}")
        else:
            ax[0].plot(x, [r["peak"] * 1e3 for r in rs], ".-", color=c, ms=3, lw=0.8, label=f"sweep {d}")
        ax[1].plot(x, [r["period"] or 0 for r in rs], "o" if d == "up" else "x", ms=3, color=c,
                   label=f"period [T], sweep {d} (0: none up to 16)")
    ax[0].axhline(1.0, color="gray", lw=0.7, ls="--", label="stop (gap 1 mm)")
    ax[0].set_ylabel(ylabel)
    ax[0].legend(fontsize=8)
    ax[1].set_ylabel("period [T]")
    ax[1].set_xlabel("Omega / omega_1")
    ax[1].legend(fontsize=7)
    ax[0].set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(OUT / f"{name}.png", dpi=110)
    plt.close(fig)


RMTM_SETS = ["shaker.amplitude=-2e-4*shaker.omega**2"]   # base displacement Y = 0.2 mm at every frequency


def soft(client):
    rows, meta, wall = sweep(client, "soft", "SpringStopSoft", [f"shaker.omega=0.6*{OMEGA1_SI}:1.6*{OMEGA1_SI}:201"],
                             RMTM_SETS, 200, 20, output="tip.w", rate="tip.v", continuation="both",
                             samples_per_period=32)
    _updown_plot(rows, "soft", "SpringStopSoft (kappa = 0.1, 5 modes, zeta = 0.02, Y = 0.2 mm, gap 1 mm): "
                 "peak tip deflection after 200 periods", "peak of tip.w [mm]")
    rows.sort(key=lambda r: (r["direction"], r["shaker.omega"]))
    for r in rows:
        r["Omega_over_omega1"] = r["shaker.omega"] / OMEGA1_SI
    write_csv("soft", rows, ["direction", "Omega_over_omega1", "impacts_per_period", "period", "peak"])
    periods = sorted({r["period"] for r in rows}, key=lambda p: p or 99)
    top = max(rows, key=lambda r: r["peak"])
    up = {round(r["Omega_over_omega1"], 9): r["peak"] for r in rows if r["direction"] == "up"}
    down = {round(r["Omega_over_omega1"], 9): r["peak"] for r in rows if r["direction"] == "down"}
    gap = max(abs(up[k] - down[k]) / max(up[k], down[k]) for k in up)
    contact = [r["Omega_over_omega1"] for r in rows if r["impacts_per_period"] > 0]
    write_md("soft", "The RMTM paper: amplitude-frequency curve, soft impact", "scripts/sweep-figures soft", [
        ("'In soft impact, the time-history response of the system does not reflect multiperiodic motion'",
         f"periods found over both sweeps: {periods} (None: none up to 16)"),
        ("Figure 8: the amplitude-frequency response (20 modes, peak after steady state; 'almost identical' "
         "across methods)",
         f"largest peak {top['peak'] * 1e3:.4f} mm at Omega/omega_1 = {top['Omega_over_omega1']:.3f} "
         f"(sweep {top['direction']}); contact with the stop for Omega/omega_1 in {min(contact):.3f} .. "
         f"{max(contact):.3f}; up and down sweeps differ by at most {gap:.1e} (relative): no hysteresis. "
         "One method (FIM, 5 modes, the scene's); the methods' agreement is in report/spring_stop"),
    ], meta, wall)


def hard(client):
    rows, meta, wall = sweep(client, "hard", "SpringStopHard", [f"shaker.omega=0.8*{OMEGA1_SI}:1.6*{OMEGA1_SI}:161"],
                             RMTM_SETS, 200, 40, output="tip.w", rate="tip.v", continuation="both",
                             samples_per_period=32)
    _updown_plot(rows, "hard", "SpringStopHard (kappa = 100, 20 modes, zeta = 0.02, Y = 0.2 mm, gap 1 mm): "
                 "positive local maxima of tip.w over 40 periods after 200", "local maxima of tip.w [mm]", maxima=True)
    rows.sort(key=lambda r: (r["direction"], r["shaker.omega"]))
    for r in rows:
        r["Omega_over_omega1"] = r["shaker.omega"] / OMEGA1_SI
    write_csv("hard", rows, ["direction", "Omega_over_omega1", "impacts_per_period", "period", "peak"])
    stmts = []
    for d in ("up", "down"):
        rs = [r for r in rows if r["direction"] == d]
        x = [r["Omega_over_omega1"] for r in rs]
        multi = ranges(x, [r["period"] is not None and r["period"] > 1 for r in rs])
        none = ranges(x, [r["period"] is None for r in rs])
        stmts.append((f"sweep {d}", f"period > 1 for Omega/omega_1 in {fmt_ranges(multi)}; no period up to 16 "
                                    f"(quasi-periodic or chaotic) in {fmt_ranges(none)}"))
    up = {round(r["Omega_over_omega1"], 9): r for r in rows if r["direction"] == "up"}
    differ = [k for k, r in up.items() for q in rows if q["direction"] == "down"
              and round(q["Omega_over_omega1"], 9) == k and (q["impacts_per_period"] > 0) != (r["impacts_per_period"] > 0)]
    write_md("hard", "The RMTM paper: bifurcation diagram, hard impact", "scripts/sweep-figures hard", [
        ("'in hard impact, the system exhibits multiperiodic and quasiperiodic motion' (Figure 9: local maxima "
         "of the positive response after steady state against the sweep frequency)", stmts[0][1] + " (sweep up)"),
        ("", stmts[1][1] + " (sweep down)"),
        ("(hysteresis)", f"{len(differ)} frequencies where one sweep impacts and the other does not: "
                         f"{fmt_ranges(ranges(sorted(differ), [True] * len(differ)))}"),
    ], meta, wall)


# ---------------------------------------------------------------- WB00
def wagg_bishop(client):
    from .wagg_bishop import study
    study(client, sweep, write_md, write_csv, OUT)


# ---------------------------------------------------------------- periodic orbits (beamstop_tools.orbits)
def _orbits_md(name, title, command, lines):
    text = [f"# {title}", "", f"Command: `{command}`; figure: [{name}.png]({name}.png), "
            f"special points: [{name}_special.csv]({name}_special.csv).", ""] + lines
    if QUICK:
        text[1:1] = ["", QUICK_NOTE.rstrip()]
    (OUT / f"{name}.md").write_text("\n".join(text) + "\n")


def _special_csv(name, orbits):
    param = orbits.param
    with open(OUT / f"{name}_special.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["type", "branch", param, "periods", "impacts_per_period", "stable", "note"])
        for s in orbits.special.to_pylist():
            w.writerow([s["type"], s["branch"], f"{s[param]:.12g}", s["periods"], f"{s['impacts_per_period']:g}",
                        s["stable"], s["note"]])


def _branch_lines(orbits):
    param = orbits.param
    rows = orbits.branch.to_pylist()
    out = ["| branch | period | points (stable) | range of " + param + " | its ends |", "|---|---|---|---|---|"]
    for b in sorted({r["branch"] for r in rows}):
        rs = [r for r in rows if r["branch"] == b]
        ends = [s for s in orbits.special.to_pylist() if s["branch"] == b and s["type"] == "EP"]
        out.append(f"| {b} | {rs[0]['periods']} T | {len(rs)} ({sum(r['stable'] for r in rs)}) | "
                   f"{min(r[param] for r in rs):.6g} .. {max(r[param] for r in rs):.6g} | "
                   + "; ".join(f"{e[param]:.6g}: {e['note']}" for e in ends) + " |")
    return out


def fig9_orbits(client):
    """VSM12 Fig. 9 with its continued branches over the 500-point sweep, and the two runs' costs side by side."""
    from .. import orbits as orb
    points = 9 if QUICK else 500
    lo, hi = (1.0, 1.4) if QUICK else (0.0, 1.8)  # the smoke run: around the start, the same code paths
    params = [f"d={lo:g}:{hi:g}:{points}"]
    info = read_fmu(FMU / "PinnedBeamStop.fmu")
    spec = spec_mod.build(info, params, VSM12_SETS + ["omega=0.7*pi**2"], 40 if QUICK else 100, 10 if QUICK else 100)
    t = time.perf_counter()
    meta = run_sweep(spec, WORK / "fig9_orbits_sweep", client, progress=sys.stderr.isatty(), restart=True,
                     command="scripts/sweep-figures fig9-orbits")
    sweep_wall = time.perf_counter() - t
    sweep_table, _ = read_points(WORK / "fig9_orbits_sweep" / "points.parquet")
    starts = [1.2]
    orbits = orb.cover(ROOT / "scenes" / "pinned_beam.json", "d", lo, hi, sweep_table, start=starts,
                       sets={"F": 72.0, "omega": 0.7 * PI2, "eps": 1e-3}, points=40 if QUICK else 200,
                       transient=int(spec.discard), max_branches=2 if QUICK else 200, out=WORK / "fig9_orbits",
                       client=client)
    single = orb.continue_orbits(ROOT / "scenes" / "pinned_beam.json", "d", lo, hi, start=[1.2],
                                 sets={"F": 72.0, "omega": 0.7 * PI2, "eps": 1e-3}, points=40 if QUICK else 200,
                                 max_branches=1, out=WORK / "fig9_orbits_one")
    orb.plot(orbits, OUT / "fig9-orbits.png", sweep_table,
             title="PinnedBeamStop, VSM12 Fig. 9 (F = 72, omega = 0.7 omega_1, R = 0.7, eps = 1e-3): "
                   "continued orbits over the sweep", output_label="w(x_i)")
    _special_csv("fig9-orbits", orbits)
    matched, total, missed = orb.on_branches(orbits, sweep_table)
    rows = orbits.branch.to_pylist()
    # Why a sweep point is on no branch: next to a period doubling the
    # multiplier near -1 decays as |mu|^discard, and the recorded periods
    # still alternate.
    def why(p):
        near = [r for r in rows if r["periods"] == 1 and abs(r["d"] - p) < 0.01]
        if not near:
            return f"d = {p:.4g}"
        r = min(near, key=lambda r: abs(r["d"] - p))
        mus = list(zip(r["multipliers_re"], r["multipliers_im"]))
        real = [a for a, b in mus if b == 0.0]
        if not real:  # complex pairs only: the response spirals in as |mu|^discard
            mu = max((math.hypot(a, b) for a, b in mus), default=math.nan)
            return (f"d = {p:.4g} (the period-1 orbit there: stable {r['stable']}, no real multiplier, its largest "
                    f"|mu| {mu:.3f} (a complex pair), |mu|^{spec.discard:g} = {mu ** spec.discard:.2g})")
        mu = min(real)
        return (f"d = {p:.4g} (the period-1 orbit there: stable {r['stable']}, its multiplier nearest -1 {mu:.3f}, "
                f"|mu|^{spec.discard:g} = {abs(mu) ** spec.discard:.2g})")

    special = orbits.special.to_pylist()
    p2 = [r for r in single.branch.to_pylist()]
    two = [r for r in p2 if r["impacts_per_period"] == 2.0]
    ends = [s for s in single.special.to_pylist() if s["type"] in ("PD", "GR", "SN") and two and
            min(r["d"] for r in two) - 1e-3 <= s["d"] <= max(r["d"] for r in two) + 1e-3]
    lines = [
        f"**Cost, side by side** (this run): the brute-force sweep, {meta['points_computed']} gaps "
        f"x ({spec.discard:g} + {spec.record}) periods, took {sweep_wall:.1f} s on {meta['workers']} worker(s); the continuation "
        f"of the branch through d = 1.2 alone ({len(single.branch)} points, {single.seconds:.1f} s). Every branch, "
        f"started again from each of the sweep's periodic points not yet on one (`scripts/orbits --cover`, its "
        f"restarts in {orb.PIECES} run(s) over the whole range, on the Dask client): "
        f"{len(rows)} points on {len({r['branch'] for r in rows})} branches, {orbits.seconds:.1f} s.",
        "",
        f"**The sweep's periodic responses on a continued branch**: {matched} of the {total} gaps where the sweep "
        f"settled on period 1 or 2 (every Poincare sample within 1e-3 of a branch's section at the same period and "
        f"impacts per period)" + (f"; not: {'; '.join(why(m) for m in missed)}." if missed else "."),
        "",
        "**The period-1 double-impact branch (P-II)**, continued from d = 1.2: "
        + "; ".join(f"{s['type']} at d = {s['d']:.6f} ({s['note']})" for s in ends) + ".",
        "",
    ] + _branch_lines(orbits)
    _orbits_md("fig9-orbits", "VSM12 Figure 9 with its periodic orbits continued in the gap",
               "scripts/sweep-figures fig9-orbits", lines)


def _spring_orbits(client, name, fmu, scene, lo, hi, start, modes_note, max_branches):
    from .. import orbits as orb
    points = 9 if QUICK else 161
    params = [f"shaker.omega={lo}*{OMEGA1_SI}:{hi}*{OMEGA1_SI}:{points}"]
    info = read_fmu(FMU / f"{fmu}.fmu")
    spec = spec_mod.build(info, params, RMTM_SETS, 40 if QUICK else 200, 10 if QUICK else 20, output="tip.w",
                          rate="tip.v", continuation="both")
    t = time.perf_counter()
    run_sweep(spec, WORK / f"{name}_sweep", client, progress=sys.stderr.isatty(), restart=True,
              command=f"scripts/sweep-figures {name}")
    sweep_wall = time.perf_counter() - t
    sweep_table, _ = read_points(WORK / f"{name}_sweep" / "points.parquet")
    orbits = orb.continue_orbits(ROOT / "scenes" / scene, "shaker.omega", lo * OMEGA1_SI, hi * OMEGA1_SI,
                                 start=[start * OMEGA1_SI], ties=["shaker.amplitude=-2e-4*shaker.omega^2"],
                                 points=20 if QUICK else 100, max_branches=1 if QUICK else max_branches,
                                 out=WORK / name)
    orb.plot(orbits, OUT / f"{name}.png", sweep_table,
             title=f"{fmu} ({modes_note}, Y = 0.2 mm, gap 1 mm): continued orbits over the up and down sweeps",
             output_label="first stop's displacement")
    _special_csv(name, orbits)
    kinds = {}
    for s in orbits.special.to_pylist():
        kinds.setdefault(s["type"], []).append(s["shaker.omega"] / OMEGA1_SI)
    lines = [
        f"Continuation: {len(orbits.branch)} points in {orbits.seconds:.1f} s; the up and down sweeps "
        f"({points} frequencies each, 200 + 20 periods): {sweep_wall:.1f} s.",
        "",
        "Special points (Omega / omega_1): " + "; ".join(f"{k}: {', '.join(f'{v:.4f}' for v in sorted(vs))}"
                                                       for k, vs in sorted(kinds.items())) + ".",
        "",
    ] + _branch_lines(orbits)
    _orbits_md(name, f"The RMTM cantilever's frequency response, continued ({fmu})", f"scripts/sweep-figures {name}", lines)


def soft_orbits(client):
    _spring_orbits(client, "soft-orbits", "SpringStopSoft", "spring_stop_soft.json", 0.6, 1.6, 1.0, "kappa = 0.1, 5 modes", 4)


def hard_orbits(client):
    _spring_orbits(client, "hard-orbits", "SpringStopHard", "spring_stop_hard.json", 0.8, 1.6, 1.6, "kappa = 100, 20 modes", 4)


def tapping_orbits(client):
    """TappingArm (a beam on a swinging hub striking a stop) over its swing frequency Omega: the
    continued orbits (the tip's penetration tip.y at the section, strikes per swing) over a sweep."""
    from .. import orbits as orb
    # Omega 12 .. 16: one strike per swing at the default, two from about
    # 15 on. The state at the section turns with the phase of the ringing
    # after the strike (omega_1 t_s / Omega rad per rad/s, t_s the time from
    # the strike to the section: about 3), so the branch is long in the
    # state: many points per unit of Omega.
    lo, hi = (11.9, 12.1) if QUICK else (12.0, 16.0)
    points = 3 if QUICK else 41
    info = read_fmu(FMU / "TappingArm.fmu")
    spec = spec_mod.build(info, [f"Omega={lo:g}:{hi:g}:{points}"], [], 10 if QUICK else 60, 3 if QUICK else 10,
                          forcing="Omega", output="tip.y", rate="none")
    t = time.perf_counter()
    run_sweep(spec, WORK / "tapping_orbits_sweep", client, progress=sys.stderr.isatty(), restart=True,
              command="scripts/sweep-figures tapping-orbits")
    sweep_wall = time.perf_counter() - t
    sweep_table, _ = read_points(WORK / "tapping_orbits_sweep" / "points.parquet")
    orbits = orb.continue_orbits(ROOT / "scenes" / "tapping_arm.json", "Omega", lo, hi, start=[12.0],
                                 points=2 if QUICK else 60, transient=10 if QUICK else 60,
                                 max_branches=1 if QUICK else 3, out=WORK / "tapping_orbits")
    orb.plot(orbits, OUT / "tapping-orbits.png", sweep_table,
             title="TappingArm (theta = -0.3 + 0.3 sin(Omega t), rubber-tipped stop): continued orbits over the sweep",
             output_label="tip.y (penetration) at the section")
    _special_csv("tapping-orbits", orbits)
    matched, total, missed = orb.on_branches(orbits, sweep_table)
    kinds = {}
    for sp in orbits.special.to_pylist():
        kinds.setdefault(sp["type"], []).append(sp["Omega"])
    lines = [
        f"Continuation: {len(orbits.branch)} points in {orbits.seconds:.1f} s (each map evaluation replays the "
        f"integration for its Jacobian, src/kinds/rotating/flow.rs); the sweep ({points} frequencies, "
        f"{spec.discard:g} + {spec.record} periods): {sweep_wall:.1f} s.",
        "",
        f"**The sweep's periodic responses on a continued branch**: {matched} of the {total} frequencies where the "
        f"sweep settled on period 1 or 2" + (f"; not: {', '.join(f'{m:.4g}' for m in missed)}." if missed else "."),
        "",
        "Special points (Omega, rad/s): " + "; ".join(f"{k}: {', '.join(f'{v:.6g}' for v in sorted(vs))}"
                                                    for k, vs in sorted(kinds.items())) + ".",
        "",
    ] + _branch_lines(orbits)
    _orbits_md("tapping-orbits", "TappingArm's strikes over its swing frequency, continued",
               "scripts/sweep-figures tapping-orbits", lines)


FIGURES = {"fig8": fig8, "fig9": fig9, "fig10": fig10, "soft": soft, "hard": hard, "wagg-bishop": wagg_bishop,
           "fig9-orbits": fig9_orbits, "soft-orbits": soft_orbits, "hard-orbits": hard_orbits,
           "tapping-orbits": tapping_orbits}


# Left out of `all --quick` (the test command runs it, at its time limit):
# a smoke run of an integrated flow's continuation takes tens of seconds.
NOT_IN_QUICK_ALL = {"tapping-orbits"}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="scripts/sweep-figures", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("names", nargs="+", choices=list(FIGURES) + ["all"])
    p.add_argument("--scheduler", metavar="ADDRESS")
    p.add_argument("--workers", type=int)
    p.add_argument("--out", type=Path, help="figures, CSVs and .md (default target/sweeps, "
                                             "target/report-quick/sweeps with --quick)")
    p.add_argument("--quick", action="store_true", help="a smoke run: few points, short transients")
    args = p.parse_args(argv)
    global OUT, WORK, QUICK
    QUICK = args.quick
    if QUICK:
        WORK = ROOT / "target" / "report-quick" / "sweeps"
    OUT = args.out.resolve() if args.out else WORK
    names = [n for n in FIGURES if not (QUICK and n in NOT_IN_QUICK_ALL)] if "all" in args.names else args.names
    OUT.mkdir(parents=True, exist_ok=True)
    with dask_client(args.scheduler, args.workers) as client:
        for n in names:
            t = time.perf_counter()
            FIGURES[n](client)
            print(f"{n}: {OUT / n}.png, {n}.md ({time.perf_counter() - t:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
