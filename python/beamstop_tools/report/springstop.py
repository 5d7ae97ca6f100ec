#!/usr/bin/env python3
"""The spring-stop report: beamstop's exact FIM / MTM / RMTM against the claims
of the RMTM paper (relative mode transfer; keys: docs/references.md) and against an independent scipy
integration (python/beamstop_tools/report/springstop_reference.py).

    python -m beamstop_tools.report.springstop [--quick] [--out report/spring_stop] [--bin PATH]

writes report/spring_stop/summary.md plus CSVs and PNGs. Every number in the
markdown is measured in this run. `--quick` is a smoke run (about 15 s) with
shorter runs and fewer settings, written to target/report-quick/spring_stop;
its numbers are not the report's.

Sections (see summary.md):
 1. run time and switches against the stop stiffness kappa = k / (3 EI / L^3)
 2. convergence of the steady-state peak in the number of modes
 3. tip-deflection maxima and contacts per forcing period ("two peaks",
    "sticking-chattering")
 4. time histories FIM vs RMTM at 5 and 20 modes
 5. run time of 0.5 s of hard impact per method (the RMTM paper's Table 3)
 6. exact FIM against numerical integration (the scipy reference)
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import os
import re
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402,F401
from scipy.signal import find_peaks  # noqa: E402

from .. import ROOT, engine  # noqa: E402
from . import springstop_reference  # noqa: E402
from .common import log, md_table, out_dir, write_csv  # noqa: E402

SCENES = {
    "soft": ROOT / "scenes" / "spring_stop_soft.json",
    "hard": ROOT / "scenes" / "spring_stop_hard.json",
    "very_hard": ROOT / "scenes" / "spring_stop_very_hard.json",
}
METHODS = ("fim", "mtm", "rmtm")
TOLS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
SPEED_RE = re.compile(r"speed=([0-9.eE+-]+)")
STAT_RE = re.compile(r"(\d+) events, (\d+) (?:event-function evaluations|event-search points), ([0-9.eE+-]+) ms")


# ----------------------------------------------------------------- scenes and runs

def load_scene(which: str) -> dict:
    with open(SCENES[which]) as fh:
        return json.load(fh)


def static_stiffness(scene: dict) -> float:
    s = scene["structure"]
    return 3.0 * s["E"] * s["I"] / s["length"] ** 3


def forcing_omega(scene: dict) -> float:
    return float(scene["loads"][0]["omega"])


def variant(which: str, *, n=None, method=None, td=None, kappa=None, k=None, gap=None,
            t_end=0.5, step=1e-2) -> dict:
    d = load_scene(which)
    d["experiment"] = {"start": 0.0, "stop": float(t_end), "step": float(step)}
    d["outputs"] = {"energy": False, "modal": False, "energy_balance": False}
    d["solver"] = {"max_probes_per_step": 1000000000000}
    law = d["stops"][0]["law"]
    if kappa is not None:
        law["k"] = kappa * static_stiffness(d)
    if k is not None:
        law["k"] = float(k)
    if method is not None:
        law["method"] = method
    if td is not None:
        law["transfer_damping"] = td
    if n is not None:
        d["structure"]["modes"] = int(n)
    if gap is not None:
        d["stops"][0]["gap"] = float(gap)
    return d


class RunFailed(RuntimeError):
    pass


class Runner:
    """Runs `beamstop run` on scene dicts in a private temporary folder."""

    def __init__(self, exe: str):
        self.exe = exe
        self.tmp = Path(tempfile.mkdtemp(prefix="springstop-"))
        self.n_runs = 0
        self.total_s = 0.0
        self.timeout_s = 300.0

    def close(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def run(self, scene: dict, *, history=True) -> dict:
        path = self.tmp / "scene.json"
        out = self.tmp / "out"
        with open(path, "w") as fh:
            json.dump(scene, fh)
        t0 = time.perf_counter()
        try:
            p = engine.beamstop(["run", path, "--out", out], exe=self.exe, timeout=self.timeout_s)
        except subprocess.TimeoutExpired:
            raise RunFailed(f"no result within {self.timeout_s:g} s")
        finally:
            self.total_s += time.perf_counter() - t0
            self.n_runs += 1
        if p.returncode != 0:
            raise RunFailed((p.stderr or p.stdout).strip().splitlines()[-1][:500] if (p.stderr or p.stdout).strip()
                            else f"exit code {p.returncode}")
        m = STAT_RE.search(p.stdout)
        if not m:
            raise RuntimeError(f"cannot parse beamstop output: {p.stdout!r}")
        res = {"events": int(m.group(1)), "evals": int(m.group(2)), "ms": float(m.group(3))}
        name = scene["name"]
        con, sep, seq, spd = [], [], [], []
        with open(out / f"{name}_events.csv") as fh:
            cols = fh.readline().strip().split(",")
            it, ie = cols.index("time"), cols.index("event")
            for line in fh:
                f = line.split(",", max(it, ie) + 1)
                if f[ie] == "contact":
                    con.append(float(f[it]))
                    seq.append((con[-1], 1))
                    m_ = SPEED_RE.search(line)
                    spd.append(float(m_.group(1)) if m_ else float("nan"))
                elif f[ie] == "separation":
                    sep.append(float(f[it]))
                    seq.append((sep[-1], -1))
        res["contacts"] = np.array(con)
        res["separations"] = np.array(sep)
        res["contact_speed"] = np.array(spd)
        res["sequence"] = seq  # (time, +1 contact / -1 separation) in the order beamstop reports them
        res["switches"] = len(res["contacts"]) + len(res["separations"])
        if history:
            with open(out / f"{name}.csv") as fh:
                hdr = fh.readline().strip().split(",")
            a = np.loadtxt(out / f"{name}.csv", delimiter=",", skiprows=1, ndmin=2)
            res["h"] = {h: a[:, i] for i, h in enumerate(hdr)}
        return res

    def timed(self, scene: dict, repeats: int) -> dict:
        """Median of `repeats` run times (the binary's own ms, CSV writing included)."""
        return self.timed_many([scene], repeats)[0]

    def timed_many(self, scenes: list, repeats: int) -> list:
        """Like `timed` for several scenes, the repeats taken in rounds over all of them, so that a
        change in the machine's load during the measurement is shared rather than hitting one setting."""
        runs = [[] for _ in scenes]
        for _ in range(repeats):
            for i, sc in enumerate(scenes):
                runs[i].append(self.run(sc, history=False))
        out = []
        for rs in runs:
            r = rs[0]
            r["ms_all"] = [x["ms"] for x in rs]
            r["ms"] = statistics.median(r["ms_all"])
            out.append(r)
        return out


# ----------------------------------------------------------------- peak finding

def hermite_peak(t, w, v):
    """Largest value of the piecewise cubic Hermite interpolant of (w, w' = v)
    on the samples: exact to O(h^4) at the local maxima, unlike the sample max."""
    best = float(np.max(w))
    idx = np.nonzero((v[:-1] > 0) & (v[1:] <= 0))[0]
    for i in idx:
        h = t[i + 1] - t[i]
        w0, w1, v0, v1 = w[i], w[i + 1], v[i] * h, v[i + 1] * h
        a = 6 * w0 + 3 * v0 - 6 * w1 + 3 * v1
        b = -6 * w0 - 4 * v0 + 6 * w1 - 2 * v1
        c = v0
        if abs(a) > 1e-300:
            disc = b * b - 4 * a * c
            if disc < 0:
                continue
            sq = math.sqrt(disc)
            roots = [(-b - sq) / (2 * a), (-b + sq) / (2 * a)]
        else:
            roots = [-c / b] if b != 0 else []
        for s in roots:
            if 0.0 <= s <= 1.0:
                p = ((2 * s ** 3 - 3 * s ** 2 + 1) * w0 + (s ** 3 - 2 * s ** 2 + s) * v0
                     + (-2 * s ** 3 + 3 * s ** 2) * w1 + (s ** 3 - s ** 2) * v1)
                best = max(best, p)
    return best


def window(h: dict, t0: float, t1: float):
    t = h["time"]
    return (t >= t0 - 1e-9) & (t <= t1 + 1e-9)


def steady_peaks(res: dict, t_end: float, T: float) -> dict:
    h = res["h"]
    sel = window(h, t_end - 2 * T, t_end)
    prev = window(h, t_end - 4 * T, t_end - 2 * T)
    t = h["time"]
    P = hermite_peak(t[sel], h["tip.w"][sel], h["tip.v"][sel])
    Pp = hermite_peak(t[prev], h["tip.w"][prev], h["tip.v"][prev])
    pen = hermite_peak(t[sel], h["stop.penetration"][sel], h["stop.v"][sel])
    return {"peak": P, "peak_pen": pen, "drift": (P - Pp) / P, "sample_peak": float(np.max(h["tip.w"][sel]))}


def keep_tail(res: dict, t_from: float) -> dict:
    """Drop the history before t_from (memory)."""
    h = res.get("h")
    if h is None:
        return res
    sel = h["time"] >= t_from - 1e-9
    r = dict(res)
    r["h"] = {k: v[sel] for k, v in h.items()}
    return r


# ----------------------------------------------------------------- formatting

def fmt(x, d=3):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if x == 0:
        return "0"
    ax = abs(x)
    if 1e-3 <= ax < 1e4:
        return f"{x:.{d}g}"
    return f"{x:.{max(d - 1, 1)}e}"


def rtol_range(rtols):
    lo, hi = min(rtols), max(rtols)
    return f"{hi:.0e}" if lo == hi else f"{hi:.0e} ... {lo:.0e}"


# ----------------------------------------------------------------- section 1

def section_stiffness(R: Runner, cfg, out: Path):
    kappas = cfg["kappas"]
    reps = cfg["reps"]
    rows = []
    timed = R.timed_many([variant("hard", n=20, method="fim", gap=1.0, t_end=0.5, step=1e-2)]
                         + [variant("hard", n=20, method="fim", kappa=kap, t_end=0.5, step=1e-2) for kap in kappas],
                         reps)
    base = timed[0]
    for kap, r in zip(kappas, timed[1:]):
        sw = r["switches"]
        rows.append({
            "kappa": kap, "switches": sw, "contacts": len(r["contacts"]), "evals": r["evals"],
            "ms": r["ms"], "ms_min": min(r["ms_all"]), "ms_max": max(r["ms_all"]),
            "ms_per_switch": r["ms"] / sw if sw else float("nan"),
            "marginal_ms_per_switch": (r["ms"] - base["ms"]) / sw if sw else float("nan"),
            "evals_per_switch": r["evals"] / sw if sw else float("nan"),
        })
        log(f"  kappa {kap:.0e}: {sw} switches, {r['evals']} evals, {r['ms']:.2f} ms")
    hdr = list(rows[0].keys())
    write_csv(out / "stiffness_sweep.csv", hdr, [[r[k] for k in hdr] for r in rows])

    k = np.array([r["kappa"] for r in rows])
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    a = ax[0]
    a.loglog(k, [r["ms"] for r in rows], "o-", color="C0", label="run time (median of %d)" % reps)
    a.axhline(base["ms"], color="C0", ls=":", lw=1, label="run time without contact (gap 1 m)")
    a.set_xlabel("kappa = k / (3 EI / L^3)")
    a.set_ylabel("run time [ms]", color="C0")
    a2 = a.twinx()
    a2.loglog(k, [max(r["switches"], 0.5) for r in rows], "s--", color="C3", label="switches")
    a2.set_ylabel("switches in 0.5 s (contacts + separations)", color="C3")
    a.set_title("hard scene, FIM, 20 modes, 0.5 s")
    h1, l1 = a.get_legend_handles_labels()
    h2, l2 = a2.get_legend_handles_labels()
    a.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper left")
    a = ax[1]
    a.semilogx(k, [r["evals_per_switch"] for r in rows], "o-", color="C2", label="event-function evaluations / switch")
    a.set_xlabel("kappa")
    a.set_ylabel("evaluations per switch", color="C2")
    a3 = a.twinx()
    a3.semilogx(k, [r["ms_per_switch"] for r in rows], "s--", color="C0", label="run time / switch")
    a3.semilogx(k, [r["marginal_ms_per_switch"] for r in rows], "^:", color="C1",
                label="(run time - contact-free run time) / switch")
    a3.set_ylabel("ms per switch")
    a3.set_yscale("log")
    h1, l1 = a.get_legend_handles_labels()
    h2, l2 = a3.get_legend_handles_labels()
    a.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper right")
    a.set_title("cost per switch")
    fig.tight_layout()
    fig.savefig(out / "stiffness_sweep.png", dpi=120)
    plt.close(fig)
    return {"rows": rows, "base_ms": base["ms"], "reps": reps}


# ----------------------------------------------------------------- section 2 (+ 3, 4 data)

def section_convergence(R: Runner, cfg, out: Path):
    t_end = cfg["t_conv"]
    nlist = cfg["nlist"]
    nref, ncheck = cfg["nref"], cfg["ncheck"]
    keep_n = set(cfg["hist_n"])
    results = {}   # (scene, method, td, N) -> dict
    hist = {}      # (scene, method, td, N) -> tail history (hard scene)
    peak_check = {}
    for which in ("soft", "hard"):
        T = 2 * math.pi / forcing_omega(load_scene(which))
        runs = [("fim", "inherited", n) for n in sorted(set(nlist) | {nref, ncheck})]
        runs += [(m, "inherited", n) for m in ("mtm", "rmtm") for n in sorted(set(nlist) | {ncheck, nref})]
        runs += [(m, "modal", n) for m in ("mtm", "rmtm") for n in cfg["modal_n"]]
        t0 = time.perf_counter()
        for m, td, n in runs:
            try:
                r = R.run(variant(which, n=n, method=m, td=td if m != "fim" else None, t_end=t_end,
                                  step=cfg["conv_step"]))
            except RunFailed as e:
                log(f"  {which} {m} {td} N={n}: failed: {e}")
                nan = float("nan")
                results[(which, m, td, n)] = dict(peak=nan, peak_pen=nan, drift=nan, sample_peak=nan, events=-1,
                                                  evals=-1, ms=nan, n_contacts=-1, failed=str(e))
                continue
            pk = steady_peaks(r, t_end, T)
            pk.update(events=r["events"], evals=r["evals"], ms=r["ms"], n_contacts=len(r["contacts"]))
            results[(which, m, td, n)] = pk
            if which == "hard" and (n in keep_n or n == nref):
                hist[(which, m, td, n)] = keep_tail(r, t_end - 10 * T)
        log(f"  {which}: {len(runs)} runs of {t_end:g} s in {time.perf_counter() - t0:.1f} s")
        # how well the Hermite peak of the output samples estimates the true peak: the same run on a finer grid
        key = (which, "rmtm", "inherited", 20)
        if key in results and math.isfinite(results[key]["peak"]):
            r = R.run(variant(which, n=20, method="rmtm", td="inherited", t_end=t_end, step=cfg["check_step"]))
            pk = steady_peaks(r, t_end, T)
            peak_check[which] = {"step": cfg["check_step"], "peak": pk["peak"],
                                 "rel": (results[key]["peak"] - pk["peak"]) / pk["peak"],
                                 "rel_pen": (results[key]["peak_pen"] - pk["peak_pen"]) / pk["peak_pen"]}

    # very hard: contacts per period only
    which = "very_hard"
    T = 2 * math.pi / forcing_omega(load_scene(which))
    t0 = time.perf_counter()
    for m in METHODS:
        for n in cfg["vh_n"]:
            try:
                r = R.run(variant(which, n=n, method=m, td="inherited" if m != "fim" else None,
                                  t_end=t_end, step=cfg["vh_step"]))
            except RunFailed as e:
                log(f"  very hard {m} N={n}: failed: {e}")
                hist[(which, m, "inherited", n)] = {"failed": str(e)}
                continue
            hist[(which, m, "inherited", n)] = keep_tail(r, t_end - 10 * T)
    log(f"  very hard: {3 * len(cfg['vh_n'])} runs in {time.perf_counter() - t0:.1f} s")

    # tables
    conv = {}
    csv_rows = []
    for which in ("soft", "hard"):
        ref = results[(which, "fim", "inherited", nref)]
        chk = results[(which, "fim", "inherited", ncheck)]
        best = results[(which, "rmtm", "inherited", nref)]
        info = {
            "ref": ref, "check": chk, "ref_vs_check": (chk["peak"] - ref["peak"]) / ref["peak"],
            "ref_vs_check_pen": (chk["peak_pen"] - ref["peak_pen"]) / ref["peak_pen"],
            "ref_vs_rmtm": (best["peak"] - ref["peak"]) / ref["peak"],
            "need": {}, "need_rmtm_ref": {},
        }
        for m in METHODS:
            ns = sorted(n for (w, mm, td, n) in results if w == which and mm == m and td == "inherited")
            for n in ns:
                r = results[(which, m, "inherited", n)]
                r["rel"] = (r["peak"] - ref["peak"]) / ref["peak"]
                r["rel_pen"] = (r["peak_pen"] - ref["peak_pen"]) / ref["peak_pen"]
                r["rel_rmtm"] = (r["peak"] - best["peak"]) / best["peak"]
                csv_rows.append([which, m, "inherited", n, r["peak"], r["peak_pen"], r["rel"], r["rel_pen"],
                                 r["rel_rmtm"], r["drift"], r["n_contacts"], r["events"], r["evals"], r["ms"]])
            for tol in TOLS:
                for key, field in (("need", "rel"), ("need_rmtm_ref", "rel_rmtm")):
                    cand = [n for n in ns if n != nref or field != "rel" or m != "fim"]
                    need = None
                    for n in cand:
                        if all(abs(results[(which, m, "inherited", n2)][field]) <= tol for n2 in cand if n2 >= n):
                            need = n
                            break
                    info[key][(m, tol)] = need
        for m in ("mtm", "rmtm"):
            for n in cfg["modal_n"]:
                r = results[(which, m, "modal", n)]
                own = results[(which, m, "modal", max(cfg["modal_n"]))]
                r["rel"] = (r["peak"] - ref["peak"]) / ref["peak"]
                r["rel_pen"] = (r["peak_pen"] - ref["peak_pen"]) / ref["peak_pen"]
                r["rel_own"] = (r["peak"] - own["peak"]) / own["peak"]
                csv_rows.append([which, m, "modal", n, r["peak"], r["peak_pen"], r["rel"], r["rel_pen"],
                                 float("nan"), r["drift"], r["n_contacts"], r["events"], r["evals"], r["ms"]])
        conv[which] = info
    write_csv(out / "convergence.csv",
              ["scene", "method", "transfer_damping", "modes", "peak_tip_w", "peak_penetration",
               "rel_diff_peak_vs_ref", "rel_diff_penetration_vs_ref", "rel_diff_peak_vs_rmtm_Nref",
               "drift_vs_previous_2_periods", "contacts_in_run", "events", "event_evaluations", "run_ms"],
              csv_rows)

    # convergence plot
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    for a, which in zip(ax, ("soft", "hard")):
        for i, m in enumerate(METHODS):
            ns = sorted(n for (w, mm, td, n) in results if w == which and mm == m and td == "inherited"
                        and not (m == "fim" and n == nref))
            y = [max(abs(results[(which, m, "inherited", n)]["rel"]), 1e-16) for n in ns]
            a.loglog(ns, y, "o-", color=f"C{i}", label=f"{m.upper()} (inherited damping)")
        for i, m in enumerate(("mtm", "rmtm")):
            ns = cfg["modal_n"]
            y = [max(abs(results[(which, m, "modal", n)]["rel"]), 1e-16) for n in ns]
            a.loglog(ns, y, "x:", color=f"C{i + 1}", alpha=0.7, label=f"{m.upper()} (modal damping)")
        a.axhline(1e-3, color="gray", lw=0.8, ls="--")
        a.axhline(1e-6, color="gray", lw=0.8, ls="--")
        a.axhline(abs(conv[which]["ref_vs_check"]), color="k", lw=0.8, ls=":",
                  label=f"|FIM {ncheck} - FIM {nref}| (reference check)")
        a.set_xlabel("modes N")
        ticks = [2, 3, 5, 10, 20, 40, 80]
        a.set_xticks(ticks)
        a.set_xticklabels([str(t) for t in ticks])
        a.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        a.set_title(f"{which} scene: steady-state peak tip deflection")
        a.grid(True, which="both", alpha=0.3)
    ax[0].set_ylabel(f"|P_N - P_ref| / P_ref   (ref: FIM, N = {nref})")
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "convergence.png", dpi=120)
    plt.close(fig)
    return results, conv, hist, peak_check


