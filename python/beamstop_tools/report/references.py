"""References for each scene and their cross-checks.

S1, S2: the closed form in extended precision (closedform.py, 40 digits),
        checked against the same at 60 digits, against the independent
        eigen-decomposition form (mplti.py), and against scipy DOP853 at
        rtol = atol = 1e-13 (dense-output event location); the effect of
        a last-digit change of the initial state shows how far any float64
        computation can follow an R = 1 impact sequence.
S3, S4: the extended-precision event-driven solution with sticking
        (mplti.py, 40 digits), checked against itself at 60 digits and
        against two scipy integrators at 1e-13 (DOP853 and Radau).
"""
from __future__ import annotations

import math
import time

import mpmath
import numpy as np

from .closedform import ClosedForm
from .eventode import EventSolver
from .metrics import first_parting
from .mplti import MpReference


class Reference:
    def __init__(self, scene, kind, impacts, sticks, releases, final, dense_fn, seconds):
        self.scene = scene
        self.kind = kind
        self.impacts = [float(x) for x in impacts]
        self.sticks = [float(x) for x in sticks]
        self.releases = [float(x) for x in releases]
        self.final = np.asarray(final, float)
        self._dense = dense_fn
        self.seconds = seconds
        self.checks = {}

    def dense_w(self, times):
        return self._dense(np.asarray(times, float))


def _maxdiff(a, b, n=None):
    """Largest difference, computed in extended precision (so that two
    references agreeing beyond float64 show how far they agree)."""
    n = min(len(a), len(b)) if n is None else n
    if n == 0:
        return 0.0
    with mpmath.workdps(80):
        return float(max(abs(mpmath.mpf(x) - mpmath.mpf(y)) for x, y in zip(a[:n], b[:n])))


def _dense_check(scene, w_mp, dense_fn, n=40):
    """The dense reference is the closed form evaluated in float64 from
    extended-precision anchors: its error against the same form in mpmath."""
    ts = np.linspace(0.0, scene.t_end, n + 2)[1:-1] + 1e-4 * np.pi
    wf = dense_fn(ts)
    return float(max(abs(float(w_mp(mpmath.mpf(t))) - x) for t, x in zip(ts, wf)))


