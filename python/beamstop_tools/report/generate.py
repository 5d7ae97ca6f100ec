"""Regenerates report/: `python -m beamstop_tools.report.generate [--quick] [--out DIR]`
(normally through scripts/report, which builds beamstop and its FMUs first).
With --quick (a smoke run: fewer settings, 30-digit references) it writes to
the git-ignored target/report-quick/ instead.
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import glob  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

from . import plots, references, runs, studies, summary  # noqa: E402
from .common import log, out_dir, write_csv  # noqa: E402
from .. import ROOT  # noqa: E402
from .models import scenes  # noqa: E402

S1_HORIZON = 3.0
T_FIXED = 1.5  # S2 truncation: w at the stop in free flight for every N


class Settings:
    def __init__(self, quick: bool):
        self.quick = quick
        if quick:
            self.tolerances = [0.0, 1e-6]
            self.native_steps = [0.0, 0.01]
            self.native_repeats = 2
            self.fmu_repeats = 1
            self.scipy_timed_runs = 1
            self.methods = {"RK45": [1e-3], "DOP853": [1e-3], "Radau": [1e-3], "LSODA": [1e-3]}
            self.kps_beam, self.fine_beam = [1e4, 1e5], None
            self.kps_chain, self.fine_chain = [1e2, 1e3], None
            self.eps_values = [1e-4, 1e-6, 1e-8]
            self.Ns = [2, 4, 8, 16, 32]
        else:
            self.tolerances = [0.0, 1e-12, 1e-9, 1e-6, 1e-3]
            self.native_steps = [0.0, 0.01]
            self.native_repeats = 20
            self.fmu_repeats = 5
            self.scipy_timed_runs = 3
            rt = [10.0**-k for k in range(3, 13)]
            self.methods = {"RK45": rt, "DOP853": rt, "Radau": rt[:8], "LSODA": rt}
            self.kps_beam, self.fine_beam = [1e4, 1e5, 1e6, 1e7], 1e6
            self.kps_chain, self.fine_chain = [1e2, 1e3, 1e4, 1e5, 1e6], 1e4
            self.eps_values = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
            self.Ns = [2, 4, 8, 16, 32, 64, 128, 200]

    def fmu_steps(self, scene):
        if scene.kind == "chain":
            return [scene.t_end, 0.1] if self.quick else [scene.t_end, 0.1, 0.01]
        return [scene.t_end, 0.01] if self.quick else [scene.t_end, 0.01, 0.001]


COLUMNS = ["scene", "family", "method", "setting", "rtol", "atol", "event_tolerance", "step", "k_p", "h",
           "wall_time_s", "timing", "work", "n_impacts", "n_impacts_ref", "n_sticks", "err_events", "err_stick",
           "err_final", "err_dense", "note"]


def slug(s):
    return "".join(c if c.isalnum() else "_" for c in s).strip("_").replace("__", "_")


def machine():
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import fmpy
    import matplotlib
    import mpmath
    import numpy
    import scipy

    import subprocess

    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "src", "Cargo.toml", "Cargo.lock", "build.rs",
                                "scenes"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
        commit = head + (" with uncommitted changes to the crate" if dirty else " (crate sources clean)")
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown (no git)"
    return {
        "commit": commit,
        "cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "numpy": numpy.__version__,
        "scipy": scipy.__version__, "matplotlib": matplotlib.__version__, "mpmath": mpmath.__version__,
        "fmpy": fmpy.__version__, "platform": platform.platform(),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="a fast smoke run (< 1 min): fewer settings, 30-digit references")
    ap.add_argument("--out", default=None, help="output folder (default: report/ of the repository, "
                                               "target/report-quick/ with --quick)")
    args = ap.parse_args(argv)
    T0 = time.perf_counter()
    cfg = Settings(args.quick)
    out = str(out_dir(args.out, "", args.quick))
    os.makedirs(out, exist_ok=True)
    for pat in ("*.csv", "*.png", "summary.md"):
        for f in glob.glob(os.path.join(out, pat)):
            os.remove(f)
    sc = scenes(S1_HORIZON)
    phases = {}

    log("references")
    t = time.perf_counter()
    refs = {k: references.build(s, quick=args.quick, log=log) for k, s in sc.items()}
    phases["references and cross-checks"] = time.perf_counter() - t

    rows, native_raw, fmu_raw = [], {}, {}
    log("beamstop (native and FMU)")
    t = time.perf_counter()
    for k, s in sc.items():
        r, native_raw[k] = runs.beamstop_native(s, refs[k], cfg.tolerances, cfg.native_steps, cfg.native_repeats, log)
        rows += r
        r, fmu_raw[k] = runs.beamstop_fmu(s, refs[k], cfg.fmu_steps(s), cfg.fmu_repeats, log)
        rows += r
    stepind = {k: runs.step_independence(s, native_raw[k], fmu_raw[k]) for k, s in sc.items()}
    phases["beamstop native and FMU"] = time.perf_counter() - t

    log("scipy solve_ivp with events")
    t = time.perf_counter()
    for k, s in sc.items():
        rows += runs.scipy_sweep(s, refs[k], cfg.methods, log, timed_runs=cfg.scipy_timed_runs)

    overhead = runs.dense_overhead(sc["S2"]) if not args.quick else {}
    phases["scipy sweeps"] = time.perf_counter() - t
    allimp = {}
    for k, s in sc.items():
        o = native_raw[k].get((0.0, 0.0))
        if o:
            allimp[k] = runs.all_impacts_error(s, refs[k], o) + (len(o["impacts"]),)

    log("penalty stop, RK4")
    t = time.perf_counter()
    for k, s in sc.items():
        if s.kind == "chain":
            st = runs.penalty_settings(s, cfg.kps_chain, cfg.fine_chain)
        else:
            st = runs.penalty_settings(s, cfg.kps_beam, cfg.fine_beam)
        rows += runs.penalty_sweep(s, refs[k], st, log)
    phases["penalty sweeps"] = time.perf_counter() - t

    log("side studies")
    t = time.perf_counter()
    eps_rows = studies.eps_sweep(sc["S3"], refs["S3"], cfg.eps_values, log)
    trunc, rdep, tchecks = studies.truncation(sc["S2"], cfg.Ns, T_FIXED, args.quick, log)
    phases["eps sweep and modal truncation"] = time.perf_counter() - t

    measures = ["err_events", "err_final", "err_dense"]
    ratios = studies.speed_ratio(rows, ["S1", "S2", "S3"], measures)
    ratios_s4 = studies.speed_ratio(rows, ["S4"], measures)
    dom = studies.dominance(rows, ["S1", "S2", "S3"], measures + ["err_stick"])
    dom_s4 = studies.dominance(rows, ["S4"], measures)

    log("writing CSV and PNG")
    t = time.perf_counter()
    for k in sc:
        methods = sorted({r["method"] for r in rows if r["scene"] == k})
        for m in methods:
            write_csv(os.path.join(out, f"{k}_{slug(m)}.csv"), COLUMNS,
                      [r for r in rows if r["scene"] == k and r["method"] == m])
        ref = refs[k]
        with open(os.path.join(out, f"{k}_reference.csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["event", "index", "time"])
            for i, x in enumerate(ref.releases):
                w.writerow(["release", i + 1, repr(x)])
            for i, x in enumerate(ref.impacts):
                w.writerow(["impact", i + 1, repr(x)])
            for i, x in enumerate(ref.sticks):
                w.writerow(["stick", i + 1, repr(x)])
            for i, x in enumerate(ref.final):
                w.writerow(["final_state", i + 1, repr(float(x))])
    write_csv(os.path.join(out, "S3_eps_sweep.csv"),
              ["eps", "wall_time_s", "n_impacts", "first_sequence_impacts", "last_interval", "stick_1",
               "stick_1_minus_ref", "n_sticks", "note"], eps_rows)
    tr_rows = []
    ref_tr = trunc[-1]
    for tr in trunc:
        row = {"N": tr["N"], "wall_time_s": tr["wall_time_s"], "n_impacts": tr["n_impacts"], "n_sticks": tr["n_sticks"],
               "t_fixed": tr["t_fixed"], "w_fixed": tr["w_fixed"],
               "w_fixed_minus_Nmax": tr["w_fixed"] - ref_tr["w_fixed"]}
        for i in range(4):
            row[f"impact_{i + 1}"] = tr["impacts"][i] if len(tr["impacts"]) > i else math.nan
        tr_rows.append(row)
    write_csv(os.path.join(out, "truncation.csv"),
              ["N", "wall_time_s", "n_impacts", "n_sticks", "impact_1", "impact_2", "impact_3", "impact_4", "t_fixed",
               "w_fixed", "w_fixed_minus_Nmax"], tr_rows)
    write_csv(os.path.join(out, "truncation_restitution.csv"),
              ["N", "R", "eps", "n_impacts", "n_sticks", "w_fixed", "w_final"], rdep)
    sr_rows = []
    for r in ratios + ratios_s4:
        for x in r["all"]:
            sr_rows.append(dict(x, scene=r["scene"], measure=r["measure"], target=r["target"]))
    write_csv(os.path.join(out, "speed_ratio.csv"),
              ["scene", "measure", "target", "error", "scipy", "t_scipy", "beamstop", "t_beamstop", "err_beamstop",
               "ratio"], sr_rows)
    for k, s in sc.items():
        plots.scene_figure(rows, s, os.path.join(out, f"{k}.png"),
                           "error in release + first chatter impacts" if k == "S3"
                           else f"error in the first {min(s.k_impacts, len(refs[k].impacts))} impact times")
    plots.truncation_figure(trunc, os.path.join(out, "truncation.png"))
    phases["CSV and PNG"] = time.perf_counter() - t

    total = time.perf_counter() - T0
    text = summary.build(
        quick=args.quick, scenes=sc, refs=refs, rows=rows, ratios=ratios, ratios_s4=ratios_s4, dominance=dom,
        dominance_s4=dom_s4, eps_rows=eps_rows, trunc=trunc, rdep=rdep, tchecks=tchecks, stepind=stepind,
        phases=phases, total=total, machine=machine(), cfg=cfg, argv=sys.argv[1:], overhead=overhead, allimp=allimp,
    )
    with open(os.path.join(out, "summary.md"), "w") as f:
        f.write(text)
    log(f"done in {total:.0f} s: {out}/summary.md")


if __name__ == "__main__":
    main()
