"""Closed-form, event-driven reference for the pinned beam in free flight
(scenes S1 and S2), in extended precision with mpmath.

Each mode is a damped oscillator under a harmonic load:
    q_j = A_j sin(Omega t) + B_j cos(Omega t)                   (particular)
        + e^{-a_j tau} (y0 cos(od_j tau) + (yd0 + a_j y0)/od_j sin(od_j tau))
with a_j = zeta omega_j, od_j = omega_j sqrt(1 - zeta^2), tau = t - t_k from the
last impact t_k. Impacts are the first roots of g(t) = d - w.q(t) after t_k:
located by a fine float64 scan of the closed form (sign changes and local
minima), then refined by mpmath.findroot at `dps` digits; eq. 28 is applied
in the same precision. No sticking (S1 and S2 never stick; a chatter impact
raises).
"""
from __future__ import annotations

import math

import mpmath
import numpy as np
from scipy.optimize import brentq, minimize_scalar

from .models import Scene


class ClosedForm:
    def __init__(self, scene: Scene, dps: int = 40, perturb: float = 0.0):
        assert scene.kind == "beam" and not scene.start_stuck
        self.scene = scene
        self.dps = dps
        mp = mpmath.mp
        mp.dps = dps
        n = scene.n
        self.n = n
        f = mpmath.mpf
        pi = mp.pi
        self.Om = f(scene.Omega)
        zeta = f(scene.zeta)
        F = f(scene.F)
        xs = f(scene.x_s)
        self.d = f(scene.d)
        self.R = f(scene.R)
        self.om, self.a, self.od, self.w, self.A, self.B = [], [], [], [], [], []
        for j in range(1, n + 1):
            om = (j * pi) ** 2
            alpha = mpmath.sqrt(2) * (1 - mpmath.cos(j * pi)) / (j * pi)
            p = alpha * F
            det = (om**2 - self.Om**2) ** 2 + (2 * zeta * om * self.Om) ** 2
            self.om.append(om)
            self.a.append(zeta * om)
            self.od.append(om * mpmath.sqrt(1 - zeta**2))
            self.w.append(mpmath.sqrt(2) * mpmath.sin(j * pi * xs))
            self.A.append(p * (om**2 - self.Om**2) / det)
            self.B.append(-p * 2 * zeta * om * self.Om / det)
        self.ww = sum(x * x for x in self.w)
        # float64 copies for the scan
        self.fom = np.array([float(x) for x in self.om])
        self.fa = np.array([float(x) for x in self.a])
        self.fod = np.array([float(x) for x in self.od])
        self.fw = np.array([float(x) for x in self.w])
        self.fA = np.array([float(x) for x in self.A])
        self.fB = np.array([float(x) for x in self.B])
        q0 = [f(x) for x in scene.q0]
        if perturb:
            # a last-digit change in a direction that is not a symmetry (with
            # d = 0 and F = 0 scaling the whole state changes no impact time)
            q0[1] = q0[1] + f(perturb) * max(abs(q0[0]), 1)
        self.anchor = (f(0), q0, [f(x) for x in scene.qd0])
        periods = [2 * math.pi / x for x in self.fom]
        if scene.Omega > 0:
            periods.append(2 * math.pi / scene.Omega)
        self.h = min(periods) / 64.0

    # ---- extended precision -------------------------------------------------
    def state(self, t, anchor=None):
        t0, q0, qd0 = anchor or self.anchor
        tau = t - t0
        Om = self.Om
        s0, c0 = mpmath.sin(Om * t0), mpmath.cos(Om * t0)
        s1, c1 = mpmath.sin(Om * t), mpmath.cos(Om * t)
        q, qd = [], []
        for j in range(self.n):
            A, B, a, od, om = self.A[j], self.B[j], self.a[j], self.od[j], self.om[j]
            y0 = q0[j] - (A * s0 + B * c0)
            yd0 = qd0[j] - (A * Om * c0 - B * Om * s0)
            e = mpmath.exp(-a * tau)
            c, s = mpmath.cos(od * tau), mpmath.sin(od * tau)
            q.append(A * s1 + B * c1 + e * (y0 * c + (yd0 + a * y0) / od * s))
            qd.append(A * Om * c1 - B * Om * s1 + e * (yd0 * c - (a * yd0 + om * om * y0) / od * s))
        return q, qd

    def gap(self, t, anchor=None):
        q, _ = self.state(t, anchor)
        return self.d - sum(wj * qj for wj, qj in zip(self.w, q))

    # ---- float64 scan ---------------------------------------------------------
    def _float_anchor(self, anchor):
        t0, q0, qd0 = anchor
        return float(t0), np.array([float(x) for x in q0]), np.array([float(x) for x in qd0])

    def f_state(self, t, anchor=None):
        """Closed form in float64 on an array of times (for the scan and the
        dense grid); accurate to ~1e-15 within a segment."""
        t0, q0, qd0 = self._float_anchor(anchor or self.anchor)
        t = np.atleast_1d(np.asarray(t, float))
        tau = (t - t0)[:, None]
        Om = float(self.Om)
        s0, c0 = math.sin(Om * t0), math.cos(Om * t0)
        A, B, a, od, om = self.fA, self.fB, self.fa, self.fod, self.fom
        y0 = q0 - (A * s0 + B * c0)
        yd0 = qd0 - (A * Om * c0 - B * Om * s0)
        s1, c1 = np.sin(Om * t)[:, None], np.cos(Om * t)[:, None]
        e = np.exp(-a * tau)
        c, s = np.cos(od * tau), np.sin(od * tau)
        q = A * s1 + B * c1 + e * (y0 * c + (yd0 + a * y0) / od * s)
        qd = A * Om * c1 - B * Om * s1 + e * (yd0 * c - (a * yd0 + om * om * y0) / od * s)
        return q, qd

    def f_gap(self, t, anchor=None):
        q, _ = self.f_state(t, anchor)
        return float(self.scene.d) - q @ self.fw

    def next_root(self, anchor, t_end):
        """First root of the gap after the anchor (None before t_end)."""
        t0 = float(anchor[0])
        h = self.h
        lo = t0
        while lo < t_end:
            hi = min(lo + 4000 * h, t_end)
            ts = np.arange(lo, hi + 0.5 * h, h)
            ts[-1] = min(ts[-1], t_end)
            if ts[0] == t0:
                ts = ts[1:]
            g = self.f_gap(ts, anchor)
            bracket = None
            neg = np.nonzero(g <= 0.0)[0]
            first_neg = neg[0] if neg.size else len(g)
            # local minima before the first sign change: grazing dips
            for i in range(1, min(first_neg, len(g) - 1)):
                if g[i] <= g[i - 1] and g[i] <= g[i + 1]:
                    r = minimize_scalar(lambda x: float(self.f_gap(x, anchor)[0]), bounds=(ts[i - 1], ts[i + 1]),
                                        method="bounded", options={"xatol": 1e-14})
                    if r.fun <= 0.0:
                        bracket = (ts[i - 1], r.x)
                        break
            if bracket is None and first_neg < len(g):
                a = ts[first_neg - 1] if first_neg > 0 else t0 + 1e-300
                if first_neg == 0:
                    raise RuntimeError(f"gap closes within one scan step after t = {t0}")
                bracket = (a, ts[first_neg])
            if bracket is not None:
                a, b = bracket
                tf = brentq(lambda x: float(self.f_gap(x, anchor)[0]), a, b, xtol=1e-15, rtol=8.9e-16)
                tm = mpmath.findroot(lambda x: self.gap(x, anchor), (mpmath.mpf(tf) - mpmath.mpf(1e-9),
                                                                      mpmath.mpf(tf) + mpmath.mpf(1e-9)))
                if not (a - 1e-9 <= float(tm) <= b + 1e-9):
                    raise RuntimeError(f"mp root {tm} outside its bracket {bracket}")
                return tm
            lo = hi
        return None

    def solve(self, t_end: float, max_impacts: int = 100000):
        """Impact times (mpf), the anchors after each impact and the final state."""
        anchor = self.anchor
        impacts, anchors = [], [anchor]
        prev = None
        eps = mpmath.mpf(self.scene.eps)
        while len(impacts) < max_impacts:
            tm = self.next_root(anchor, t_end)
            if tm is None:
                break
            q, qd = self.state(tm, anchor)
            vn = sum(wj * v for wj, v in zip(self.w, qd))
            if vn <= 0:
                raise RuntimeError(f"graze at t = {tm}")
            if prev is not None and tm - prev < eps:
                raise RuntimeError(f"chatter at t = {tm}: not covered by the closed-form reference")
            k = (1 + self.R) * vn / self.ww
            qd = [v - k * wj for v, wj in zip(qd, self.w)]
            anchor = (tm, q, qd)
            impacts.append(tm)
            anchors.append(anchor)
            prev = tm
        self.impacts, self.anchors = impacts, anchors
        qf, qdf = self.state(mpmath.mpf(t_end), anchor)
        self.final = (qf, qdf)
        return impacts

    def dense_w(self, times: np.ndarray) -> np.ndarray:
        starts = np.array([float(a[0]) for a in self.anchors])
        idx = np.searchsorted(starts, times, side="right") - 1
        out = np.empty(len(times))
        for k in np.unique(idx):
            m = idx == k
            out[m] = self.f_gap(times[m], self.anchors[k]) * -1.0 + float(self.scene.d)
        return out
