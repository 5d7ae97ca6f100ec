#!/usr/bin/env python3
"""Independent numerical reference for the spring-stop cantilever scenes.

Written from the RMTM paper (its model section; docs/references.md) and the
scene files only; nothing of beamstop is imported or called.

Model (SI units)
----------------
A uniform Euler-Bernoulli cantilever, clamped at x = 0 to a base moving as
y_b(t); w(x, t) is the deflection relative to the base,
w = sum_j W_j(x) q_j(t), with the clamped-free modes mass-normalised,
int_0^L mu W_j^2 dx = 1 (mu = rho A), omega_j = beta_j^2 sqrt(EI / (mu L^4)):

    q_j'' + 2 zeta omega_j q_j' + omega_j^2 q_j
        = -mu a_b(t) int_0^L W_j dx - s F(t) W_j(x_s)

a_b(t) = amplitude * sin(omega t) from every `base_excitation` load
(amplitude = -Y Omega^2).  The stop sits at x_s on side s (+1 positive, -1
negative), moves with the base, gap delta.  Penetration p = s w(x_s) - delta;
F = k p + c p' while in contact, 0 otherwise.  Contact starts when
min(p, k p + c p') rises through 0 and ends when k p + c p' falls through 0
(for c = 0 both are p = 0).  Zero initial conditions.

Mode shapes in a form that is stable for any mode number:
    W~(xi) = a1 cos(b xi) + a2 sin(b xi) + a3 exp(-b (1 - xi)) + a4 exp(-b xi)
with beta from cos(b) + sech(b) = 0 and (a1..a4) the null vector of the
(row-scaled) boundary-condition matrix W(0) = W'(0) = W''(1) = W'''(1) = 0.

Integration
-----------
Piecewise smooth, restarted at every switch.  Method "DOP853" (default; any
scipy OdeSolver class name works: "Radau", "RK45", "LSODA") drives the scipy
OdeSolver directly -- the same stepper solve_ivp uses -- so that the state at
an event can be recomputed at step-endpoint accuracy: the switch is found by
brentq on the step's dense output, then the step is re-integrated from its
accepted start point to the root, and the root polished by Newton on the
re-integrated state.  Besides sign changes at step ends, a step is also
searched for a grazing double crossing (g < 0 at both ends, g' from + to -,
tangent lines meeting above 0).  A new phase is entered only if the switching
function really moves across (the sign of its derivative); a zero-length
phase therefore cannot occur.

Method "exact" is a second, integrator-free opinion: each phase is a linear
time-invariant system y' = A y + b0 + sum_l b_l sin(Omega_l t), solved in
closed form (eigen-decomposition of A plus the harmonic and static
particular solutions), with the switching function sampled densely
(spacing 0.25 / max|lambda|) and its roots found by brentq + Newton on the
closed form.

CLI
---
    python python/beamstop_tools/report/springstop_reference.py SCENE.json --modes N \
        --t-end 0.5 --dt 1e-4 --out out.csv [--k K] [--c C] [--method DOP853]

writes t, tip_w, tip_v, force, contact and prints contact onsets, run time,
max tip_w and the estimated error of the reference (difference to a run at
a tighter tolerance, and optionally to the "exact" method).
"""
from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import dataclass

import numpy as np
from scipy import integrate, optimize

EPS = np.finfo(float).eps

# ----------------------------------------------------------------- mode shapes


def cantilever_beta(j: int) -> float:
    """j-th root (1-based) of cos(b) + sech(b) = 0, i.e. cos(b) cosh(b) = -1.

    f(b) = cos b + sech b has exactly one root in ((j-1) pi, j pi)."""
    f = lambda b: math.cos(b) + 1.0 / math.cosh(b) if b < 700 else math.cos(b)
    lo, hi = (j - 1) * math.pi, j * math.pi
    if j == 1:
        lo = 1.0
    b = optimize.brentq(f, lo, hi, xtol=1e-300, rtol=4 * EPS, maxiter=200)
    # one Newton polish (f' = -sin b - sech b tanh b)
    fp = -math.sin(b) - (math.tanh(b) / math.cosh(b) if b < 700 else 0.0)
    if fp != 0.0:
        b2 = b - f(b) / fp
        if abs(b2 - b) < 1e-12 * b:
            b = b2
    return b