def section_peaks(cfg, hist, out: Path):
    t_end = cfg["t_conv"]
    rows = []
    per = {}
    for which in ("hard", "very_hard"):
        T = 2 * math.pi / forcing_omega(load_scene(which))
        gap = float(load_scene(which)["stops"][0]["gap"])
        ns = cfg["hist_n"] if which == "hard" else cfg["vh_n"]
        for m in METHODS:
            for n in ns:
                key = (which, m, "inherited", n)
                if key not in hist:
                    continue
                if "failed" in hist[key]:
                    per[key] = {"scene": which, "method": m, "modes": n, "failed": hist[key]["failed"]}
                    rows.append(per[key])
                    continue
                h = hist[key]["h"]
                np_ = cfg["n_periods_count"]
                sel = window(h, t_end - np_ * T, t_end)
                w = h["tip.w"][sel]
                rng = float(w.max() - w.min())
                all_max, _ = find_peaks(w)
                prom_max, _ = find_peaks(w, prominence=0.01 * rng)
                c = np.asarray(hist[key]["contacts"])
                tw0 = t_end - np_ * T
                n_con = int(np.sum(c >= tw0))
                # contacts per period, each of the last np_ periods
                per_p = [int(np.sum((c >= t_end - (j + 1) * T) & (c < t_end - j * T))) for j in range(np_)]
                frac = float(np.mean(h["stop.contact"][sel] > 0))
                # contact phases in the window, paired in the order beamstop reports the events
                longest, t_on, n_zero = 0.0, None, 0
                if h["stop.contact"][sel][0] > 0:
                    t_on = tw0
                for t, e in hist[key]["sequence"]:
                    if t < tw0:
                        continue
                    if e == 1:
                        t_on = t
                    elif t_on is not None:
                        longest = max(longest, t - t_on)
                        n_zero += (t - t_on) <= 1e-12
                        t_on = None
                if t_on is not None:
                    longest = max(longest, t_end - t_on)
                # "sticking" seen from the tip: within 1e-3 gap of the stop (or pressed into it)
                near = h["tip.w"][sel] >= gap * (1.0 - 1e-3)
                run_, best_run = 0, 0
                for x in near:
                    run_ = run_ + 1 if x else 0
                    best_run = max(best_run, run_)
                dt_s = float(np.median(np.diff(h["time"][sel])))
                row = {"scene": which, "method": m, "modes": n, "periods": np_,
                       "maxima_per_period": len(all_max) / np_, "prominent_maxima_per_period": len(prom_max) / np_,
                       "contacts_per_period": n_con / np_, "contacts_per_period_min": min(per_p),
                       "contacts_per_period_max": max(per_p), "contact_time_fraction": frac,
                       "longest_contact_over_T": longest / T,
                       "zero_length_contacts_per_period": n_zero / np_,
                       "near_stop_fraction": float(np.mean(near)), "longest_near_stop_over_T": best_run * dt_s / T,
                       "events_in_run": hist[key]["events"],
                       "run_ms": hist[key]["ms"], "failed": ""}
                rows.append(row)
                per[key] = row
    hdr = list(next(r for r in rows if not r["failed"]).keys())
    write_csv(out / "peaks_contacts.csv", hdr, [[r.get(k, "") for k in hdr] for r in rows])
    return per


