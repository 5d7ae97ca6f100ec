"""An independent model of scenes/rigid_and_hertz.json (the RigidAndHertzStops
FMU), written from the papers' equations, not from beamstop's code: the
pinned-pinned beam's modes in VSM12's scaled units (W_j = sqrt(2) sin(j pi x),
omega_j = (j pi)^2, modal damping 2 zeta omega_j, the distributed load's
modal forces F sin(Omega t) sqrt(2) (1 - cos j pi) / (j pi)); a rigid stop
with the modal restitution rule (VSM12 eq. 28), chatter ended by the
threshold eps with R = 0, then sticking held by the reaction that keeps
w . q'' = 0 (VSM12 eq. 33, the other stop's force among the loads) until it
would pull; a Hertz stop with Hunt-Crossley damping K p^1.5 (1 + 3 (1 - e)
/ 2 p' / v0) (DWZ, HC75/MO99) that never pulls (pressed, penetrated without
force, apart). scipy's DOP853 between events, located by its event
functions, restarted at each.
"""

from __future__ import annotations

import json
import math

import numpy as np
from scipy.integrate import solve_ivp


class Model:
    def __init__(self, scene: dict):
        s = scene
        self.n = s["structure"]["modes"]
        j = np.arange(1, self.n + 1)
        self.omega = (j * math.pi) ** 2
        self.c = 2 * s["damping"]["zeta"] * self.omega
        load = s["loads"][0]
        self.F, self.Omega = load["amplitude"], load["omega"]
        self.load_shape = math.sqrt(2) * (1 - np.cos(j * math.pi)) / (j * math.pi)
        rigid, soft = s["stops"]
        self.w_r = math.sqrt(2) * np.sin(j * math.pi * rigid["x"])
        self.gap_r = rigid["gap"]
        self.R, self.eps = rigid["law"]["R"], rigid["law"]["eps"]
        self.w_s = math.sqrt(2) * np.sin(j * math.pi * soft["x"])
        self.gap_s = soft["gap"]
        self.K, self.e = soft["law"]["K"], soft["law"]["e"]

    def raw_force(self, q, qd, v0):
        p = self.w_s @ q - self.gap_s
        if p <= 0:
            return 0.0
        return self.K * p ** 1.5 * (1 + 1.5 * (1 - self.e) * (self.w_s @ qd) / v0)

    def accel(self, t, q, qd, soft_force):
        return self.F * math.sin(self.Omega * t) * self.load_shape - self.omega ** 2 * q - self.c * qd - self.w_s * soft_force


def simulate(scene: dict, t_end: float, rtol=1e-12, atol=1e-14):
    """The events [(time, kind, stop)] and a dense solution of [q; qd]."""
    m = Model(scene)
    n = m.n
    y = np.zeros(2 * n)
    t = 0.0
    soft, v0 = "open", 0.0
    held, previous_impact = False, None
    events, pieces = [], []
    P = np.eye(n) - np.outer(m.w_r, m.w_r) / (m.w_r @ m.w_r)

    def soft_force(q, qd):
        return max(m.raw_force(q, qd, v0), 0.0) if soft == "pressed" else 0.0

    def rhs(t, y):
        q, qd = y[:n], y[n:]
        a = m.accel(t, q, qd, soft_force(q, qd))
        return np.concatenate([qd, P @ a if held else a])

    def push(t, y):  # a held stop's push, w . a / (w . w) (the stop limits w . q from above)
        q, qd = y[:n], y[n:]
        return (m.w_r @ m.accel(t, q, qd, soft_force(q, qd))) / (m.w_r @ m.w_r)

    while t < t_end:
        fns, kinds = [], []
        if held:
            f = lambda t, y: push(t, y); f.direction = -1; fns.append(f); kinds.append("release")
        else:
            f = lambda t, y: m.w_r @ y[:n] - m.gap_r; f.direction = 1; fns.append(f); kinds.append("impact")
        if soft == "open":
            f = lambda t, y: m.w_s @ y[:n] - m.gap_s; f.direction = 1; fns.append(f); kinds.append("contact")
        else:
            f = lambda t, y: m.w_s @ y[:n] - m.gap_s; f.direction = -1; fns.append(f); kinds.append("separation")
            if soft == "pressed":
                f = lambda t, y: m.raw_force(y[:n], y[n:], v0); f.direction = -1; fns.append(f); kinds.append("unpressed")
            else:
                f = lambda t, y: m.raw_force(y[:n], y[n:], v0); f.direction = 1; fns.append(f); kinds.append("pressed")
        for f in fns:
            f.terminal = True
        sol = solve_ivp(rhs, (t, t_end), y, method="DOP853", rtol=rtol, atol=atol, events=fns, dense_output=True)
        pieces.append((t, sol.t[-1], sol.sol))
        hit = [(te[0], k) for te, k in zip(sol.t_events, range(len(fns))) if len(te)]
        if not hit:
            break
        t, k = min(hit)
        y = sol.sol(t)
        q, qd = y[:n].copy(), y[n:].copy()
        kind = kinds[k]
        if kind == "impact":
            speed = m.w_r @ qd
            chatter = previous_impact is not None and t - previous_impact < m.eps
            R = 0.0 if chatter else m.R
            qd = qd - (1 + R) * speed / (m.w_r @ m.w_r) * m.w_r
            q = q + (m.gap_r - m.w_r @ q) / (m.w_r @ m.w_r) * m.w_r
            previous_impact = t
            events.append((t, "impact", "rigid"))
            if chatter and push(t, np.concatenate([q, qd])) >= 0:
                held, previous_impact = True, None
                events.append((t, "stick", "rigid"))
        elif kind == "release":
            held = False
            events.append((t, "release", "rigid"))
        elif kind == "contact":
            soft, v0 = "pressed", m.w_s @ qd
            events.append((t, "contact", "soft"))
        elif kind == "separation":
            soft = "open"
            events.append((t, "separation", "soft"))
        elif kind == "unpressed":
            soft = "penetrated"
            events.append((t, "separation", "soft"))
        else:
            soft = "pressed"
        y = np.concatenate([q, qd])
    return events, pieces


def state_at(pieces, t):
    for a, b, sol in pieces:
        if a <= t <= b:
            return sol(t)
    return pieces[-1][2](pieces[-1][1])


if __name__ == "__main__":
    import sys
    scene = json.load(open(sys.argv[1]))
    events, _ = simulate(scene, scene["experiment"]["stop"])
    for e in events:
        print(f"{e[0]:.17f},{e[1]},{e[2]}")