def stable_coefficients(b: float) -> np.ndarray:
    """(a1, a2, a3, a4) of W~ from the clamped-free boundary conditions.

    Rows (divided by b^k so all entries are O(1)):
      W(0)        = a1        + a3 e^-b + a4
      W'(0)/b     =       a2  + a3 e^-b - a4
      W''(1)/b^2  = -a1 cos b - a2 sin b + a3 + a4 e^-b
      W'''(1)/b^3 =  a1 sin b - a2 cos b + a3 - a4 e^-b
    The null vector is taken from the SVD; sign chosen so W''(0) > 0
    (the textbook convention W = cosh - cos - s (sinh - sin)), scaled so that
    int_0^1 W~^2 = 1 (normalised later by quadrature; here a1 = -1 first)."""
    e = math.exp(-b)
    cb, sb = math.cos(b), math.sin(b)
    M = np.array([
        [1.0, 0.0, e, 1.0],
        [0.0, 1.0, e, -1.0],
        [-cb, -sb, 1.0, e],
        [sb, -cb, 1.0, -e],
    ])
    _, s, vt = np.linalg.svd(M)
    a = vt[-1]
    a = a / -a[0]  # a1 = -1 as in the textbook form
    # W''(0)/b^2 = -a1 + a3 e^-b + a4 must be > 0
    if -a[0] + a[2] * e + a[3] < 0:
        a = -a
    return a


def shape_tilde(a: np.ndarray, b: float, xi, deriv: int = 0):
    """W~^(deriv)(xi) / b^deriv for xi in [0, 1] (stable form)."""
    xi = np.asarray(xi, dtype=float)
    c, s = np.cos(b * xi), np.sin(b * xi)
    e1, e0 = np.exp(-b * (1.0 - xi)), np.exp(-b * xi)
    if deriv == 0:
        return a[0] * c + a[1] * s + a[2] * e1 + a[3] * e0
    if deriv == 1:
        return -a[0] * s + a[1] * c + a[2] * e1 - a[3] * e0
    if deriv == 2:
        return -a[0] * c - a[1] * s + a[2] * e1 + a[3] * e0
    if deriv == 3:
        return a[0] * s - a[1] * c + a[2] * e1 - a[3] * e0
    raise ValueError(deriv)


def textbook_shape(b: float, xi):
    """cosh - cos - s (sinh - sin): loses every digit past mode ~12 in double."""
    xi = np.asarray(xi, dtype=float)
    s = (math.cosh(b) + math.cos(b)) / (math.sinh(b) + math.sin(b))
    return np.cosh(b * xi) - np.cos(b * xi) - s * (np.sinh(b * xi) - np.sin(b * xi))


def _gauss_panels(b: float):
    """Composite Gauss-Legendre nodes/weights on [0, 1], fine enough for cos(b xi)."""
    panels = max(4, int(math.ceil(b / 3.0)))
    x, w = np.polynomial.legendre.leggauss(24)
    edges = np.linspace(0.0, 1.0, panels + 1)
    h = np.diff(edges)
    nodes = (edges[:-1, None] + 0.5 * h[:, None] * (x[None, :] + 1.0)).ravel()
    weights = (0.5 * h[:, None] * w[None, :]).ravel()
    return nodes, weights


@dataclass
class CantileverMode:
    j: int
    beta: float
    a: np.ndarray      # coefficients of W~, scaled so int_0^1 W~^2 dxi = 1
    mean: float        # int_0^1 W~ dxi

    def __call__(self, xi, deriv=0):
        return shape_tilde(self.a, self.beta, xi, deriv) * self.beta ** deriv


def cantilever_mode(j: int) -> CantileverMode:
    b = cantilever_beta(j)
    a = stable_coefficients(b)
    nodes, weights = _gauss_panels(b)
    m2 = float(weights @ shape_tilde(a, b, nodes) ** 2)
    a = a / math.sqrt(m2)
    e = math.exp(-b)
    mean = (a[0] * math.sin(b) + a[1] * (1.0 - math.cos(b)) + (a[2] + a[3]) * (1.0 - e)) / b
    return CantileverMode(j, b, a, mean)


# ----------------------------------------------------------------- the model


@dataclass
class Model:
    """Modal description of one scene truncated to n modes."""
    n: int
    L: float
    mu: float
    EI: float
    zeta: float
    omega: np.ndarray        # natural circular frequencies
    damp: np.ndarray         # 2 zeta omega
    W_stop: np.ndarray       # W_j(x_stop)
    W_tip: np.ndarray        # W_j(L) (the tip sensor)
    intW: np.ndarray         # int_0^L W_j dx
    loads: list              # (modal force vector b_j, Omega, waveform) with rhs b sin(Omega t)
    side: float              # +1 / -1
    gap: float
    k: float
    c: float
    modes: list
    base_loads: list = None  # (amplitude, Omega, waveform) of a_b(t)

    @property
    def has_stop(self) -> bool:
        return self.k != 0.0 or self.c != 0.0

    def modal_force(self, t: float) -> np.ndarray:
        f = np.zeros(self.n)
        for b, om, wf in self.loads:
            f += b * (math.sin(om * t) if wf == "sin" else math.cos(om * t))
        return f

    def base_acceleration(self, t: float) -> float:
        return sum(amp * (math.sin(om * t) if wf == "sin" else math.cos(om * t))
                   for amp, om, wf in self.base_loads)