def section_histories(cfg, hist, out: Path):
    t_end = cfg["t_conv"]
    T = 2 * math.pi / forcing_omega(load_scene("hard"))
    nref = cfg["nref"]
    gap = float(load_scene("hard")["stops"][0]["gap"])
    fig, ax = plt.subplots(2, 2, figsize=(13, 7.5), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    rows_out = {}
    diffs = {}
    kref = ("hard", "fim", "inherited", nref)
    for col, n in enumerate((5, 20)):
        a, ad = ax[0, col], ax[1, col]
        curves = [(kref, f"FIM, {nref} modes (reference)", dict(color="0.6", lw=3)),
                  (("hard", "fim", "inherited", n), f"FIM, {n} modes", dict(color="C0", lw=1.4)),
                  (("hard", "rmtm", "inherited", n), f"RMTM, {n} modes, inherited damping", dict(color="C2", lw=1.2, ls="--")),
                  (("hard", "rmtm", "modal", n), f"RMTM, {n} modes, modal damping (the paper's)", dict(color="C3", lw=1.0, ls=":"))]
        href = hist[kref]["h"]
        sref = window(href, t_end - 3 * T, t_end)
        for key, lab, kw in curves:
            if key not in hist:
                continue
            h = hist[key]["h"]
            sel = window(h, t_end - 3 * T, t_end)
            a.plot(h["time"][sel], h["tip.w"][sel] * 1e3, label=lab, **kw)
            if key != kref:
                ad.plot(h["time"][sel], (h["tip.w"][sel] - href["tip.w"][sref]) / gap, label=lab, **kw)
            rows_out[(key[1], key[2], key[3])] = (h["time"][sel], h["tip.w"][sel])
        a.axhline(gap * 1e3, color="k", lw=0.8, ls="-.", label="gap")
        a.set_ylabel("tip deflection [mm]")
        a.set_title(f"hard scene, last 3 forcing periods before t = {t_end:g} s, N = {n}")
        a.legend(fontsize=7, loc="lower left")
        a.grid(alpha=0.3)
        ad.set_ylabel(f"(tip_w - tip_w(FIM, {nref})) / gap")
        ad.set_xlabel("t [s]")
        ad.grid(alpha=0.3)
        kf, kr = ("hard", "fim", "inherited", n), ("hard", "rmtm", "inherited", n)
        if kf in hist and kr in hist:
            hf, hr = hist[kf]["h"], hist[kr]["h"]
            sf, sr = window(hf, t_end - 3 * T, t_end), window(hr, t_end - 3 * T, t_end)
            diffs[n] = float(np.max(np.abs(hf["tip.w"][sf] - hr["tip.w"][sr]))) / gap
    fig.tight_layout()
    fig.savefig(out / "histories_hard.png", dpi=110)
    plt.close(fig)
    # CSV of the plotted curves on the common grid
    keys = sorted(rows_out)
    if keys:
        t = rows_out[keys[0]][0]
        cols = [t] + [rows_out[k][1] for k in keys]
        hdr = ["time"] + [f"tip_w_{m}_{td}_N{n}" for (m, td, n) in keys]
        write_csv(out / "histories_hard.csv", hdr, np.column_stack(cols).tolist())
    return diffs


# ----------------------------------------------------------------- section 5

def section_runtime(R: Runner, cfg, out: Path):
    rows = []
    combos = [(n, m, td) for n in cfg["rt_n"]
              for m, td in (("fim", None), ("mtm", "inherited"), ("rmtm", "inherited"), ("mtm", "modal"), ("rmtm", "modal"))]
    timed = R.timed_many([variant("hard", n=n, method=m, td=td, t_end=0.5, step=1e-2) for n, m, td in combos],
                         cfg["reps"])
    for (n, m, td), r in zip(combos, timed):
        rows.append({"method": m, "transfer_damping": td or "-", "modes": n, "ms": r["ms"],
                     "ms_min": min(r["ms_all"]), "ms_max": max(r["ms_all"]),
                     "switches": r["switches"], "evals": r["evals"]})
    hdr = list(rows[0].keys())
    write_csv(out / "runtime_methods.csv", hdr, [[r[k] for k in hdr] for r in rows])
    return rows


# ----------------------------------------------------------------- section 6

def section_reference(R: Runner, cfg, out: Path, ref):
    gap = float(load_scene("hard")["stops"][0]["gap"])
    t_end, dt = 0.5, 1e-4
    rows = []
    for which in ("soft", "hard"):
        for n in cfg["ref_n"]:
            sc = variant(which, n=n, method="fim", t_end=t_end, step=dt)
            b = R.run(sc)
            bt = R.timed(sc, cfg["reps"])["ms"]
            h = b["h"]
            r = ref.simulate(copy.deepcopy(load_scene(which)), n, t_end, dt, rtol=cfg["ref_rtol"])
            r2 = ref.simulate(copy.deepcopy(load_scene(which)), n, t_end, dt, rtol=cfg["ref_check_rtol"])
            assert len(r["t"]) == len(h["time"]) and np.max(np.abs(r["t"] - h["time"])) < 1e-12
            err = float(np.max(np.abs(h["tip.w"] - r["tip_w"]))) / gap
            self_err = float(np.max(np.abs(r2["tip_w"] - r["tip_w"]))) / gap
            on_b, on_r = b["contacts"], np.asarray(r["onsets"])
            dton = float(np.max(np.abs(on_b - on_r))) if len(on_b) == len(on_r) and len(on_b) else float("nan")
            rows.append({"scene": which, "modes": n, "err_over_gap": err, "ref_self_err_over_gap": self_err,
                         "contacts_beamstop": len(on_b), "contacts_reference": len(on_r),
                         "max_abs_d_onset_s": dton, "beamstop_ms": bt,
                         "reference_s": float(r["run_time"]), "reference_check_s": float(r2["run_time"]),
                         "reference_steps": int(r["n_steps"]), "pass_1e-9": err <= 1e-9})
            log(f"  {which} N={n}: |beamstop - reference| = {err:.2e} gap, reference self {self_err:.1e} gap")
    hdr = list(rows[0].keys())
    write_csv(out / "reference_check.csv", hdr, [[r[k] for k in hdr] for r in rows])

    # work-precision: hard, 5 modes
    n = 5
    sc = variant("hard", n=n, method="fim", t_end=t_end, step=dt)
    b = R.run(sc)
    b_ms = R.timed(sc, cfg["reps"])["ms"]
    b_ms_coarse = R.timed(variant("hard", n=n, method="fim", t_end=t_end, step=1e-2), cfg["reps"])["ms"]
    wp = []
    for rt in cfg["wp_rtols"]:
        r = ref.simulate(copy.deepcopy(load_scene("hard")), n, t_end, dt, rtol=rt)
        err = float(np.max(np.abs(b["h"]["tip.w"] - r["tip_w"]))) / gap
        on = np.asarray(r["onsets"])
        # the first beamstop contact the reference does not reproduce (within 1e-6 s); later ones follow from it
        missed = [(t, v) for t, v in zip(b["contacts"], b["contact_speed"])
                  if not len(on) or np.min(np.abs(on - t)) > 1e-6][:1]
        extra = [t for t in on if not len(b["contacts"]) or np.min(np.abs(b["contacts"] - t)) > 1e-6]
        wp.append({"rtol": rt, "run_time_s": float(r["run_time"]), "err_over_gap": err,
                   "contacts": len(on), "steps": int(r["n_steps"]),
                   "missed_contacts": " ".join(f"t = {t:.6f} s (impact speed {v:.2e} m/s)" for t, v in missed),
                   "extra_contacts": " ".join(f"t={t:.6f}s" for t in extra)})
        log(f"  work-precision rtol {rt:.0e}: {float(r['run_time']):.2f} s, error {err:.2e} gap")
    hdr = list(wp[0].keys())
    write_csv(out / "work_precision.csv", hdr, [[r[k] for k in hdr] for r in wp])
    fig, a = plt.subplots(figsize=(6.5, 4.5))
    xs = [w["run_time_s"] for w in wp]
    ys = [max(w["err_over_gap"], 1e-17) for w in wp]
    a.loglog(xs, ys, "o-", color="C0",
             label=f"scipy DOP853 reference, rtol {max(cfg['wp_rtols']):.0e} ... {min(cfg['wp_rtols']):.0e}")
    for w, x, y in zip(wp, xs, ys):
        if not w["missed_contacts"]:
            a.annotate(f"rtol {w['rtol']:.0e}", (x, y), textcoords="offset points", xytext=(5, -3), fontsize=7)
    miss = [(w, x, y) for w, x, y in zip(wp, xs, ys) if w["missed_contacts"]]
    if miss:
        w0, x0, y0 = min(miss, key=lambda m: m[1])
        a.annotate(f"rtol {rtol_range([m[0]['rtol'] for m in miss])}:\n"
                   f"miss the contact at\n{w0['missed_contacts']}", (x0, y0), textcoords="offset points",
                   xytext=(-150, -45), fontsize=7, arrowprops=dict(arrowstyle="->", lw=0.6))
    best = min(wp, key=lambda w: w["rtol"])
    a.loglog([b_ms / 1e3], [max(best["err_over_gap"], 1e-17)], "*", ms=14, color="C3",
             label=f"beamstop (exact FIM), 1e-4 output grid; y = distance to rtol {best['rtol']:.0e}")
    a.axvline(b_ms_coarse / 1e3, color="C3", ls=":", lw=1, label="beamstop, 1e-2 output grid")
    a.set_xlabel("run time [s]")
    a.set_ylabel("max |tip_w - tip_w(beamstop)| / gap")
    a.set_title("hard scene, 5 modes, 0.5 s from rest")
    a.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "work_precision.png", dpi=120)
    plt.close(fig)
    return {"rows": rows, "wp": wp, "b_ms": b_ms, "b_ms_coarse": b_ms_coarse}