def build(scene, quick=False, log=print):
    t0 = time.perf_counter()
    dps = 30 if quick else 40
    checks = {}
    if scene.key in ("S1", "S2"):
        main = ClosedForm(scene, dps)
        main.solve(scene.t_end)
        final = [float(x) for x in main.final[0] + main.final[1]]
        ref = Reference(scene, f"closed form, mpmath {dps} digits", main.impacts, [], [], final, main.dense_w,
                        time.perf_counter() - t0)
        if not quick:
            hi = ClosedForm(scene, 60)
            hi.solve(scene.t_end)
            main_final = main.final[0] + main.final[1]
            checks["closed form 60 digits"] = {
                "impacts": _maxdiff(main.impacts, hi.impacts), "n": len(hi.impacts),
                "final": _maxdiff(hi.final[0] + hi.final[1], main_final),
            }
            eig = MpReference(scene, dps)
            eig.solve(scene.t_end)
            checks["eigen form (mplti) 40 digits"] = {
                "impacts": _maxdiff(main.impacts, eig.impacts), "n": len(eig.impacts),
                "final": _maxdiff(eig.final_mp, main_final),
            }
            mpmath.mp.dps = dps

            def w_mp(t):
                k = max(i for i, a in enumerate(main.anchors) if a[0] <= t)
                return main.d - main.gap(t, main.anchors[k])

            checks["dense grid in float64"] = _dense_check(scene, w_mp, ref.dense_w)
        # DOP853 at 1e-13, and a last-digit perturbation, over a longer horizon
        ext = 8.0 if scene.key == "S1" else scene.t_end
        if quick:
            ext = min(ext, 4.0)
        long = ClosedForm(scene, dps)
        long.solve(ext)
        dop = EventSolver(scene.with_horizon(ext)).run("DOP853", 1e-13, 1e-13)
        pert = ClosedForm(scene, dps, perturb=2.0**-53)
        pert.solve(ext)
        li = [float(x) for x in long.impacts]
        within = [k for k, t in enumerate(li) if t <= scene.t_end]
        nh = len(within)
        d_dop = [abs(a - b) for a, b in zip(dop.impacts, li)]
        with mpmath.workdps(80):
            d_pert = [float(abs(a - b)) for a, b in zip(pert.impacts, long.impacts)]
        dop_h = EventSolver(scene).run("DOP853", 1e-13, 1e-13)
        checks["DOP853 1e-13"] = {
            "impacts": _maxdiff(dop_h.impacts, ref.impacts), "n": len(dop_h.impacts),
            "final": float(np.max(np.abs(dop_h.final - ref.final))),
            "extended_horizon": ext, "n_extended": len(li),
            "parting_1e-9": _part(dop.impacts, li, 1e-9),
            "parting_1e-12": _part(dop.impacts, li, 1e-12),
            "diffs": d_dop,
        }
        checks["last-digit perturbation"] = {
            "size": "q0[2] += 2^-53 max(|q0[1]|, 1)",
            "within_horizon": max(d_pert[:nh]) if nh else 0.0,
            "parting_1e-12": _part(pert.impacts, long.impacts, 1e-12),
            "parting_1e-9": _part(pert.impacts, long.impacts, 1e-9),
            "diffs": d_pert,
        }
        checks["extended_impacts"] = li
    else:
        main = MpReference(scene, dps)
        main.solve(scene.t_end)
        ref = Reference(scene, f"event-driven eigen form with sticking, mpmath {dps} digits", main.impacts,
                        main.sticks, main.releases, main.final, main.dense_w, time.perf_counter() - t0)
        if not quick:
            hi = MpReference(scene, 60)
            hi.solve(scene.t_end)
            checks["eigen form 60 digits"] = {
                "impacts": _maxdiff(main.impacts, hi.impacts), "n": len(hi.impacts),
                "events": max([_maxdiff(main.sticks, hi.sticks), _maxdiff(main.releases, hi.releases),
                               _maxdiff(main.impacts, hi.impacts)]),
                "final": _maxdiff(hi.final_mp, main.final_mp),
            }
            mpmath.mp.dps = dps

            def w_mp(t):
                k = max(i for i, a in enumerate(main.anchors) if a[0] <= t)
                t0, st, c = main.anchors[k]
                return main.d if st else main.d - main.event_mp(False, t, t0, c)

            checks["dense grid in float64"] = _dense_check(scene, w_mp, ref.dense_w)
        if not quick:
            pert = MpReference(scene, dps, perturb=2.0**-53)
            pert.solve(scene.t_end)
            checks["last-digit perturbation"] = {
                "size": "q0[2] += 2^-53 max(|q0[1]|, 1)",
                "within_horizon": max([_maxdiff(main.impacts, pert.impacts), _maxdiff(main.sticks, pert.sticks),
                                       _maxdiff(main.releases, pert.releases)]),
                "final": _maxdiff(main.final_mp, pert.final_mp),
                "n": len(pert.impacts),
            }
        for method in (["DOP853"] if quick else ["DOP853", "Radau"]):
            r = EventSolver(scene).run(method, 1e-13, 1e-13)
            checks[f"{method} 1e-13"] = {
                "impacts": _maxdiff(r.impacts, ref.impacts), "n": len(r.impacts),
                "sticks": [float(x) for x in r.sticks], "releases": [float(x) for x in r.releases],
                "release_diff": abs(r.releases[0] - ref.releases[0]) if r.releases and ref.releases else math.nan,
                "parting_1e-9": _part(r.impacts, ref.impacts, 1e-9),
                "parting_1e-12": _part(r.impacts, ref.impacts, 1e-12),
                "final": float(np.max(np.abs(r.final - ref.final))),
                "diffs": [abs(a - b) for a, b in zip(r.impacts, ref.impacts)],
                "impact_times": list(r.impacts),
            }
        if scene.key == "S3":
            # does a much smaller atol help? and how small are the chatter flights?
            r = EventSolver(scene).run("DOP853", 1e-13, 1e-22)
            checks["DOP853 rtol 1e-13, atol 1e-22"] = {
                "n": len(r.impacts), "sticks": [float(x) for x in r.sticks],
                "parting_1e-9": _part(r.impacts, ref.impacts, 1e-9),
                "parting_1e-12": _part(r.impacts, ref.impacts, 1e-12),
            }
            checks["chatter flights"] = _flights(main, ref)
        if "DOP853 1e-13" in checks and "Radau 1e-13" in checks:
            a, b = checks["DOP853 1e-13"]["impact_times"], checks["Radau 1e-13"]["impact_times"]
            checks["DOP853 vs Radau"] = {
                "parting_1e-9": _part(a, b, 1e-9), "parting_1e-12": _part(a, b, 1e-12),
                "impacts": _maxdiff(a, b, min(len(a), len(b), scene.k_impacts)),
            }
    ref.checks = checks
    ref.seconds = time.perf_counter() - t0
    log(f"  reference {scene.key}: {len(ref.impacts)} impacts, {ref.seconds:.1f} s")
    return ref


def _part(a, b, thr):
    k = first_parting(a, b, thr)
    n = min(len(a), len(b))
    if k is None:
        return {"index": None, "of": n}
    return {"index": k, "of": n, "time": float(b[k])}


def _flights(main, ref):
    """Duration and height (largest gap) of each flight of the first chatter
    sequence of the extended-precision reference (S3)."""
    stick = ref.sticks[0]
    rel = ref.releases[0]
    seq = [t for t in ref.impacts if rel < t <= stick]
    out = []
    for a, b in zip(seq[:-1], seq[1:]):
        k = max(i for i, an in enumerate(main.anchors) if float(an[0]) <= a + 1e-15)
        t0, st, c = main.anchors[k]
        cf = np.array([complex(x) for x in c])
        ts = np.linspace(a, b, 201)[1:-1]
        g = main.event_float(False, ts, t0, cf)
        out.append((b - a, float(np.max(g))))
    return out