def build_model(scene: dict, n_modes: int | None = None, k: float | None = None,
                c: float | None = None) -> Model:
    st = scene["structure"]
    if st.get("type", "beam") != "beam" or st.get("support", "clamped-free") != "clamped-free":
        raise NotImplementedError("only clamped-free beams")
    n = int(n_modes if n_modes is not None else st["modes"])
    L, E, I, rho, A = (float(st[key]) for key in ("length", "E", "I", "rho", "A"))
    mu, EI = rho * A, E * I
    zeta = float(scene.get("damping", {}).get("zeta", 0.0))
    modes = [cantilever_mode(j) for j in range(1, n + 1)]
    beta = np.array([m.beta for m in modes])
    omega = beta ** 2 * math.sqrt(EI / (mu * L ** 4))
    norm = 1.0 / math.sqrt(mu * L)  # W_j(x) = W~_j(x / L) / sqrt(mu L)
    intW = np.array([m.mean for m in modes]) * L * norm

    loads, base_loads = [], []
    for ld in scene.get("loads", []):
        if ld["type"] != "base_excitation":
            raise NotImplementedError(f"load type {ld['type']}")
        wf = ld.get("waveform", "sin")
        if wf not in ("sin", "cos"):
            raise NotImplementedError(f"waveform {wf}")
        amp, om = float(ld["amplitude"]), float(ld["omega"])
        loads.append((-mu * amp * intW, om, wf))
        base_loads.append((amp, om, wf))

    stops = scene.get("stops", [])
    if len(stops) > 1:
        raise NotImplementedError("one stop")
    if stops:
        sp = stops[0]
        law = sp["law"]
        if law["type"] != "spring_dashpot":
            raise NotImplementedError(f"stop law {law['type']}")
        x_s, gap = float(sp["x"]), float(sp["gap"])
        side = 1.0 if sp.get("side", "positive") == "positive" else -1.0
        kk, cc = float(law["k"]), float(law.get("c", 0.0))
    else:
        x_s, gap, side, kk, cc = L, 0.0, 1.0, 0.0, 0.0
    if k is not None:
        kk = float(k)
    if c is not None:
        cc = float(c)
    if kk < 0 or cc < 0:
        raise ValueError("k, c must be >= 0")
    W_stop = np.array([float(m(x_s / L)) for m in modes]) * norm
    W_tip = np.array([float(m(1.0)) for m in modes]) * norm
    return Model(n, L, mu, EI, zeta, omega, 2.0 * zeta * omega, W_stop, W_tip, intW,
                 loads, side, gap, kk, cc, modes, base_loads)


# ----------------------------------------------------------------- phase functions
# state y = (q_1..q_n, qd_1..qd_n); phase 0 = free, 1 = contact


class Dynamics:
    def __init__(self, m: Model):
        self.m = m
        n = m.n
        self.n = n
        self.w2 = m.omega ** 2
        self.d = m.damp
        self.sw = m.side * m.W_stop          # p = sw . q - gap
        self.sp = m.k + m.c * m.omega[0]    # force-per-metre scale of p in min(.,.)
        self.loads = m.loads

    def forcing(self, t):
        if len(self.loads) == 1:
            b, om, wf = self.loads[0]
            return b * (math.sin(om * t) if wf == "sin" else math.cos(om * t))
        return self.m.modal_force(t)

    def rhs_free(self, t, y):
        n = self.n
        out = np.empty_like(y)
        out[:n] = y[n:]
        out[n:] = self.forcing(t) - self.d * y[n:] - self.w2 * y[:n]
        return out

    def rhs_contact(self, t, y):
        n = self.n
        q, v = y[:n], y[n:]
        F = self.m.k * (self.sw @ q - self.m.gap) + self.m.c * (self.sw @ v)
        out = np.empty_like(y)
        out[:n] = v
        out[n:] = self.forcing(t) - self.d * v - self.w2 * q - F * self.sw
        return out

    def rhs(self, phase):
        return self.rhs_contact if phase else self.rhs_free

    def pen(self, y):
        n = self.n
        return self.sw @ y[:n] - self.m.gap, self.sw @ y[n:]

    def force(self, y, phase):
        if not phase:
            return 0.0
        p, pd = self.pen(y)
        return self.m.k * p + self.m.c * pd

    def g(self, phase, t, y):
        """Switching function of `phase` and its time derivative under that
        phase's dynamics.  Free: min(sp p, k p + c p') rising through 0;
        contact: k p + c p' falling through 0."""
        k, c = self.m.k, self.m.c
        p, pd = self.pen(y)
        if c == 0.0:
            return k * p, k * pd
        pdd = self.sw @ self.rhs(phase)(t, y)[self.n:]
        G, dG = k * p + c * pd, k * pd + c * pdd
        if phase:
            return G, dG
        P, dP = self.sp * p, self.sp * pd
        return (P, dP) if P <= G else (G, dG)

    def direction(self, phase):
        return -1.0 if phase else 1.0


