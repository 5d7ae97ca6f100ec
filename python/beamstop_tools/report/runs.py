"""Running every method on a scene and scoring it against the reference."""
from __future__ import annotations

import math
import time

import numpy as np

from . import native, penalty
from .eventode import EventSolver
from .metrics import errors


def _row(scene, family, method, label, wall, timing, res, **kw):
    row = {
        "scene": scene.key, "family": family, "method": method, "setting": label,
        "rtol": "", "atol": "", "event_tolerance": "", "step": "", "k_p": "", "h": "",
        "wall_time_s": wall, "timing": timing, "work": "", "note": "",
    }
    row.update(kw)
    row.update(res)
    return row


# ---- beamstop, native ---------------------------------------------------------------

def beamstop_native(scene, ref, tolerances, steps, repeats, log=print):
    rows, raw = [], {}
    for tol in tolerances:
        for step in steps:
            dense_dt = scene.dense_dt
            out = native.measure(scene, event_tolerance=tol, step=step, repeats=repeats, dense_dt=dense_dt)
            label = f"event_tolerance={tol:g}, step={'one call' if step == 0 else f'{step:g}'}"
            if "error" in out:
                rows.append(_row(scene, "beamstop", "beamstop native", label, math.nan, "", {},
                                 event_tolerance=tol, step=step, note="error: " + out["error"]))
                continue
            raw[(tol, step)] = out
            dt = out["dense"]["t"] if dense_dt > 0 else None
            res = errors(scene, ref, out["impacts"], out["sticks"], out["releases"], native.native_final(scene, out),
                         dt, out["dense"]["w"] if dt else None)
            note = ""
            rows.append(_row(scene, "beamstop", "beamstop native", label, out["wall_time_s"],
                             f"median of {repeats} after a warm-up", res, event_tolerance=tol, step=step,
                             work=f"{out['stats']['probes']} probes, {out['stats']['events']} events", note=note))
    log(f"  beamstop native {scene.key}: {len(rows)} runs")
    return rows, raw


def step_independence(scene, raw_native, fmu_raw):
    """Impact times and final state of the runs that should be identical:
    one call, stepped at the dense grid, stepped at 0.01 (native) and the
    FMU at each step size."""
    one = native.measure(scene, event_tolerance=0.0, step=0.0, repeats=1, dense_dt=0.0)
    base_imp = np.array(one["impacts"])
    base_fin = native.native_final(scene, one)
    res = []

    def cmp(name, imp, fin):
        imp = np.asarray(imp)
        if len(imp) != len(base_imp):
            res.append((name, f"{len(imp)} impacts vs {len(base_imp)}", math.nan, math.nan))
            return
        di = float(np.max(np.abs(imp - base_imp))) if len(imp) else 0.0
        df = float(np.max(np.abs(np.asarray(fin) - base_fin)))
        res.append((name, "same count", di, df))

    for (tol, step), out in raw_native.items():
        if tol != 0.0:
            continue
        name = f"native, {'stepped at the dense grid ' + str(scene.dense_dt) if step == 0 else 'step ' + str(step)}"
        cmp(name, out["impacts"], native.native_final(scene, out))
    for h, out in fmu_raw.items():
        cmp(f"FMU, h = {h:g}", out["impacts"], out["final"])
    return res


# ---- beamstop FMU through fmpy ----------------------------------------------------------

def beamstop_fmu(scene, ref, steps, repeats, log=print):
    rows, raw = [], {}
    runner = native.FmuRunner(scene)
    for h in steps:
        r = runner.run(h, repeats=repeats)
        raw[h] = r
        dense = r["steps"] >= 10
        res = errors(scene, ref, r["impacts"], r["sticks"], r["releases"], r["final"],
                     r["grid"] if dense else None, r["w"] if dense else None)
        label = f"h={h:g}" + (" (one doStep)" if r["steps"] == 1 else "")
        rows.append(_row(scene, "beamstop", "beamstop FMU (fmpy)", label, r["wall_time_s"],
                         f"median of {repeats} doStep loops after a warm-up", res, step=h,
                         work=f"{r['steps']} doStep + getReal", note="" if dense else "no dense grid (one step)"))
    log(f"  beamstop FMU {scene.key}: {len(rows)} runs")
    return rows, raw