# ----------------------------------------------------------------- summary

def build_summary(cfg, meta, s1, conv_res, conv, peaks, hdiffs, rt, s6, peak_check):
    L = []
    A = L.append
    nref, ncheck = cfg["nref"], cfg["ncheck"]
    A("# Spring stop: FIM, MTM and RMTM against the claims of the RMTM paper\n")
    A(f"Generated by `{meta['command']}` in {meta['wall_s']:.0f} s on {meta['host']} "
      f"({os.cpu_count()} cores; load average {meta['load0']:.2f} at start, {meta['load1']:.2f} at the end: "
      f"other jobs share the machine, so run times carry their noise). beamstop: `{meta['exe']}` "
      f"(built {meta['exe_mtime']}), repository HEAD {meta['head']}. "
      f"{meta['n_runs']} beamstop runs. "
      + ("**Quick smoke run: shortened runs and settings; these are not the report's figures.** " if cfg["quick"] else "")
      + "Every figure below is measured in this run.\n")
    A("Scenes: scenes/spring_stop_{soft,hard,very_hard}.json (kappa = k / (3EI/L^3) = 0.1, 100, 1e4; "
      "soft driven at Omega = omega_1, hard and very hard at 1.3 omega_1; zeta = 0.02; gap 1 mm). "
      "MTM and RMTM use `transfer_damping: \"inherited\"` (same continuum as FIM) unless marked \"modal\" "
      "(the paper's damping, zeta on each tip-spring mode). Run times are beamstop's own figure "
      "(`beamstop run`, CSV writing included), medians of "
      f"{cfg['reps']} runs (taken in rounds over the settings of a table) with a 1e-2 output step and energy "
      "outputs off.\n")

    # 1
    rows = s1["rows"]
    A("## 1. Run time and switches against stiffness\n")
    A(f"Hard scene, FIM, 20 modes, 0.5 s from rest. Switches = contacts + separations in the events CSV. "
      f"A contact-free run (gap 1 m) takes {s1['base_ms']:.2f} ms; the last column subtracts it. "
      f"Plot: `stiffness_sweep.png`; data: `stiffness_sweep.csv`.\n")
    A(md_table(["kappa", "switches", "evaluations", "run time [ms]", "ms / switch", "(ms - contact-free) / switch",
                "evaluations / switch"],
               [[f"{r['kappa']:.0e}", r["switches"], r["evals"], f"{r['ms']:.2f}", fmt(r["ms_per_switch"]),
                 fmt(r["marginal_ms_per_switch"]), fmt(r["evals_per_switch"])] for r in rows]))
    flat = [r for r in rows if 1e-2 <= r["kappa"] <= 1e8 and r["switches"]]
    if flat:
        mps = [r["ms_per_switch"] for r in flat]
        mar = [r["marginal_ms_per_switch"] for r in flat]
        eps_ = [r["evals_per_switch"] for r in flat]
        kmx = max(flat, key=lambda r: r["ms_per_switch"])["kappa"]
        kmn = min(flat, key=lambda r: r["ms_per_switch"])["kappa"]
        s1["flat"] = {"ratio_ms": max(mps) / min(mps), "ratio_marg": max(mar) / min(mar) if min(mar) > 0 else float("nan"),
                      "ratio_ev": max(eps_) / min(eps_), "ev_min": min(eps_), "ev_max": max(eps_),
                      "ms_min": min(mps), "ms_max": max(mps), "k_at_max": kmx, "k_at_min": kmn,
                      "mar_min": min(mar), "mar_max": max(mar),
                      "ms_lo_end": flat[0]["ms_per_switch"], "ms_hi_end": flat[-1]["ms_per_switch"]}
        f = s1["flat"]
        A(f"\nOver kappa = 1e-2 ... 1e8: run time per switch {fmt(f['ms_min'])} ... {fmt(f['ms_max'])} ms "
          f"(max/min {f['ratio_ms']:.1f}; largest at kappa = {f['k_at_max']:.0e}, smallest at {f['k_at_min']:.0e}), "
          f"after subtracting the contact-free run {fmt(f['mar_min'])} ... {fmt(f['mar_max'])} ms "
          f"(max/min {fmt(f['ratio_marg'])}); evaluations per switch {fmt(f['ev_min'])} ... {fmt(f['ev_max'])} "
          f"(max/min {f['ratio_ev']:.1f}).\n")

    # 2
    A("## 2. Convergence in modes\n")
    A(f"From rest to t = {cfg['t_conv']:g} s (output step {cfg['conv_step']:g} s); peak = maximum over the last 2 "
      "forcing periods of the cubic Hermite interpolant of (tip.w, tip.v) (the samples alone miss the peak by up to "
      f"{max(abs(r['sample_peak'] - r['peak']) / r['peak'] for r in conv_res.values() if math.isfinite(r['peak'])):.1e}"
      " relative"
      + "".join(f"; with a {c['step']:g} s grid, RMTM at N = 20 in the {w} scene moves by {c['rel']:.1e} (peak) and "
                f"{c['rel_pen']:.1e} (penetration), the peak-estimation error" for w, c in peak_check.items())
      + "); "
      "peak penetration likewise from (stop.penetration, stop.v). "
      f"Reference: FIM at N = {nref}. Relative differences are (P_N - P_ref) / P_ref. "
      "'Needs' = the smallest listed N from which on every listed N agrees with the reference within the tolerance. "
      "Data: `convergence.csv`; plot: `convergence.png`.\n")
    for which in ("soft", "hard"):
        c = conv[which]
        ref = c["ref"]
        A(f"### {which} scene\n")
        A(f"Reference peak tip deflection {ref['peak']:.10e} m, peak penetration {ref['peak_pen']:.6e} m. "
          f"Reference check: FIM N = {ncheck} differs by {c['ref_vs_check']:.2e} (peak) and "
          f"{c['ref_vs_check_pen']:.2e} (penetration); RMTM at N = {nref} differs from the reference by "
          f"{c['ref_vs_rmtm']:.2e}. Steady state: the peak of the last 2 periods differs from that of the 2 "
          f"periods before by {ref['drift']:.1e} (reference run), i.e. the transient from rest has not fully "
          f"decayed at this level; all runs share the same window, so the comparison in N is unaffected.\n")
        ns = sorted({n for (w, m, td, n) in conv_res if w == which and td == "inherited"})
        hdr = ["N"] + [f"{m.upper()} peak rel. diff" for m in METHODS] + [f"{m.upper()} penetration rel. diff" for m in METHODS]
        trows = []
        for n in ns:
            row = [n]
            for fld in ("rel", "rel_pen"):
                for m in METHODS:
                    r = conv_res.get((which, m, "inherited", n))
                    row.append("(ref)" if (m == "fim" and n == nref) else (f"{r[fld]:+.2e}" if r else "-"))
            trows.append(row)
        A(md_table(hdr, trows))
        A("")
        nrow = []
        for m in METHODS:
            def s(v):
                return str(v) if v is not None else f"> {max(ns)}"
            nrow.append([m.upper()] + [s(c["need"][(m, tol)]) for tol in TOLS]
                        + [s(c["need_rmtm_ref"][(m, 1e-6)])])
        A("Modes needed for a relative agreement of the peak tip deflection with the reference "
          f"(last column: with RMTM at N = {nref} as the reference instead):\n")
        A(md_table(["method"] + [f"{tol:.0e}" for tol in TOLS] + [f"1e-06 vs RMTM N={nref}"], nrow))
        A("")
        A(f"`transfer_damping: \"modal\"` (the paper's damping), relative to the FIM reference and to the same "
          f"method at N = {max(cfg['modal_n'])}:\n")
        mrows = []
        for n in cfg["modal_n"]:
            row = [n]
            for m in ("mtm", "rmtm"):
                r = conv_res[(which, m, "modal", n)]
                row += [f"{r['rel']:+.2e}", f"{r['rel_own']:+.2e}"]
            mrows.append(row)
        A(md_table(["N", "MTM modal vs FIM ref", f"MTM modal vs MTM modal N={max(cfg['modal_n'])}",
                    "RMTM modal vs FIM ref", f"RMTM modal vs RMTM modal N={max(cfg['modal_n'])}"], mrows))
        A("")

    # 3
    A("## 3. \"Two peaks in one period\" and \"sticking-chattering\"\n")
    A(f"Steady state = the last {cfg['n_periods_count']} forcing periods before t = {cfg['t_conv']:g} s "
      f"({cfg['conv_step']:g} s samples in the hard scene, {cfg['vh_step']:g} s in the very hard one). "
      "Maxima = local maxima of tip.w; prominent = prominence at least 1 % of the "
      "window's peak-to-peak range. Contacts from the events CSV; contact fraction = share of samples with "
      "stop.contact = 1; longest contact in forcing periods T. Transfer damping inherited. Data: `peaks_contacts.csv`.\n")
    for which in ("hard", "very_hard"):
        A(f"### {which.replace('_', ' ')} scene\n")
        ns = sorted({k[3] for k in peaks if k[0] == which})
        ta, tb, tc, td_ = [], [], [], []
        fails = {}
        for n in ns:
            ra, rb, rc, rd = [n], [n], [n], [n]
            for m in METHODS:
                p = peaks.get((which, m, "inherited", n))
                if p is None or p.get("failed"):
                    if p is not None:
                        fails[(m, n)] = p["failed"]
                    for r_ in (ra, rb, rc, rd):
                        r_.append("failed*" if p is not None else "-")
                    continue
                rc.append(f"{p['events_in_run']} / {p['run_ms']:.0f}")
                cp = (f"{p['contacts_per_period']:.2f}" if p["contacts_per_period_min"] == p["contacts_per_period_max"]
                      else f"{p['contacts_per_period']:.2f} [{p['contacts_per_period_min']}-{p['contacts_per_period_max']}]")
                ra.append(f"{p['prominent_maxima_per_period']:.2f} / {p['maxima_per_period']:.2f}")
                rb.append(f"{cp} ({p['zero_length_contacts_per_period']:.2f}); {p['contact_time_fraction']:.3f}; "
                          f"{p['longest_contact_over_T']:.3f}")
                rd.append(f"{p['near_stop_fraction']:.3f}; {p['longest_near_stop_over_T']:.3f}")
            ta.append(ra)
            tb.append(rb)
            tc.append(rc)
            td_.append(rd)
        A("Tip-deflection maxima per forcing period, prominent / all:\n")
        A(md_table(["N"] + [m.upper() for m in METHODS], ta))
        A("")
        A("Contacts per forcing period [min-max over the periods] (of which zero-length: contact and separation "
          "at the same instant); contact fraction; longest contact phase in forcing periods:\n")
        A(md_table(["N"] + [m.upper() for m in METHODS], tb))
        A("")
        A("Tip at the stop (tip.w >= (1 - 1e-3) gap): fraction of the samples; longest uninterrupted stretch in "
          "forcing periods:\n")
        A(md_table(["N"] + [m.upper() for m in METHODS], td_))
        A("")
        A(f"Events in the whole run (0 ... {cfg['t_conv']:g} s) / run time [ms] "
          f"({cfg['conv_step'] if which == 'hard' else cfg['vh_step']:g} s output step):\n")
        A(md_table(["N"] + [m.upper() for m in METHODS], tc))
        A("")
        for (m, n), msg in sorted(fails.items()):
            A(f"\\* {m.upper()}, N = {n}: beamstop stopped: `{msg}`  ")
        if fails:
            A("")

    # 4
    A("## 4. Time histories\n")
    A("`histories_hard.png` (data `histories_hard.csv`): hard scene, tip deflection over the last 3 forcing "
      f"periods before t = {cfg['t_conv']:g} s; FIM and RMTM (inherited) at 5 and 20 modes, RMTM with the paper's "
      f"modal damping, and FIM at {nref} modes. " +
      " ".join(f"max |FIM - RMTM| over these 3 periods at N = {n}: {d:.2e} gap." for n, d in sorted(hdiffs.items()))
      + "\n")
    A("![histories](histories_hard.png)\n")

    # 5
    A("## 5. Run time of 0.5 s of hard impact (the RMTM paper's Table 3)\n")
    A(f"Hard scene from rest, 0.5 s, output step 1e-2, medians of {cfg['reps']} (min-max in brackets). "
      "Data: `runtime_methods.csv`.\n")
    trows = []
    for r in rt:
        trows.append([r["method"].upper(), r["transfer_damping"], r["modes"], f"{r['ms']:.2f} ({r['ms_min']:.2f}-{r['ms_max']:.2f})",
                      r["switches"], r["evals"]])
    A(md_table(["method", "transfer damping", "N", "run time [ms]", "switches", "evaluations"], trows))
    A("")

    # 6
    A("## 6. Exact FIM against numerical integration\n")
    A(f"Reference: python/beamstop_tools/report/springstop_reference.py (scipy DOP853, rtol {cfg['ref_rtol']:g}, events by "
      "root finding and re-integration; written from the RMTM paper, imports nothing of beamstop). From rest, 0.5 s, "
      "common 1e-4 s grid. The reference's own accuracy estimate is its difference to a run at rtol "
      f"{cfg['ref_check_rtol']:.3g}. Done-criterion: max |tip_w(beamstop) - tip_w(reference)| <= 1e-9 gap. "
      "Data: `reference_check.csv`, `work_precision.csv`.\n")
    A(md_table(["scene", "N", "max diff / gap", "reference self-estimate / gap", "contacts beamstop / reference",
                "max |d t_contact| [s]", "beamstop [ms] (1e-4 grid)", "reference [s]", "<= 1e-9 gap"],
               [[r["scene"], r["modes"], f"{r['err_over_gap']:.2e}", f"{r['ref_self_err_over_gap']:.1e}",
                 f"{r['contacts_beamstop']} / {r['contacts_reference']}", fmt(r["max_abs_d_onset_s"]),
                 f"{r['beamstop_ms']:.2f}", f"{r['reference_s']:.2f}", "yes" if r["pass_1e-9"] else "**no**"]
                for r in s6["rows"]]))
    A("")
    A(f"Error against run time, hard scene, 5 modes (`work_precision.png`); beamstop takes {s6['b_ms']:.2f} ms "
      f"with the 1e-4 output grid, {s6['b_ms_coarse']:.2f} ms with a 1e-2 grid (medians of {cfg['reps']}).\n")
    A(md_table(["reference rtol", "run time [s]", "max diff to beamstop / gap", "contacts", "steps",
                "run time / beamstop's", "first beamstop contact the reference misses"],
               [[f"{w['rtol']:.0e}", f"{w['run_time_s']:.2f}", f"{w['err_over_gap']:.2e}", w["contacts"], w["steps"],
                 f"{w['run_time_s'] * 1e3 / s6['b_ms']:.0f}", w["missed_contacts"] or "none"] for w in s6["wp"]]))
    A("")
    A("![work-precision](work_precision.png)\n")
    return L