def _bracket(direction, t0, g0, dg0, t1, g1, dg1):
    """Does the directional switching function s = direction * g cross 0
    upward in [t0, t1]?  Returns the upper end of a bracket, or None.
    Plain sign change, or a grazing double crossing: s < 0 at both ends,
    s' > 0 at t0 and < 0 at t1, tangents meeting above 0 (then the caller
    looks for the maximum first)."""
    s0, s1 = direction * g0, direction * g1
    if s0 < 0.0 <= s1:
        return "sign"
    if s0 < 0.0 and s1 < 0.0 and direction * dg0 > 0.0 and direction * dg1 < 0.0:
        d0, d1 = direction * dg0, direction * dg1
        tc = (s1 - s0 + d0 * t0 - d1 * t1) / (d0 - d1)
        if s0 + d0 * (tc - t0) > 0.0:
            return "graze"
    return None


# ----------------------------------------------------------------- ODE path


class _OdeRunner:
    def __init__(self, dyn: Dynamics, method: str, rtol: float, atol: np.ndarray):
        self.dyn, self.rtol, self.atol = dyn, rtol, atol
        self.cls = getattr(integrate, method)
        self.nfev = 0
        self.nsteps = 0

    def solver(self, phase, t0, y0, t_bound, first_step=None):
        kw = {}
        if first_step is not None:
            kw["first_step"] = first_step
        return self.cls(self.dyn.rhs(phase), t0, y0, t_bound, rtol=self.rtol, atol=self.atol, **kw)

    def integrate_to(self, phase, t0, y0, t1):
        if t1 == t0:
            return y0.copy()
        s = self.solver(phase, t0, y0, t1)
        while s.status == "running":
            s.step()
        if s.status != "finished":
            raise RuntimeError(f"integration failed: {s.status}")
        self.nfev += s.nfev
        return s.y.copy()


def _locate(dyn, phase, kind, t0, t1, g0, dg0, state_at):
    """Root of direction*g in [t0, t1] rising through 0; state_at(t) gives y."""
    dirn = dyn.direction(phase)
    sfun = lambda s: dirn * dyn.g(phase, s, state_at(s))[0]
    hi = t1
    if kind == "graze":
        dsfun = lambda s: dirn * dyn.g(phase, s, state_at(s))[1]
        try:
            tmax = optimize.brentq(dsfun, t0, t1, xtol=1e-300, rtol=4 * EPS)
        except ValueError:  # the interpolant's slope does not change sign after all
            return None
        if sfun(tmax) < 0.0:
            return None
        hi = tmax
    if sfun(t0) >= 0.0:  # interpolant disagrees in the last bits: take the start
        return t0
    if sfun(hi) < 0.0:
        return None
    return optimize.brentq(sfun, t0, hi, xtol=1e-300, rtol=4 * EPS, maxiter=200)


class _Output:
    def __init__(self, grid, n):
        self.grid = grid
        m = len(grid)
        self.y = np.zeros((m, 2 * n))
        self.phase = np.zeros(m, dtype=np.int8)
        self.i = 0

    def fill(self, t_hi, inclusive, state_many, phase):
        """Fill grid points up to t_hi with state_many(times) -> (2n, m)."""
        g = self.grid
        j = np.searchsorted(g, t_hi, side="right" if inclusive else "left")
        if j > self.i:
            ts = g[self.i:j]
            self.y[self.i:j] = np.asarray(state_many(ts)).T.reshape(len(ts), -1)
            self.phase[self.i:j] = phase
            self.i = j


def _scales(m: Model):
    qs = max(m.gap, 1e-3) * math.sqrt(m.mu * m.L)
    return np.concatenate([np.full(m.n, qs), m.omega * qs])


