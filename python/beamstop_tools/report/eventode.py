"""What a user would otherwise write: scipy.integrate.solve_ivp with events,
for the same rigid-stop model (eq. 28 impacts, chatter rule, sticking).

Free flight:  qdd = f(t) - D qd - K q;  event g = d - w.q falling through 0.
Impact:       qd+ = qd- - (1 + R)(w.qd-) w / (w.w), positions unchanged;
              R = 0 when the previous impact is less than eps ago (chatter),
              and then, if the loads press the beam on the stop, sticking.
Sticking:     qdd = f - D qd - K q + w lambda,
              lambda = (w.(K q + D qd) - w.f) / (w.w)   (so w.qdd = 0),
              state projected onto the constraint at entry; the beam is
              released when lambda crosses zero upwards (event).

Used both as a baseline (RK45, DOP853, Radau, LSODA across tolerances) and,
at rtol = atol = 1e-13 with two different integrators (DOP853, Radau), as the
cross-check of the extended-precision references (references.py). On S3 it
cannot follow the chatter (see summary.md), whatever the tolerances.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from .models import Scene

TINY = 1e-300


class Result:
    def __init__(self):
        self.impacts: list[float] = []
        self.sticks: list[float] = []
        self.releases: list[float] = []
        self.segments: list = []  # (t0, t1, dense or None)
        self.final: np.ndarray | None = None
        self.nfev = 0
        self.wall = math.nan
        self.failed: str | None = None

    def dense_w(self, scene: Scene, times: np.ndarray) -> np.ndarray:
        starts = np.array([s[0] for s in self.segments])
        idx = np.clip(np.searchsorted(starts, times, side="right") - 1, 0, len(starts) - 1)
        out = np.full(len(times), np.nan)
        n = scene.n
        for k in np.unique(idx):
            m = idx == k
            sol = self.segments[k][2]
            if sol is None:
                continue
            y = sol(times[m])
            out[m] = scene.w @ y[:n]
        return out


class EventSolver:
    def __init__(self, scene: Scene):
        self.s = scene
        n = scene.n
        self.n = n
        K, D, w = scene.K, scene.D, scene.w
        self.ww = float(w @ w)
        P = np.eye(n) - np.outer(w, w) / self.ww
        Z, I = np.zeros((n, n)), np.eye(n)
        self.A_free = np.block([[Z, I], [-K, -D]])
        self.A_stuck = np.block([[Z, I], [-P @ K, -P @ D]])
        self.P = P
        self.lam_row = np.concatenate([w @ K, w @ D]) / self.ww  # lambda = lam_row.y - w.f/ww
        self.w_f = (float(w @ scene.fs) / self.ww, float(w @ scene.fc) / self.ww)
        Om = scene.Omega
        fs, fc = scene.fs, scene.fc
        A_free, A_stuck, Pfs, Pfc = self.A_free, self.A_stuck, P @ fs, P @ fc
        zn = np.zeros(n)

        def rhs_free(t, y):
            s, c = math.sin(Om * t), math.cos(Om * t)
            return A_free @ y + np.concatenate([zn, fs * s + fc * c])

        def rhs_stuck(t, y):
            s, c = math.sin(Om * t), math.cos(Om * t)
            return A_stuck @ y + np.concatenate([zn, Pfs * s + Pfc * c])

        self.rhs_free, self.rhs_stuck = rhs_free, rhs_stuck

    def gap(self, y):
        return self.s.d - float(self.s.w @ y[: self.n])

    def lam(self, t, y):
        Om = self.s.Omega
        return float(self.lam_row @ y) - (self.w_f[0] * math.sin(Om * t) + self.w_f[1] * math.cos(Om * t))

    def run(self, method: str, rtol: float, atol: float, dense: bool = False, max_events: int = 20000) -> Result:
        s, n = self.s, self.n
        res = Result()
        t, y = 0.0, s.y0().astype(float)
        stuck = s.start_stuck
        prev = None
        jac_kw = {}
        implicit = method in ("Radau", "BDF", "LSODA")
        t_end = s.t_end
        w, R, eps = s.w, s.R, s.eps
        events_done = 0
        if stuck:
            y = self._project(y)
        while t < t_end:
            if events_done > max_events:
                res.failed = f"more than {max_events} events (chatter without end) at t = {t:.6g}"
                break
            if not stuck:
                g0 = self.gap(y)
                off = g0 - max(abs(g0), TINY)  # event function strictly positive at the start

                def ev(tt, yy, off=off):
                    return s.d - w @ yy[:n] - off

                ev.terminal, ev.direction = True, -1
                fun = self.rhs_free
                if implicit:
                    jac_kw = {"jac": (lambda tt, yy, A=self.A_free: A)}
            else:
                l0 = self.lam(t, y)
                off = l0 + max(abs(l0), TINY)  # strictly negative at the start

                def ev(tt, yy, off=off):
                    return self.lam(tt, yy) - off

                ev.terminal, ev.direction = True, 1
                fun = self.rhs_stuck
                if implicit:
                    jac_kw = {"jac": (lambda tt, yy, A=self.A_stuck: A)}
            kw = dict(method=method, rtol=rtol, atol=atol, events=[ev], dense_output=dense, **jac_kw)
            sol = solve_ivp(fun, (t, t_end), y, **kw)
            res.nfev += sol.nfev
            if not sol.success:
                res.failed = f"solve_ivp: {sol.message} at t = {sol.t[-1]:.6g}"
                break
            if dense:
                res.segments.append((t, sol.t[-1], sol.sol))
            if sol.status == 1 and len(sol.t_events[0]):
                te = float(sol.t_events[0][0])
                ye = np.array(sol.y_events[0][0], float)
                events_done += 1
                if te <= t:
                    res.failed = f"event did not advance at t = {t:.17g}"
                    break
                t, y = te, ye
                if stuck:
                    stuck = False
                    prev = None
                    res.releases.append(te)
                    continue
                vn = float(w @ y[n:])
                if vn <= 0.0:
                    continue  # a graze: the gap touches zero and opens again
                chatter = prev is not None and te - prev < eps
                r = 0.0 if chatter else R
                y[n:] -= (1.0 + r) * vn * w / self.ww
                res.impacts.append(te)
                prev = te
                if chatter and self.lam(te, y) <= 0.0:
                    stuck = True
                    prev = None
                    y = self._project(y)
                    res.sticks.append(te)
            else:
                t, y = float(sol.t[-1]), sol.y[:, -1].copy()
                break
        res.final = y
        return res

    def _project(self, y):
        n, w, ww = self.n, self.s.w, self.ww
        y = y.copy()
        y[:n] += (self.s.d - w @ y[:n]) * w / ww
        y[n:] -= (w @ y[n:]) * w / ww
        return y