def findings(cfg, s1, conv_res, conv, peaks, hdiffs, rt, s6):
    """One paragraph; every figure and every verdict is computed from the results above."""
    nref = cfg["nref"]
    parts = []
    f = s1.get("flat")
    if f:
        grows = f["ms_hi_end"] > 1.5 * f["ms_lo_end"]
        if grows:
            verdict = (f"does not hold: it grows from {fmt(f['ms_lo_end'])} ms at kappa = 1e-2 to "
                       f"{fmt(f['ms_hi_end'])} ms at 1e8")
        elif f["ratio_ms"] <= 2:
            verdict = "holds (within a factor 2)"
        else:
            verdict = (f"holds in the sense that the cost does not grow with the stiffness ({fmt(f['ms_lo_end'])} ms "
                       f"at kappa = 1e-2, {fmt(f['ms_hi_end'])} ms at 1e8; largest at kappa = {f['k_at_max']:.0e}), "
                       f"but it is not flat (factor {f['ratio_ms']:.1f})")
        parts.append(
            f"**Cost per switch** (hard scene, FIM, 20 modes, 0.5 s): over kappa = 1e-2 ... 1e8 the run time per switch "
            f"ranges over {fmt(f['ms_min'])} ... {fmt(f['ms_max'])} ms (factor {f['ratio_ms']:.1f}) and the "
            f"event-function evaluations per switch over {fmt(f['ev_min'])} ... {fmt(f['ev_max'])} "
            f"(factor {f['ratio_ev']:.1f}); the claim of a cost per switch flat in kappa {verdict}.")
    cs, ch = conv["soft"], conv["hard"]
    nmax = max(k[3] for k in conv_res if k[2] == "inherited")

    def need(c, m, tol):
        v = c["need"][(m, tol)]
        return v if v is not None else math.inf

    def sneed(c, m, tol):
        v = need(c, m, tol)
        return str(v) if math.isfinite(v) else f"> {nmax}"

    def trio(c, tol):
        return f"{sneed(c, 'fim', tol)} / {sneed(c, 'mtm', tol)} / {sneed(c, 'rmtm', tol)}"

    soft_few = all(need(cs, m, 1e-3) <= 5 for m in METHODS)
    parts.append(
        f"**Soft impact** (N needed, FIM / MTM / RMTM, inherited damping): {trio(cs, 1e-3)} modes for 1e-3 of the "
        f"steady-state peak and {trio(cs, 1e-6)} for 1e-6, so the paper's 'soft impact converges with few modes' "
        + ("holds." if soft_few else "does not hold at 1e-3."))

    def order(c, tol):
        ms = sorted(METHODS, key=lambda m: (need(c, m, tol), m))
        out = ms[0].upper()
        for x, y in zip(ms, ms[1:]):
            out += (" = " if need(c, x, tol) == need(c, y, tol) else " < ") + y.upper()
        return out
    parts.append(
        f"**Hard impact** (kappa = 100): {trio(ch, 1e-3)} modes for 1e-3, {trio(ch, 1e-4)} for 1e-4 and "
        f"{trio(ch, 1e-6)} for 1e-6 "
        f"(reference FIM at N = {nref}, which differs from N = {cfg['ncheck']} by {abs(ch['ref_vs_check']):.1e} and "
        f"from RMTM at N = {nref} by {abs(ch['ref_vs_rmtm']):.1e}); the order of the methods is {order(ch, 1e-3)} at "
        f"1e-3 and {order(ch, 1e-6)} at 1e-6. The paper's 'about 20 modes (FIM), 9 (RMTM)' used a tolerance its "
        f"extraction lost; RMTM {'does' if need(ch, 'rmtm', 1e-6) < need(ch, 'fim', 1e-6) else 'does not'} need fewer "
        f"modes than FIM at 1e-6 and MTM {'is' if need(ch, 'mtm', 1e-3) >= max(need(ch, 'fim', 1e-3), need(ch, 'rmtm', 1e-3)) else 'is not'} "
        f"the slowest at 1e-3.")
    fin = [t for t in TOLS if math.isfinite(need(ch, "fim", t)) and math.isfinite(need(ch, "rmtm", t))]
    if fin:
        tb = min(fin, key=lambda t: abs(math.log(need(ch, "fim", t) / 20)) + abs(math.log(need(ch, "rmtm", t) / 9)))
        parts.append(
            f"The listed tolerance whose counts come closest to the paper's 20 (FIM) and 9 (RMTM) is {tb:.0e}: "
            f"FIM {need(ch, 'fim', tb)}, RMTM {need(ch, 'rmtm', tb)}, MTM {sneed(ch, 'mtm', tb)}.")
    r5 = conv_res.get(("hard", "rmtm", "inherited", 5))
    f5 = conv_res.get(("hard", "fim", "inherited", 5))
    f20 = conv_res.get(("hard", "fim", "inherited", 20))
    if r5 and f20 and f5:
        parts.append(
            f"RMTM at 5 modes is {abs(r5['rel']):.1e} from the reference (FIM at 5: {abs(f5['rel']):.1e}, FIM at 20: "
            f"{abs(f20['rel']):.1e}), so 'RMTM with 5 modes gives FIM's 20-mode result' "
            + ("does not hold for the peak." if abs(r5["rel"]) > 3 * abs(f20["rel"]) else "holds for the peak."))
    if 5 in hdiffs and 20 in hdiffs:
        parts.append(
            f"Over the last 3 periods FIM and RMTM differ by up to {hdiffs[5]:.1e} gap at 5 modes and {hdiffs[20]:.1e} "
            f"gap at 20 (the paper: 'completely different' at 5, 'consistent' at 20).")
    pm = [peaks[k] for k in peaks if k[0] == "hard" and k[3] >= 10 and not peaks[k].get("failed")]
    if pm:
        vals = sorted({round(p["prominent_maxima_per_period"], 2) for p in pm})
        cps = sorted({round(p["contacts_per_period"], 2) for p in pm})
        lng = max(p["longest_contact_over_T"] for p in pm)
        parts.append(
            f"In the hard scene at N >= 10 every method shows {', '.join(f'{v:.2f}' for v in vals)} prominent tip "
            f"maxima and {', '.join(f'{v:.2f}' for v in cps)} contacts per forcing period, "
            + ("so 'two peaks in one period' holds" if vals == [2.0] else "so 'two peaks in one period' does not hold as such")
            + f"; the longest contact lasts {lng:.3f} T, i.e. no sticking phase.")
    vh = {(k[1], k[3]): p for k, p in peaks.items() if k[0] == "very_hard"}
    if vh:
        def cp(m, n):
            p = vh.get((m, n))
            if p is None:
                return "-"
            if p.get("failed"):
                return "failed"
            return (f"{p['contacts_per_period']:.2f} contacts/T, longest contact {p['longest_contact_over_T']:.3f} T, "
                    f"longest stretch at the stop {p['longest_near_stop_over_T']:.3f} T")
        nshow = sorted({5, 20, max(n for (_, n) in vh)} & {n for (_, n) in vh})
        txt = "; ".join(f"{m.upper()}: " + ", ".join(f"{cp(m, n)} at N = {n}" for n in nshow) for m in METHODS)
        stuck = [(m, n) for (m, n), p in vh.items() if not p.get("failed") and p["contact_time_fraction"] > 0.99]
        failed = sorted((m, n) for (m, n), p in vh.items() if p.get("failed"))
        zeno = sorted((m, n) for (m, n), p in vh.items() if not p.get("failed") and p["events_in_run"] > 1e5)
        zeno_txt = ", ".join(f"{m.upper()} N = {n} ({vh[(m, n)]['events_in_run']} events)" for m, n in zeno)
        parts.append(
            f"**Very hard impact** (kappa = 1e4), steady state: {txt}."
            + (f" MTM reports contact through the whole window at N = "
               f"{', '.join(str(n) for (m, n) in sorted(stuck) if m == 'mtm')} (contact fraction > 0.99) while its tip "
               f"stays below the stop (tip at the stop in at most "
               f"{max(vh[(m, n)]['near_stop_fraction'] for (m, n) in stuck if m == 'mtm'):.3f} of the samples): "
               "its contact phase never ends, a method artefact and not sticking."
               if any(m == "mtm" for m, _ in stuck) else "")
            + (f" Runs that stopped (more than a million switches within one output step, i.e. Zeno chattering): "
               f"{', '.join(f'{m.upper()} N = {n}' for m, n in failed)}." if failed else "")
            + (f" Runs with more than 1e5 switches in {cfg['t_conv']:g} s: "
               f"{zeno_txt}."
               if zeno else "")
            + (" (The paper reports that its RMTM 'encountered problem in finding proper zero-crossing point' at 6 "
               "modes.)" if any(m == "rmtm" for m, _ in failed + zeno) else ""))
        conv_vh = [p for (m, n), p in vh.items() if m in ("fim", "rmtm") and n >= 15 and not p.get("failed")]
        if conv_vh:
            st = max(p["longest_near_stop_over_T"] for p in conv_vh)
            cps = sorted({round(p["contacts_per_period"], 2) for p in conv_vh})
            parts.append(
                f"At N >= 15 FIM and RMTM give {', '.join(f'{c:.2f}' for c in cps)} contacts per period and the tip "
                f"never stays at the stop longer than {st:.3f} T: "
                + ("chattering, but no sticking phase, so the paper's 'sticking-chattering' pattern is not reproduced "
                   "in the very hard scene." if st < 0.1 else "a sticking phase is present."))
    if rt:
        d = {(r["method"], r["transfer_damping"], r["modes"]): r["ms"] for r in rt}
        dmin = {(r["method"], r["transfer_damping"], r["modes"]): r["ms_min"] for r in rt}
        n20 = {k: v for k, v in d.items() if k[2] == 20}
        fastest = min(n20, key=n20.get)
        inh = [d[("fim", "-", 20)], d[("mtm", "inherited", 20)], d[("rmtm", "inherited", 20)]]
        inh_min = [dmin[("fim", "-", 20)], dmin[("mtm", "inherited", 20)], dmin[("rmtm", "inherited", 20)]]
        modal = [d[("mtm", "modal", 20)], d[("rmtm", "modal", 20)]]
        parts.append(
            f"**Table 3** (0.5 s of hard impact, 20 modes): FIM {d[('fim', '-', 20)]:.2f} ms, MTM "
            f"{d[('mtm', 'inherited', 20)]:.2f} / {d[('mtm', 'modal', 20)]:.2f} ms, RMTM "
            f"{d[('rmtm', 'inherited', 20)]:.2f} / {d[('rmtm', 'modal', 20)]:.2f} ms (inherited / modal damping): "
            f"with inherited damping the three medians are within {100 * (max(inh) / min(inh) - 1):.0f} % of each other "
            f"(the fastest of the {cfg['reps']} runs within {100 * (max(inh_min) / min(inh_min) - 1):.0f} %), with the "
            f"paper's modal damping MTM and RMTM take {max(modal) / d[('fim', '-', 20)]:.2f} of FIM's time or less; "
            + ("FIM is the fastest, as the paper says." if fastest[0] == "fim" else
               f"the fastest is {fastest[0].upper()} ({fastest[1]} damping), so the paper's 'FIM is the fastest' does not hold here."))
    if s6:
        worst = max(r["err_over_gap"] for r in s6["rows"])
        same = all(r["contacts_beamstop"] == r["contacts_reference"] for r in s6["rows"])
        parts.append(
            f"**Against numerical integration**: exact FIM agrees with the independent scipy reference to "
            f"{worst:.1e} of the gap at worst (soft and hard, N = {', '.join(str(n) for n in cfg['ref_n'])}; "
            + ("done-criterion 1e-9 met" if worst <= 1e-9 else "done-criterion 1e-9 **not** met")
            + f"), with {'equal' if same else '**different**'} contact counts; the reference takes "
            f"{min(w['run_time_s'] for w in s6['wp']):.2f} ... {max(w['run_time_s'] for w in s6['wp']):.2f} s "
            f"(rtol {max(cfg['wp_rtols']):.0e} ... {min(cfg['wp_rtols']):.0e}, hard, 5 modes) for what beamstop does "
            f"in {s6['b_ms']:.1f} ms"
            + (f"; at rtol {rtol_range([w['rtol'] for w in s6['wp'] if w['missed_contacts']])} it misses the contact at "
               f"{next(w['missed_contacts'] for w in s6['wp'] if w['missed_contacts'])} and is then "
               f"{max(w['err_over_gap'] for w in s6['wp'] if w['missed_contacts']):.2f} gap off."
               if any(w["missed_contacts"] for w in s6["wp"]) else "."))
    return " ".join(parts)