def _simulate_ode(m, dyn, t_end, grid, method, rtol, atol_rel, max_events):
    atol = atol_rel * _scales(m)
    run = _OdeRunner(dyn, method, rtol, atol)
    out = _Output(grid, m.n)
    t, y, phase = 0.0, np.zeros(2 * m.n), 0
    onsets, separations = [], []
    out.fill(0.0, True, lambda ts: np.repeat(y[:, None], len(ts), axis=1), phase)
    stuck = 0
    last_event = None
    first_step = None
    grazes = noswitch = 0
    while t < t_end:
        s = run.solver(phase, t, y, t_end, first_step)
        use_events = m.has_stop
        g0, dg0 = dyn.g(phase, t, y) if use_events else (0.0, 0.0)
        event = None
        while s.status == "running":
            t_old, y_old = s.t, s.y.copy()
            s.step()
            run.nsteps += 1
            if s.status == "failed":
                raise RuntimeError(f"{method} failed at t = {t_old}: {s.message}")
            t_new = s.t
            if use_events:
                g1, dg1 = dyn.g(phase, t_new, s.y)
                kind = _bracket(dyn.direction(phase), t_old, g0, dg0, t_new, g1, dg1)
                if kind is not None:
                    interp = s.dense_output()
                    tr = _locate(dyn, phase, kind, t_old, t_new, g0, dg0, interp)
                    if tr is not None:
                        event = (t_old, y_old, t_new, tr, interp)
                        grazes += kind == "graze"
                        break
                g0, dg0 = g1, dg1
            interp = s.dense_output()
            y_new = s.y.copy()
            out.fill(t_new, True, lambda ts: np.where(ts[None, :] == t_new, y_new[:, None], interp(ts)),
                     phase)
            first_step = s.h_abs if hasattr(s, "h_abs") else None
        run.nfev += s.nfev
        if event is None:
            t, y = s.t, s.y.copy()
            break
        t_old, y_old, t_new, tr, interp = event
        first_step = getattr(s, "h_abs", None)
        # state at the root at step-endpoint accuracy, root polished by Newton
        yr = run.integrate_to(phase, t_old, y_old, tr)
        for _ in range(4):
            gr, dgr = dyn.g(phase, tr, yr)
            if dgr == 0.0:
                break
            dt = -gr / dgr
            if abs(dt) <= 2 * EPS * max(abs(tr), 1e-300) or not (t_old < tr + dt <= t_new):
                break
            tr = tr + dt
            yr = run.integrate_to(phase, t_old, y_old, tr)
        out.fill(tr, False, interp, phase)
        # does the switching function really move across?  (a zero-length
        # phase is impossible: the new phase's function starts moving away)
        _, dgr = dyn.g(phase, tr, yr)
        if dyn.direction(phase) * dgr > 0.0:
            (separations if phase else onsets).append((tr, yr.copy()))
            phase = 1 - phase
            stuck = 0
        else:
            noswitch += 1
            stuck = stuck + 1 if last_event == tr else 1
            if stuck > 5:
                raise RuntimeError(f"no progress at a switch at t = {tr}")
        last_event = tr
        t, y = tr, yr
        if len(onsets) > max_events:
            raise RuntimeError(f"more than {max_events} contacts")
    out.fill(np.inf, True, lambda ts: np.repeat(y[:, None], len(ts), axis=1), phase)
    return out, onsets, separations, {"nsteps": run.nsteps, "nfev": run.nfev,
                                      "grazes": grazes, "noswitch": noswitch}


# ----------------------------------------------------------------- exact path


class _LtiPhase:
    """y' = A y + b0 + sum_l b_l {sin|cos}(Omega_l t) in closed form."""

    def __init__(self, m: Model, dyn: Dynamics, phase: int):
        n = m.n
        K = np.diag(dyn.w2)
        C = np.diag(dyn.d)
        b0 = np.zeros(2 * n)
        if phase:
            K = K + m.k * np.outer(dyn.sw, dyn.sw)
            C = C + m.c * np.outer(dyn.sw, dyn.sw)
            b0[n:] = m.k * m.gap * dyn.sw
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        A[n:, :n] = -K
        A[n:, n:] = -C
        self.A = A
        lam, V = np.linalg.eig(A)
        self.lam, self.V = lam, V
        self.Vinv = np.linalg.inv(V)
        self.cond = np.linalg.cond(V)
        self.yc = np.linalg.solve(A, -b0)  # static particular solution
        self.harm = []
        for b, om, wf in m.loads:
            bl = np.zeros(2 * n)
            bl[n:] = b
            Z = np.linalg.solve(1j * om * np.eye(2 * n) - A, bl.astype(complex))
            self.harm.append((Z, om, wf))
        self.maxlam = float(np.max(np.abs(lam)))

    def particular(self, ts):
        ts = np.atleast_1d(ts)
        yp = np.repeat(self.yc[:, None], len(ts), axis=1).astype(float)
        for Z, om, wf in self.harm:
            e = np.exp(1j * om * ts)[None, :]
            yp += (Z[:, None] * e).imag if wf == "sin" else (Z[:, None] * e).real
        return yp

    def start(self, t0, y0):
        self.t0 = t0
        self.coef = self.Vinv @ (y0 - self.particular(t0)[:, 0])

    def __call__(self, ts):
        scalar = np.ndim(ts) == 0
        ts = np.atleast_1d(np.asarray(ts, dtype=float))
        E = np.exp(self.lam[:, None] * (ts - self.t0)[None, :]) * self.coef[:, None]
        y = (self.V @ E).real + self.particular(ts)
        return y[:, 0] if scalar else y