# ---- scipy solve_ivp with events --------------------------------------------------------

LOW_OVERHEAD_DENSE = ("Radau",)  # dense output costs Radau ~2 % (measured in each run, see summary)


def scipy_sweep(scene, ref, methods, log=print, timed_runs=3):
    """Every method at each of its rtols: one run with dense output for the
    errors, then up to `timed_runs` timed runs (while they take under 1 s
    together; Radau's dense run is its timing when it takes over 1 s)."""
    rows = []
    solver = EventSolver(scene)
    for method, rtols in methods.items():
        for rtol in rtols:
            atol = rtol * 1e-3
            t0 = time.perf_counter()
            dres = solver.run(method, rtol, atol, dense=True)
            td = time.perf_counter() - t0
            if method in LOW_OVERHEAD_DENSE and td > 1.0:
                wall, how = td, "1 run (with dense output, < 2% overhead for this method)"
            else:
                times = []
                while len(times) < timed_runs and sum(times) < 1.0:
                    t0 = time.perf_counter()
                    solver.run(method, rtol, atol)
                    times.append(time.perf_counter() - t0)
                wall, how = min(times), f"best of {len(times)}"
            grid = _grid(scene)
            dw = dres.dense_w(scene, grid) if not dres.failed else None
            res = errors(scene, ref, dres.impacts, dres.sticks, dres.releases, dres.final,
                         grid if dw is not None else None, dw)
            note = dres.failed or ""
            if scene.key == "S3" and not dres.sticks:
                note = (note + "; " if note else "") + "never sticks"
            rows.append(_row(scene, "scipy", method, f"rtol={rtol:g}", wall, how, res, rtol=rtol, atol=atol,
                             work=f"{dres.nfev} rhs evaluations", note=note))
        log(f"  scipy {method} {scene.key}: {len(rtols)} runs")
    return rows


def _grid(scene):
    n = int(round(scene.t_end / scene.dense_dt))
    g = np.arange(n + 1) * scene.dense_dt
    g[-1] = min(g[-1], scene.t_end)
    return g[g <= scene.t_end]


# ---- penalty stop, fixed-step RK4 ---------------------------------------------------------

def penalty_settings(scene, kps, fine_kp):
    out = []
    m_eff = 1.0 / scene.ww
    for kp in kps:
        wc = math.sqrt(kp / m_eff)
        m = max(1, math.ceil(scene.dense_dt * wc / 0.25))
        out.append((kp, m))
        if kp == fine_kp:
            out.append((kp, 4 * m))
    return out


def penalty_sweep(scene, ref, settings, log=print):
    rows = []
    for kp, m in settings:
        r = penalty.run(scene, kp, m)
        res = errors(scene, ref, r.impacts, r.sticks, r.releases, r.final, r.times[::m], r.w[::m])
        note = f"omega_c h = {r.omega_c * r.h:.3g}, c_p = {r.c_p:.4g}"
        if scene.key == "S3" and not r.sticks:
            note += "; never sticks"
        rows.append(_row(scene, "penalty", "penalty RK4", f"k_p={kp:g}, h={r.h:.3g}", r.wall, "1 run (loop only)",
                         res, k_p=kp, h=r.h, work=f"{r.steps} RK4 steps", note=note, steps=r.steps))
    log(f"  penalty {scene.key}: {len(rows)} runs")
    return rows


def dense_overhead(scene, methods=("RK45", "DOP853", "Radau", "LSODA"), rtol=1e-6):
    """Wall time with dense output over wall time without (best of 3 each)."""
    solver = EventSolver(scene)
    out = {}
    for m in methods:
        best = {}
        for dense in (False, True):
            ts = []
            for _ in range(3):
                t0 = time.perf_counter()
                solver.run(m, rtol, rtol * 1e-3, dense=dense)
                ts.append(time.perf_counter() - t0)
            best[dense] = min(ts)
        out[m] = best[True] / best[False] - 1.0
    return out


def all_impacts_error(scene, ref, out):
    """Largest error over every impact of a beamstop run (not only the first K)."""
    imp = np.asarray(out["impacts"])
    r = np.asarray(ref.impacts)
    if len(imp) != len(r):
        return math.nan, None
    d = np.abs(imp - r)
    k = int(np.argmax(d))
    return float(d[k]), k