# ----------------------------------------------------------------- main

def config(quick: bool) -> dict:
    if quick:
        return dict(quick=True, reps=1, kappas=[1e-2, 1e2, 1e6, 1e10], t_conv=0.5, nlist=[3, 5, 10, 20],
                    nref=30, ncheck=20, modal_n=[5, 10, 20], conv_step=1e-4, check_step=5e-5, vh_step=1e-4,
                    hist_n=[5, 10, 20], vh_n=[5, 20], n_periods_count=4,
                    rt_n=[5, 20], ref_n=[5], ref_rtol=1e-11, ref_check_rtol=1e-10, wp_rtols=[1e-6, 1e-8])
    return dict(quick=False, reps=5, kappas=[10.0 ** e for e in range(-2, 13)], t_conv=4.0,
                nlist=[2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 40, 60], nref=80, ncheck=60,
                conv_step=5e-5, check_step=2e-5, vh_step=1e-4,
                modal_n=[5, 10, 20, 40, 80], hist_n=[5, 10, 20, 40], vh_n=[2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 40],
                n_periods_count=10, rt_n=[5, 10, 20], ref_n=[5, 20], ref_rtol=1e-13,
                ref_check_rtol=100 * np.finfo(float).eps, wp_rtols=[10.0 ** -e for e in range(6, 14)])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke run (< 1 min); not the report's figures")
    ap.add_argument("--out", default=None, help="output folder (default report/spring_stop, or "
                                                 "target/report-quick/spring_stop with --quick, git-ignored)")
    ap.add_argument("--bin", default=str(engine.binary()),
                    help="the beamstop executable (default $BEAMSTOP_BIN or target/release/beamstop)")
    a = ap.parse_args(argv)
    cfg = config(a.quick)
    out = out_dir(a.out, "spring_stop", a.quick)
    out.mkdir(parents=True, exist_ok=True)
    T0 = time.perf_counter()
    load0 = os.getloadavg()[0]
    R = Runner(a.bin)
    try:
        log("1. run time against stiffness")
        s1 = section_stiffness(R, cfg, out)
        log("2. convergence in modes (and histories for 3, 4)")
        conv_res, conv, hist, peak_check = section_convergence(R, cfg, out)
        log("3. maxima and contacts per period")
        peaks = section_peaks(cfg, hist, out)
        log("4. time histories")
        hdiffs = section_histories(cfg, hist, out)
        del hist
        log("5. run time per method")
        rt = section_runtime(R, cfg, out)
        log("6. exact FIM against the scipy reference")
        s6 = section_reference(R, cfg, out, springstop_reference)
    finally:
        R.close()
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              cwd=ROOT).stdout.strip() or "?"
    except OSError:
        head = "?"
    cmd = "python -m beamstop_tools.report.springstop" + (" --quick" if a.quick else "") + (
        f" --bin {a.bin}" if a.bin != str(engine.binary()) else "")
    meta = {"command": cmd, "wall_s": time.perf_counter() - T0, "host": os.uname().nodename, "load0": load0,
            "load1": os.getloadavg()[0], "exe": a.bin,
            "exe_mtime": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(os.path.getmtime(a.bin))),
            "head": head, "n_runs": R.n_runs}
    lines = build_summary(cfg, meta, s1, conv_res, conv, peaks, hdiffs, rt, s6, peak_check)
    lines.insert(3, "## Findings\n\n" + findings(cfg, s1, conv_res, conv, peaks, hdiffs, rt, s6) + "\n")
    with open(out / "summary.md", "w") as fh:
        fh.write("\n".join(lines) + "\n")
    log(f"wrote {out} in {time.perf_counter() - T0:.0f} s")


if __name__ == "__main__":
    main()