def _simulate_exact(m, dyn, t_end, grid, max_events):
    phases = [_LtiPhase(m, dyn, 0), _LtiPhase(m, dyn, 1) if m.has_stop else None]
    out = _Output(grid, m.n)
    t, y, phase = 0.0, np.zeros(2 * m.n), 0
    onsets, separations = [], []
    out.fill(0.0, True, lambda ts: np.repeat(y[:, None], len(ts), axis=1), phase)
    nsamples = 0
    stuck, last_event = 0, None
    grazes = noswitch = 0
    chunk = 4096
    while t < t_end:
        P = phases[phase]
        P.start(t, y)
        if not m.has_stop:
            out.fill(np.inf, True, P, phase)
            return out, onsets, separations, {"nsteps": 0, "nfev": 0, "cond": P.cond,
                                              "grazes": 0, "noswitch": 0}
        h = 0.25 / P.maxlam
        dirn = dyn.direction(phase)
        event = None
        ta = t
        while ta < t_end and event is None:
            ts = ta + h * np.arange(chunk + 1)
            ts[ts > t_end] = t_end
            ts = np.unique(ts)
            Y = P(ts)
            nsamples += len(ts) - 1
            gs = np.array([dyn.g(phase, ti, Y[:, i]) for i, ti in enumerate(ts)]) if m.c != 0.0 \
                else np.stack([m.k * (dyn.sw @ Y[:m.n] - m.gap), m.k * (dyn.sw @ Y[m.n:])], axis=1)
            s = dirn * gs[:, 0]
            ds = dirn * gs[:, 1]
            sign = (s[:-1] < 0.0) & (s[1:] >= 0.0)
            graze = (s[:-1] < 0.0) & (s[1:] < 0.0) & (ds[:-1] > 0.0) & (ds[1:] < 0.0)
            if graze.any():
                t0_, t1_ = ts[:-1], ts[1:]
                with np.errstate(divide="ignore", invalid="ignore"):
                    tc = (s[1:] - s[:-1] + ds[:-1] * t0_ - ds[1:] * t1_) / (ds[:-1] - ds[1:])
                    graze &= s[:-1] + ds[:-1] * (tc - t0_) > 0.0
            cand = np.nonzero(sign | graze)[0]
            for i in cand:
                kind = "sign" if sign[i] else "graze"
                tr = _locate(dyn, phase, kind, ts[i], ts[i + 1], gs[i, 0], gs[i, 1], P)
                if tr is not None:
                    event = tr
                    grazes += kind == "graze"
                    break
            if event is None:
                out.fill(ts[-1], True, P, phase)
                ta = ts[-1]
        if event is None:
            t, y = t_end, P(t_end)
            break
        tr = event
        for _ in range(4):
            gr, dgr = dyn.g(phase, tr, P(tr))
            if dgr == 0.0:
                break
            dt = -gr / dgr
            if abs(dt) <= 2 * EPS * abs(tr) or abs(dt) > h:
                break
            tr += dt
        out.fill(tr, False, P, phase)
        yr = P(tr)
        _, dgr = dyn.g(phase, tr, yr)
        if dirn * dgr > 0.0:
            (separations if phase else onsets).append((tr, yr.copy()))
            phase = 1 - phase
            stuck = 0
        else:
            noswitch += 1
            stuck = stuck + 1 if last_event == tr else 1
            if stuck > 5:
                raise RuntimeError(f"no progress at a switch at t = {tr}")
        last_event = tr
        t, y = tr, yr
        if len(onsets) > max_events:
            raise RuntimeError(f"more than {max_events} contacts")
    out.fill(np.inf, True, lambda ts: np.repeat(y[:, None], len(ts), axis=1), phase)
    return out, onsets, separations, {"nsteps": nsamples, "nfev": 0,
                                      "grazes": grazes, "noswitch": noswitch,
                                      "cond": max(p.cond for p in phases if p is not None)}


# ----------------------------------------------------------------- public API


