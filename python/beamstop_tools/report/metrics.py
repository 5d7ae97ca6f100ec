"""The three error measures of issue 3, against a scene's reference.

* events: the largest error in the first K impact times (S3: the release
  time and the first K chatter impact times); NaN when the method has
  fewer impacts than that.
* stick (S3 only): the error in the first stick time; NaN when the method
  never sticks.
* final: the largest error in the state (q, qd) at the final time (modal
  coordinates for the beam, x and x' for the chain).
* dense: the largest error in w at the stop on the method's own output grid
  (spacing 1e-3 for the beam, 1e-2 for the chain, or its communication step).
"""
from __future__ import annotations

import math

import numpy as np


def _first_positive(xs):
    return [x for x in xs if x > 0.0]


def errors(scene, ref, impacts, sticks, releases, final, dense_t, dense_w):
    K = min(scene.k_impacts, len(ref.impacts))
    out = {"n_impacts": len(impacts), "n_impacts_ref": len(ref.impacts)}
    ev = math.nan
    if len(impacts) >= K:
        ev = float(np.max(np.abs(np.asarray(impacts[:K]) - np.asarray(ref.impacts[:K])))) if K else 0.0
    if scene.key == "S3":
        rel = _first_positive(releases)
        if rel and ref.releases:
            ev = max(ev, abs(rel[0] - ref.releases[0])) if not math.isnan(ev) else ev
        else:
            ev = math.nan
        st = _first_positive(sticks)
        out["err_stick"] = abs(st[0] - ref.sticks[0]) if st and ref.sticks else math.nan
        out["n_sticks"] = len(st)
    out["err_events"] = ev
    if final is not None and np.all(np.isfinite(final)):
        out["err_final"] = float(np.max(np.abs(np.asarray(final) - ref.final)))
    else:
        out["err_final"] = math.nan
    if dense_t is not None and len(dense_t):
        w_ref = ref.dense_w(np.asarray(dense_t, float))
        dw = np.asarray(dense_w, float)
        out["err_dense"] = float(np.max(np.abs(dw - w_ref))) if np.all(np.isfinite(dw)) else math.nan
    else:
        out["err_dense"] = math.nan
    return out


def first_parting(a, b, threshold):
    """Index (0-based) of the first impact where two sequences differ by more
    than threshold, or None."""
    for k, (x, y) in enumerate(zip(a, b)):
        if abs(x - y) > threshold:
            return k
    return None
