"""Side studies: the chatter threshold eps (S3), modal truncation (S2), and
the speed ratio against the best scipy method."""
from __future__ import annotations

import math

import numpy as np

from . import native
from .closedform import ClosedForm
from .models import pinned
from .mplti import MpReference


def eps_sweep(scene, ref, eps_values, log=print):
    rows = []
    for eps in eps_values:
        out = native.measure(scene, repeats=5, dense_dt=0.0, set_extra={"eps": eps})
        if "error" in out:
            rows.append({"eps": eps, "note": out["error"]})
            continue
        imp = out["impacts"]
        sticks = [s for s in out["sticks"] if s > 0]
        rel = out["releases"]
        first = [t for t in imp if rel and t > rel[0] and (not sticks or t <= sticks[0])]
        rows.append({
            "eps": eps, "wall_time_s": out["wall_time_s"], "n_impacts": len(imp),
            "first_sequence_impacts": len(first), "stick_1": sticks[0] if sticks else math.nan,
            "stick_1_minus_ref": (sticks[0] - ref.sticks[0]) if sticks else math.nan,
            "n_sticks": len(sticks),
            "last_interval": (first[-1] - first[-2]) if len(first) > 1 else math.nan,
            "note": "",
        })
    log(f"  eps sweep: {len(rows)} runs")
    return rows


def truncation(scene, Ns, t_fixed, quick, log=print):
    rows = []
    for N in Ns:
        reps = 3 if N <= 64 else 1
        out = native.measure(scene, modes=N, repeats=reps, dense_dt=0.25)  # w every 0.25 (t_fixed on the grid)
        t = np.array(out["dense"]["t"])
        w = np.array(out["dense"]["w"])
        k = int(np.argmin(np.abs(t - t_fixed)))
        rows.append({
            "N": N, "wall_time_s": out["wall_time_s"], "n_impacts": len(out["impacts"]),
            "n_sticks": len(out["sticks"]), "impacts": out["impacts"][:6], "t_fixed": float(t[k]),
            "w_fixed": float(w[k]), "w_grid": w.tolist(), "t_grid": t.tolist(),
        })
        log(f"  truncation N = {N}: {out['wall_time_s']:.3g} s, {len(out['impacts'])} impacts")
    # R no longer matters at large N
    rdep = []
    for N in ([4, 64] if quick else [4, 64, 200]):
        for R in (0.0, 0.7, 1.0):
            out = native.measure(scene, modes=N, repeats=1, dense_dt=0.25, set_extra={"R": R})
            t = np.array(out["dense"]["t"])
            k = int(np.argmin(np.abs(t - t_fixed)))
            rdep.append({"N": N, "R": R, "eps": scene.eps, "n_impacts": len(out["impacts"]), "n_sticks": len(out["sticks"]),
                         "w_fixed": float(out["dense"]["w"][k]),
                         "w_final": float(out["dense"]["w"][-1])})
    # the chatter threshold is not what makes w settle: eps = 1e-9
    for N in ([64] if quick else [64, 200]):
        out = native.measure(scene, modes=N, repeats=1, dense_dt=0.25, set_extra={"eps": 1e-9})
        t = np.array(out["dense"]["t"])
        k = int(np.argmin(np.abs(t - t_fixed)))
        rdep.append({"N": N, "R": scene.R, "eps": 1e-9, "n_impacts": len(out["impacts"]),
                     "n_sticks": len(out["sticks"]), "w_fixed": float(out["dense"]["w"][k]),
                     "w_final": float(out["dense"]["w"][-1])})
    # independent check of beamstop at more modes
    checks = []
    for N in ([8] if quick else [8, 16]):
        s = pinned("S2", scene.title, n=N, F=scene.F, Omega=scene.Omega, zeta=scene.zeta, R=scene.R, eps=scene.eps,
                   d=scene.d, t_end=scene.t_end, set_values=scene.set_values)
        try:
            ref = ClosedForm(s, 30)
            ref.solve(s.t_end)
            kind = "closed form, 30 digits"
        except RuntimeError:
            ref = MpReference(s, 30)
            ref.solve(s.t_end)
            kind = "eigen form with sticking, 30 digits"
        out = native.measure(scene, modes=N, repeats=1, dense_dt=scene.dense_dt)
        ri = [float(x) for x in ref.impacts]
        same = len(ri) == len(out["impacts"])
        checks.append({
            "N": N, "reference": kind, "n_ref": len(ri), "n_beamstop": len(out["impacts"]),
            "impacts": float(np.max(np.abs(np.array(out["impacts"]) - np.array(ri)))) if same else math.nan,
            "dense": float(np.max(np.abs(np.array(out["dense"]["w"]) - ref.dense_w(np.array(out["dense"]["t"]))))),
        })
        log(f"  truncation check N = {N}: {checks[-1]}")
    return rows, rdep, checks


def speed_ratio(rows, keys, measures):
    """For each error level reached by the best scipy method (the lower
    envelope of all scipy runs), scipy's wall time over the smallest wall
    time of a beamstop run with an equal or smaller error."""
    out = []
    for key in keys:
        for m in measures:
            sci = [(r[m], r["wall_time_s"], f"{r['method']} {r['setting']}") for r in rows
                   if r["scene"] == key and r["family"] == "scipy" and _ok(r.get(m)) and _ok(r["wall_time_s"])]
            if not sci:
                continue
            env, best = [], math.inf
            for e, t, lab in sorted(sci, key=lambda p: p[1]):
                if e < best:
                    env.append((e, t, lab))
                    best = e
            for target in ("beamstop native", "beamstop FMU (fmpy)"):
                bs = [(r[m], r["wall_time_s"], r["setting"]) for r in rows
                      if r["scene"] == key and r["method"] == target and _ok(r.get(m)) and _ok(r["wall_time_s"])]
                ratios = []
                for e, t, lab in env:
                    cands = [(tb, sb, eb) for eb, tb, sb in bs if eb <= e]
                    if not cands:
                        continue
                    tb, sb, eb = min(cands)
                    ratios.append({"error": e, "scipy": lab, "t_scipy": t, "beamstop": sb, "t_beamstop": tb,
                                   "err_beamstop": eb, "ratio": t / tb})
                if ratios:
                    worst = min(ratios, key=lambda r: r["ratio"])
                    tight = min(ratios, key=lambda r: r["error"])
                    out.append({"scene": key, "measure": m, "target": target, "levels": len(ratios), **worst,
                                "tight_ratio": tight["ratio"], "tight_error": tight["error"],
                                "tight_scipy": tight["scipy"], "all": ratios})
    return out


def dominance(rows, keys, measures):
    """Baseline points (scipy, penalty) that no beamstop native run beats
    in both error and time."""
    bad = []
    for key in keys:
        for m in measures:
            bs = [(r[m], r["wall_time_s"]) for r in rows
                  if r["scene"] == key and r["method"] == "beamstop native" and _ok(r.get(m)) and _ok(r["wall_time_s"])]
            for r in rows:
                if r["scene"] != key or r["family"] not in ("scipy", "penalty"):
                    continue
                if not (_ok(r.get(m)) and _ok(r["wall_time_s"])):
                    continue
                if not any(eb <= r[m] and tb <= r["wall_time_s"] for eb, tb in bs):
                    bad.append((key, m, r["method"], r["setting"], r[m], r["wall_time_s"]))
    return bad


def _ok(x):
    return isinstance(x, (int, float)) and math.isfinite(x)
