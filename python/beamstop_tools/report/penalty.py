"""A penalty-spring stop integrated with fixed-step RK4, as a generic
co-simulation tool would approximate a rigid stop.

Contact force (Kelvin-Voigt) while the stop point penetrates, p = w.q - d > 0:
    F_c = k_p p + c_p (w.qd),   qdd = f - D qd - K q - w F_c.
The dashpot is chosen from the restitution of a linear spring-dashpot acting
on the effective mass at the stop, m_eff = 1 / (w.w) (the mass that eq. 28
assigns to the contact point):
    zeta_c = -ln R / sqrt(pi^2 + ln^2 R),  c_p = 2 zeta_c sqrt(k_p m_eff),
so that an isolated impact of m_eff has exactly the coefficient R (R = 1:
no dashpot). Contact onsets (the impacts) and ends are located by linear
interpolation of p between steps; a contact that lasts more than 50 contact
durations (pi / omega_c) is read as sticking: its onset is the stick time
(the last impact) and its end the release time.

Pure Python with numpy (8-vectors): the per-step cost is interpreter
overhead, so the wall times are those of a scripted loop, not of a
compiled tool; the step counts are reported as well.
"""
from __future__ import annotations

import math
import time

import numpy as np

from .models import Scene


def dashpot(R: float, k_p: float, m_eff: float) -> float:
    if R >= 1.0:
        return 0.0
    lr = math.log(R) if R > 0 else -40.0
    zc = -lr / math.sqrt(math.pi**2 + lr * lr)
    return 2.0 * zc * math.sqrt(k_p * m_eff)


class PenaltyResult:
    pass


def run(scene: Scene, k_p: float, m: int, record: bool = True):
    """RK4 with h = dense_dt / m over [0, t_end]; returns the wall time of
    the integration loop and the recorded trajectory."""
    n = scene.n
    h = scene.dense_dt / m
    steps = int(round(scene.t_end / h))
    h = scene.t_end / steps
    ww = scene.ww
    m_eff = 1.0 / ww
    c_p = dashpot(scene.R, k_p, m_eff)
    Z, I = np.zeros((n, n)), np.eye(n)
    A = np.block([[Z, I], [-scene.K, -scene.D]])
    wq = np.concatenate([scene.w, np.zeros(n)])
    wv = np.concatenate([np.zeros(n), scene.w])
    cvec = np.concatenate([np.zeros(n), scene.w])  # force direction in y'
    fs = np.concatenate([np.zeros(n), scene.fs])
    fc = np.concatenate([np.zeros(n), scene.fc])
    Om, d = scene.Omega, scene.d
    sin, cos = math.sin, math.cos

    def rhs(t, y):
        dy = A @ y + fs * sin(Om * t) + fc * cos(Om * t)
        p = wq @ y - d
        if p > 0.0:
            dy -= cvec * (k_p * p + c_p * (wv @ y))
        return dy

    y = scene.y0().astype(float)
    pen = np.empty(steps + 1)
    wpos = np.empty(steps + 1)
    pen[0] = wq @ y - d
    wpos[0] = wq @ y
    t0 = time.perf_counter()
    t = 0.0
    for k in range(steps):
        k1 = rhs(t, y)
        k2 = rhs(t + 0.5 * h, y + 0.5 * h * k1)
        k3 = rhs(t + 0.5 * h, y + 0.5 * h * k2)
        k4 = rhs(t + h, y + h * k3)
        y = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        t = (k + 1) * h
        wy = wq @ y
        wpos[k + 1] = wy
        pen[k + 1] = wy - d
    wall = time.perf_counter() - t0
    if not np.all(np.isfinite(y)):
        raise FloatingPointError("penalty RK4 diverged")
    times = np.arange(steps + 1) * h
    r = PenaltyResult()
    r.wall = wall
    r.h = h
    r.steps = steps
    r.k_p = k_p
    r.c_p = c_p
    r.omega_c = math.sqrt(k_p / m_eff)
    r.final = y
    r.times = times
    r.w = wpos
    # contact episodes
    inside = pen > 0.0
    ons, offs = [], []
    if inside[0]:
        ons.append(0.0)
    for k in range(steps):
        if not inside[k] and inside[k + 1]:
            ons.append(_cross(times[k], times[k + 1], pen[k], pen[k + 1]))
        elif inside[k] and not inside[k + 1]:
            if not ons:
                ons.append(0.0)
            offs.append(_cross(times[k], times[k + 1], pen[k], pen[k + 1]))
    # a contact starting at t = 0 from rest is the initial sticking, not an impact
    long_contact = 50.0 * math.pi / r.omega_c
    r.impacts, r.sticks, r.releases = [], [], []
    for i, on in enumerate(ons):
        off = offs[i] if i < len(offs) else math.inf
        if on > 0.0:
            r.impacts.append(on)
        if off - on > long_contact:
            if on > 0.0:
                r.sticks.append(on)
            if math.isfinite(off):
                r.releases.append(off)
    return r


def _cross(t0, t1, p0, p1):
    return t0 + (t1 - t0) * p0 / (p0 - p1)