def simulate(scene: dict, n_modes: int, t_end: float, dt: float, rtol: float = 1e-13,
             k: float | None = None, c: float | None = None, method: str = "DOP853",
             atol_rel: float | None = None, max_events: int = 1_000_000) -> dict:
    """Integrate the scene from rest to t_end; outputs on t = 0, dt, 2 dt, ...

    Returns numpy arrays: t, tip_w, tip_v (relative to the base, at x = L),
    force (stop force, >= 0), contact (0/1), q, qd (modal states, rows = times),
    onsets, separations (switch times), onset_tip_w/_v, separation_tip_w/_v
    (tip state at the switches), 0-d arrays run_time, n_steps, n_grazes,
    n_noswitch, and omega, W_tip, W_stop, intW (the modal data used).
    `method`: a scipy OdeSolver name ("DOP853", "Radau", ...) or "exact".
    atol per state component = atol_rel * scale, scale = gap sqrt(mu L) for
    q_j and omega_j gap sqrt(mu L) for qd_j; atol_rel defaults to 1e-3 rtol."""
    m = build_model(scene, n_modes, k, c)
    dyn = Dynamics(m)
    nt = int(round(t_end / dt))
    grid = dt * np.arange(nt + 1)
    grid[-1] = min(grid[-1], t_end) if abs(grid[-1] - t_end) > 1e-12 * t_end else t_end
    if atol_rel is None:
        atol_rel = 1e-3 * rtol
    t0 = time.perf_counter()
    if method == "exact":
        out, on, sep, stats = _simulate_exact(m, dyn, t_end, grid, max_events)
    else:
        out, on, sep, stats = _simulate_ode(m, dyn, t_end, grid, method, rtol, atol_rel, max_events)
    run_time = time.perf_counter() - t0
    n = m.n
    q, qd = out.y[:, :n], out.y[:, n:]
    p = q @ dyn.sw - m.gap
    force = np.where(out.phase == 1, m.k * p + m.c * (qd @ dyn.sw), 0.0)
    res = {
        "t": grid,
        "tip_w": q @ m.W_tip,
        "tip_v": qd @ m.W_tip,
        "force": force,
        "contact": out.phase.astype(np.int64),
        "q": q,
        "qd": qd,
        "onsets": np.array([e[0] for e in on]),
        "separations": np.array([e[0] for e in sep]),
        # tip displacement / velocity at the switches (from the located state)
        "onset_tip_w": np.array([e[1][:n] @ m.W_tip for e in on]),
        "onset_tip_v": np.array([e[1][n:] @ m.W_tip for e in on]),
        "separation_tip_w": np.array([e[1][:n] @ m.W_tip for e in sep]),
        "separation_tip_v": np.array([e[1][n:] @ m.W_tip for e in sep]),
        "run_time": np.array(run_time),
        "n_steps": np.array(stats["nsteps"]),
        "n_grazes": np.array(stats["grazes"]),      # events found by the double-crossing search
        "n_noswitch": np.array(stats["noswitch"]),  # located roots where g did not move across
        "omega": m.omega,
        "W_tip": m.W_tip,
        "W_stop": m.W_stop,
        "intW": m.intW,
    }
    if "cond" in stats:
        res["cond"] = np.array(stats["cond"])
    return res


# ----------------------------------------------------------------- self-test


def self_test(verbose: bool = True) -> None:
    """Stable shapes vs the textbook form (modes 1-6), identities, BCs."""
    worst = 0.0
    xi = np.linspace(0.0, 1.0, 201)
    for j in range(1, 7):
        md = cantilever_mode(j)
        tb = textbook_shape(md.beta, xi)
        err = np.max(np.abs(md(xi) - tb)) / np.max(np.abs(tb))
        worst = max(worst, err)
        # the textbook form itself carries ~ cosh(beta) eps of cancellation
        assert err < 1e-14 + 20 * EPS * math.cosh(md.beta), (j, err)
    # the stable form against the textbook form in extended arithmetic
    try:
        import mpmath as mp
    except ImportError:  # pragma: no cover
        mp = None
    worst_mp = 0.0
    if mp is not None:
        xs = [0.0, 0.05, 0.13, 0.5, 0.77, 0.96, 1.0]
        for j in (1, 2, 5, 12, 20, 40):
            md = cantilever_mode(j)
            # cosh - s sinh cancels ~ beta / ln 10 digits: carry them all
            mp.mp.dps = 30 + int(md.beta / 2.0)
            b = mp.findroot(lambda z: mp.cos(z) + 1 / mp.cosh(z), md.beta)
            assert abs(float(b) - md.beta) <= 4 * EPS * md.beta, (j, float(b), md.beta)
            s_ = (mp.cosh(b) + mp.cos(b)) / (mp.sinh(b) + mp.sin(b))
            for x in xs:
                ref = mp.cosh(b * x) - mp.cos(b * x) - s_ * (mp.sinh(b * x) - mp.sin(b * x))
                e_ = abs(float(md(x)) - float(ref))
                worst_mp = max(worst_mp, e_)
                assert e_ < 1e-12, (j, x, e_)
    for j in (1, 2, 3, 7, 12, 20, 40, 80):
        md = cantilever_mode(j)
        b = md.beta
        # boundary conditions
        bc = [md(0.0), md(0.0, 1) / b, md(1.0, 2) / b ** 2, md(1.0, 3) / b ** 3]
        assert max(abs(float(v)) for v in bc) < 1e-12, (j, bc)
        # tip value of the unit-mean-square cantilever mode is +-2
        assert abs(abs(float(md(1.0))) - 2.0) < 1e-11, (j, float(md(1.0)))
        # mean: quadrature vs closed form vs the textbook identity 2 s / beta
        nodes, weights = _gauss_panels(b)
        qm = float(weights @ md(nodes))
        assert abs(qm - md.mean) < 1e-13, (j, qm, md.mean)
        if b < 300:
            s_tb = (math.cosh(b) + math.cos(b)) / (math.sinh(b) + math.sin(b))
            assert abs(2 * s_tb / b - md.mean) < 1e-13, (j, 2 * s_tb / b, md.mean)
        # orthogonality with mode 1
        m1 = cantilever_mode(1)
        if j > 1:
            o = float(weights @ (md(nodes) * m1(nodes)))
            assert abs(o) < 1e-12, (j, o)
    if verbose:
        print(f"self-test ok: stable vs textbook shapes (double), modes 1-6, max rel diff {worst:.1e};"
              f" vs extended-precision textbook, modes 1-40, max abs diff {worst_mp:.1e}")


