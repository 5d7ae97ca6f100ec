"""An independent model of scenes/tapping_arm.json (the TappingArm FMU),
written from the equations, not from beamstop's code: the clamped-free
beam's modes from the characteristic equation cos b cosh b = -1 and the
classical shapes cosh - cos - sigma (sinh - sin), their modal integrals by
Gauss-Legendre quadrature; the first-order (geometric stiffening, KRB87)
equations of a beam on a hub whose angle is prescribed (DWZ's kinematics,
R = 0, no gravity):

    M B'' = theta'^2 (M - D) B - K B - C B' - Gamma theta'' - F d gamma / dB

with M = mu L I, K = EI / L^3 diag(b^4), Gamma_i = mu int x phi_i,
D_ij = mu int (L^2 - x^2) / 2 phi_i' phi_j', C = 2 zeta omega_i M, the tip
at A(theta) [L - B^T C_L B / 2, w . B] (C_L = int phi_i' phi_j', w = phi(L))
and the penetration gamma = Y_tip of the plane y = 0 (normal (0, -1));
Lankarani-Nikravesh contact F = K gamma^1.5 (1 + 3 (1 - e^2) / 4 gamma' / v0)
while positive, v0 the speed at the onset. scipy's DOP853 with an event at
the onset.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar


def clamped_free_roots(n: int) -> np.ndarray:
    f = lambda b: math.cos(b) + 1.0 / math.cosh(b)  # cos b cosh b = -1, scaled
    return np.array([brentq(f, (j - 0.5) * math.pi - 0.2, (j - 0.5) * math.pi + 0.4, xtol=1e-15) for j in range(1, n + 1)])


class Model:
    def __init__(self, scene: dict):
        beam = scene["beam"]
        self.L, self.mu, self.EI = beam["length"], beam["mass_per_length"], beam["bending_stiffness"]
        n = self.n = scene["n_modes"]
        L, mu = self.L, self.mu
        b = clamped_free_roots(n)
        sigma = (np.sinh(b) - np.sin(b)) / (np.cosh(b) + np.cos(b))
        xi, wq = np.polynomial.legendre.leggauss(200)
        xi, wq = 0.5 * (xi + 1.0), 0.5 * wq  # on [0, 1]
        bx = np.outer(b, xi)
        W = np.cosh(bx) - np.cos(bx) - sigma[:, None] * (np.sinh(bx) - np.sin(bx))
        dW = b[:, None] * (np.sinh(bx) + np.sin(bx) - sigma[:, None] * (np.cosh(bx) - np.cos(bx)))
        norm = np.sqrt((W**2) @ wq)  # shapes of unit mean square
        W, dW = W / norm[:, None], dW / norm[:, None]
        self.w = (np.cosh(b) - np.cos(b) - sigma * (np.sinh(b) - np.sin(b))) / norm
        self.M = mu * L * np.eye(n)
        self.omega = b**2 * math.sqrt(self.EI / (mu * L**4))
        self.K = np.diag(self.omega**2) * mu * L
        self.Gamma = mu * L**2 * (W * xi) @ wq
        self.D = mu * L * (dW * (0.5 * (1 - xi**2) * wq)) @ dW.T
        self.CL = (dW * wq) @ dW.T / L
        self.C = np.diag(2 * scene.get("modal_damping", 0.0) * self.omega) * mu * L
        law = scene["surface"]["law"]
        self.Kc, self.alpha = law["K"], 0.75 * (1 - law["e"] ** 2)
        hub = scene["hub"]["prescribed"]
        self.theta0, self.A, self.Omega = scene["initial"].get("theta", 0.0), hub["A"], hub["Omega"]
        self.Minv = np.linalg.inv(self.M)
        self.MmD = self.M - self.D

    def hub(self, t):
        s, c = math.sin(self.Omega * t), math.cos(self.Omega * t)
        return self.theta0 + self.A * s, self.A * self.Omega * c, -self.A * self.Omega**2 * s

    def penetration(self, t, y):
        """gamma = Y of the tip, its rate, and d gamma / dB."""
        n = self.n
        B, Bd = y[:n], y[n:]
        th, thd, _ = self.hub(t)
        s, c = math.sin(th), math.cos(th)
        X = self.L - 0.5 * B @ self.CL @ B
        V = self.w @ B
        gamma = s * X + c * V
        rate = c * thd * X + s * (-(B @ self.CL @ Bd)) - s * thd * V + c * (self.w @ Bd)
        grad = s * (-(self.CL @ B)) + c * self.w
        return gamma, rate, grad

    def rhs(self, t, y, v0):
        n = self.n
        B, Bd = y[:n], y[n:]
        _, thd, thdd = self.hub(t)
        q = thd**2 * (self.MmD @ B) - self.K @ B - self.C @ Bd - self.Gamma * thdd
        if v0 is not None:
            gamma, rate, grad = self.penetration(t, y)
            if gamma > 0:
                q = q - max(0.0, self.Kc * gamma**1.5 * (1 + self.alpha * rate / v0)) * grad
        return np.concatenate([Bd, self.Minv @ q])

    def force(self, t, y, v0):
        gamma, rate, _ = self.penetration(t, y)
        if gamma <= 0 or v0 is None:
            return 0.0
        return max(0.0, self.Kc * gamma**1.5 * (1 + self.alpha * rate / v0))

    def run(self, t_end: float, rtol=1e-9):
        """The first strike: its onset time and speed, the peak force, the
        contact's end, and the state at `t_end` (at rest in the rotating frame at 0)."""
        y0 = np.zeros(2 * self.n)
        onset = lambda t, y: self.penetration(t, y)[0]
        onset.terminal, onset.direction = True, 1
        atol = 1e-14
        free = solve_ivp(lambda t, y: self.rhs(t, y, None), (0, t_end), y0, method="DOP853", rtol=rtol, atol=atol,
                         events=onset)
        t_on, y_on = free.t_events[0][0], free.y_events[0][0]
        v0 = self.penetration(t_on, y_on)[1]
        leave = lambda t, y: self.penetration(t, y)[0]
        leave.terminal, leave.direction = True, -1
        hit = solve_ivp(lambda t, y: self.rhs(t, y, v0), (t_on, t_end), y_on, method="DOP853", rtol=rtol, atol=atol,
                        events=leave, dense_output=True)
        ts = np.linspace(t_on, hit.t[-1], 101)
        k = int(np.argmax([self.force(t, hit.sol(t), v0) for t in ts]))
        best = minimize_scalar(lambda t: -self.force(t, hit.sol(t), v0), bounds=(ts[max(k - 1, 0)], ts[min(k + 1, 100)]),
                               method="bounded", options={"xatol": 1e-12})
        peak = -best.fun
        t_off, y_off = hit.t_events[0][0], hit.y_events[0][0]
        after = solve_ivp(lambda t, y: self.rhs(t, y, None), (t_off, t_end), y_off, method="DOP853", rtol=rtol, atol=atol)
        return {"onset": t_on, "speed": v0, "peak_force": peak, "separation": t_off, "state": after.y[:, -1],
                "tip_w": self.w @ after.y[: self.n, -1]}