# ----------------------------------------------------------------- CLI


def _write_csv(path, res):
    cols = np.column_stack([res["t"], res["tip_w"], res["tip_v"], res["force"], res["contact"]])
    np.savetxt(path, cols, delimiter=",", header="t,tip_w,tip_v,force,contact", comments="",
               fmt=["%.10g", "%.17g", "%.17g", "%.17g", "%d"])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--modes", type=int, default=None)
    ap.add_argument("--t-end", type=float, default=0.5)
    ap.add_argument("--dt", type=float, default=1e-4)
    ap.add_argument("--out", default=None)
    ap.add_argument("--k", type=float, default=None)
    ap.add_argument("--c", type=float, default=None)
    ap.add_argument("--method", default="DOP853")
    ap.add_argument("--rtol", type=float, default=1e-13)
    ap.add_argument("--check-rtol", type=float, default=None,
                    help="tolerance of the error-estimate run (default: max(rtol/100, 100 eps))")
    ap.add_argument("--no-check", action="store_true", help="skip the error-estimate run")
    ap.add_argument("--exact-check", action="store_true",
                    help="also compare with the closed-form piecewise-LTI solution")
    ap.add_argument("--self-test", action="store_true")
    a = ap.parse_args(argv)
    if a.self_test:
        self_test()
    with open(a.scene) as fh:
        scene = json.load(fh)
    n = a.modes if a.modes is not None else int(scene["structure"]["modes"])
    gap = float(scene["stops"][0]["gap"]) if scene.get("stops") else 1.0
    res = simulate(scene, n, a.t_end, a.dt, rtol=a.rtol, k=a.k, c=a.c, method=a.method)
    if a.out:
        _write_csv(a.out, res)
    print(f"scene {scene.get('name')}  modes {n}  method {a.method}  rtol {a.rtol:g}  "
          f"t_end {a.t_end:g}  dt {a.dt:g}")
    print(f"  contact onsets      {len(res['onsets'])}")
    print(f"  run time            {float(res['run_time']):.2f} s  ({int(res['n_steps'])} steps)")
    if int(res["n_grazes"]) or int(res["n_noswitch"]):
        print(f"  grazing events      {int(res['n_grazes'])} found by the double-crossing search, "
              f"{int(res['n_noswitch'])} tangential roots without a switch")
    print(f"  max tip_w           {res['tip_w'].max():.9e} m  (gap {gap:g} m)")
    print(f"  max force           {res['force'].max():.6e} N")

    def compare(other, label):
        dd = np.abs(other["tip_w"] - res["tip_w"])
        d = np.max(dd)
        bad = np.nonzero(dd > 1e-10 * gap)[0]
        dv = np.max(np.abs(other["tip_v"] - res["tip_v"]))
        no = len(other["onsets"])
        dton = (np.max(np.abs(other["onsets"] - res["onsets"])) if no == len(res["onsets"]) and no
                else float("nan"))
        print(f"  vs {label}: max|d tip_w| {d:.3e} m = {d / gap:.2e} gap, max|d tip_v| {dv:.3e} m/s, "
              f"onsets {no}, max|d t_onset| {dton:.2e} s  ({float(other['run_time']):.2f} s)")
        if len(bad):
            print(f"    difference exceeds 1e-10 gap from t = {res['t'][bad[0]]:.4f} s on")
        return d

    if not a.no_check and a.method != "exact":
        rt = a.check_rtol if a.check_rtol is not None else max(a.rtol / 100, 100 * EPS)
        other = simulate(scene, n, a.t_end, a.dt, rtol=rt, k=a.k, c=a.c, method=a.method)
        compare(other, f"{a.method} rtol {rt:.3g} (error estimate)")
    if a.exact_check and a.method != "exact":
        other = simulate(scene, n, a.t_end, a.dt, k=a.k, c=a.c, method="exact")
        compare(other, f"exact piecewise-LTI (cond(V) {float(other['cond']):.1e})")
    return res


if __name__ == "__main__":
    main()
