"""Event-driven reference in extended precision for any scene of the report,
sticking included (used for S3 and S4, and as a second closed form for S1/S2).

Every phase is linear and time invariant with harmonic (and constant) forcing:
    z' = A z + b0 + bs sin(Omega t) + bc cos(Omega t).
Its exact solution is z(t) = zc + Re(Y e^{i Omega t}) + V e^{Lambda (t - t0)} V^{-1} (z0 - zp(t0)),
with zc = -A^{-1} b0, Y = (i Omega - A)^{-1} (bc - i bs) and A = V Lambda V^{-1},
all computed by mpmath at `dps` digits.
  free flight: z = (q, qd), A = [[0, I], [-K, -D]];
  sticking:    q = qc + N eta, qd = N etad with N an orthonormal basis of
               w's null space and qc = d w / (w.w): the constrained motion
               (w.qdd = 0) in its own coordinates, A = [[0, I], [-N'KN, -N'DN]].
Events: the gap g = d - w.q falling through zero (free), the reaction
lambda = (w.(K q + D qd) - w.f)/(w.w) rising through zero (stuck). Each
event is bracketed by probes in extended precision at t0 + h 4^-k (so that
chatter flights down to 1e-15 h are seen), then by a float64 scan of the
same closed form on a grid of h (sign changes and local minima), and
refined by mpmath.findroot. The impact law (eq. 28), the chatter rule and
the projection at the start of sticking are applied at `dps` digits.
"""
from __future__ import annotations

import math

import mpmath
import numpy as np
from scipy.optimize import minimize_scalar

from .models import Scene


def _mp_vec(x):
    return mpmath.matrix([mpmath.mpf(v) for v in x])


class Phase:
    """z' = A z + b0 + bs sin + bc cos, exactly (mp) and in float64."""

    def __init__(self, A, b0, bs, bc, Om):
        m = A.rows
        self.m = m
        self.Om = Om
        I = mpmath.eye(m)
        self.zc = -mpmath.lu_solve(A, b0) if any(x != 0 for x in b0) else mpmath.matrix(m, 1)
        rhs = mpmath.matrix([bc[i] - 1j * bs[i] for i in range(m)])
        self.Y = mpmath.lu_solve(1j * Om * I - A, rhs)
        E, V = mpmath.eig(A)
        self.lam = E
        self.V = V
        self.Vi = mpmath.inverse(V)
        # float64 copies
        self.fzc = np.array([float(x) for x in self.zc])
        self.fY = np.array([complex(x) for x in self.Y])
        self.flam = np.array([complex(x) for x in E])
        self.fV = np.array([[complex(V[i, j]) for j in range(m)] for i in range(m)])
        self.fVi = np.array([[complex(self.Vi[i, j]) for j in range(m)] for i in range(m)])
        self.fOm = float(Om)

    def zp(self, t):
        e = mpmath.expj(self.Om * t)
        return mpmath.matrix([self.zc[i] + mpmath.re(self.Y[i] * e) for i in range(self.m)])

    def coeffs(self, t0, z0):
        h0 = z0 - self.zp(t0)
        return self.Vi * h0

    def state(self, t, t0, c):
        tau = t - t0
        ex = mpmath.matrix([mpmath.exp(l * tau) * ci for l, ci in zip(self.lam, c)])
        h = self.V * ex
        zp = self.zp(t)
        return mpmath.matrix([zp[i] + mpmath.re(h[i]) for i in range(self.m)])

    def f_state(self, t, t0, c_float):
        t = np.atleast_1d(np.asarray(t, float))
        tau = (t - float(t0))[:, None]
        ex = np.exp(self.flam[None, :] * tau) * c_float[None, :]
        h = (ex @ self.fV.T).real
        zp = self.fzc[None, :] + (self.fY[None, :] * np.exp(1j * self.fOm * t)[:, None]).real
        return zp + h


class MpReference:
    def __init__(self, scene: Scene, dps: int = 40, perturb: float = 0.0):
        mp = mpmath.mp
        mp.dps = dps
        self.s = scene
        self.dps = dps
        n = scene.n
        self.n = n
        f = mpmath.mpf
        if scene.kind == "beam":
            pi = mp.pi
            om = [(j * pi) ** 2 for j in range(1, n + 1)]
            K = mpmath.diag([o * o for o in om])
            D = mpmath.diag([2 * f(scene.zeta) * o for o in om])
            w = mpmath.matrix([mpmath.sqrt(2) * mpmath.sin(j * pi * f(scene.x_s)) for j in range(1, n + 1)])
            alpha = [mpmath.sqrt(2) * (1 - mpmath.cos(j * pi)) / (j * pi) for j in range(1, n + 1)]
            fs = mpmath.matrix([a * f(scene.F) for a in alpha])
            fc = mpmath.matrix(n, 1)
        else:
            K = mpmath.matrix([[f(x) for x in row] for row in scene.K])
            D = mpmath.matrix([[f(x) for x in row] for row in scene.D])
            w = _mp_vec(scene.w)
            fs = _mp_vec(scene.fs)
            fc = _mp_vec(scene.fc)
        self.K, self.D, self.w, self.fs, self.fc = K, D, w, fs, fc
        self.Om = f(scene.Omega)
        self.d = f(scene.d)
        self.R = f(scene.R)
        self.eps = f(scene.eps)
        self.ww = (w.T * w)[0]
        Z, I = mpmath.matrix(n, n), mpmath.eye(n)
        zero = mpmath.matrix(2 * n, 1)
        A = _block(Z, I, -K, -D)
        self.free = Phase(A, zero, _stack(mpmath.matrix(n, 1), fs), _stack(mpmath.matrix(n, 1), fc), self.Om)
        # sticking: null space of w
        basis = [w / mpmath.sqrt(self.ww)]
        for k in range(n):
            v = mpmath.matrix(n, 1)
            v[k] = 1
            for b in basis:
                v = v - (b.T * v)[0] * b
            nv = mpmath.norm(v)
            if nv > mpmath.mpf(10) ** (-dps // 2):
                basis.append(v / nv)
            if len(basis) == n:
                break
        Nm = mpmath.matrix(n, n - 1)
        for c in range(n - 1):
            for r in range(n):
                Nm[r, c] = basis[c + 1][r]
        self.N = Nm
        self.qc = w * (self.d / self.ww)
        m = n - 1
        Kr = Nm.T * K * Nm
        Dr = Nm.T * D * Nm
        Zr, Ir = mpmath.matrix(m, m), mpmath.eye(m)
        Ar = _block(Zr, Ir, -Kr, -Dr)
        b0 = _stack(mpmath.matrix(m, 1), -(Nm.T * K * self.qc))
        self.stuck_phase = Phase(Ar, b0, _stack(mpmath.matrix(m, 1), Nm.T * fs),
                                 _stack(mpmath.matrix(m, 1), Nm.T * fc), self.Om)
        self.lam_q = (w.T * K)  # row
        self.lam_qd = (w.T * D)
        q0 = _mp_vec(scene.q0)
        if perturb:
            q0[1] = q0[1] + f(perturb) * max(abs(q0[0]), 1)
        self.z0 = _stack(q0, _mp_vec(scene.qd0))
        # float copies for the scan
        self.fw = np.array([float(x) for x in w])
        self.fd = float(self.d)
        self.fN = np.array([[float(Nm[r, c]) for c in range(m)] for r in range(n)])
        self.fqc = np.array([float(x) for x in self.qc])
        self.fK = np.array([[float(K[r, c]) for c in range(n)] for r in range(n)])
        self.fD = np.array([[float(D[r, c]) for c in range(n)] for r in range(n)])
        self.ffs = np.array([float(x) for x in fs])
        self.ffc = np.array([float(x) for x in fc])
        freqs = [abs(complex(x).imag) for x in list(self.free.lam) + list(self.stuck_phase.lam)]
        freqs = [x for x in freqs if x > 0] + ([float(scene.Omega)] if scene.Omega > 0 else [])
        self.h = min(2 * math.pi / x for x in freqs) / 64.0

    # ---- phase helpers ----------------------------------------------------------
    def full_from_reduced(self, zr):
        n = self.n
        m = n - 1
        eta = mpmath.matrix([zr[i] for i in range(m)])
        etad = mpmath.matrix([zr[m + i] for i in range(m)])
        return self.qc + self.N * eta, self.N * etad

    def reduced_from_full(self, q, qd):
        eta = self.N.T * (q - self.qc)
        etad = self.N.T * qd
        return _stack(eta, etad)

    def lam_of(self, t, q, qd):
        fvec = self.fs * mpmath.sin(self.Om * t) + self.fc * mpmath.cos(self.Om * t)
        return ((self.lam_q * q)[0] + (self.lam_qd * qd)[0] - (self.w.T * fvec)[0]) / self.ww

    def event_mp(self, stuck, t, t0, c):
        n = self.n
        if not stuck:
            z = self.free.state(t, t0, c)
            q = mpmath.matrix([z[i] for i in range(n)])
            return self.d - (self.w.T * q)[0]
        z = self.stuck_phase.state(t, t0, c)
        q, qd = self.full_from_reduced(z)
        return self.lam_of(t, q, qd)

    def event_float(self, stuck, t, t0, cf):
        n = self.n
        if not stuck:
            z = self.free.f_state(t, t0, cf)
            return self.fd - z[:, :n] @ self.fw
        m = n - 1
        z = self.stuck_phase.f_state(t, t0, cf)
        q = self.fqc[None, :] + z[:, :m] @ self.fN.T
        qd = z[:, m:] @ self.fN.T
        t = np.atleast_1d(t)
        fv = np.sin(self.s.Omega * t)[:, None] * self.ffs + np.cos(self.s.Omega * t)[:, None] * self.ffc
        return (q @ self.fK.T @ self.fw + qd @ self.fD.T @ self.fw - fv @ self.fw) / float(self.ww)

    def next_event(self, stuck, t0, c, t_end):
        """First time after t0 where the event function (gap, or -lambda
        while stuck, both positive while nothing happens) reaches zero."""
        sign = -1 if stuck else 1
        phase = self.stuck_phase if stuck else self.free
        cf = np.array([complex(x) for x in c])
        h = self.h

        def fm(t):
            return sign * self.event_mp(stuck, t, t0, c)

        def ff(t):
            return sign * self.event_float(stuck, t, t0, cf)

        # geometric probes in extended precision
        # values within rounding of zero are undecided (after a release the
        # gap leaves zero like tau^3)
        noise = mpmath.mpf(10) ** (-(self.dps - 8))
        prev = None
        for k in range(26, -1, -1):
            tk = t0 + h * mpmath.mpf(4) ** (-k)
            if tk > t_end:
                break
            v = fm(tk)
            if v <= -noise and prev is not None:
                return self._refine(fm, prev, tk)
            if v > noise:
                prev = tk
        if prev is None:
            raise RuntimeError(f"event function stays within rounding of zero after t = {t0}")
        lo = float(t0) + h
        while lo < t_end:
            hi = min(lo + 4000 * h, t_end)
            ts = np.arange(lo, hi + 0.5 * h, h)
            ts = ts[ts <= t_end]
            if len(ts) == 0:
                break
            g = ff(ts)
            neg = np.nonzero(g <= 0.0)[0]
            first = neg[0] if neg.size else len(g)
            for i in range(1, min(first, len(g) - 1)):
                if g[i] <= g[i - 1] and g[i] <= g[i + 1]:
                    r = minimize_scalar(lambda x: float(ff(x)[0]), bounds=(ts[i - 1], ts[i + 1]), method="bounded",
                                        options={"xatol": 1e-14})
                    if r.fun <= 0.0 or fm(mpmath.mpf(r.x)) <= 0:
                        return self._refine(fm, mpmath.mpf(ts[i - 1]), mpmath.mpf(r.x))
            if first < len(g):
                a = mpmath.mpf(ts[first - 1]) if first > 0 else prev
                b = mpmath.mpf(ts[first])
                if fm(a) <= 0:
                    # the float scan and the extended precision disagree on the
                    # sign at a root that sits on a grid point: step back
                    b = a
                    a = mpmath.mpf(ts[first - 2]) if first > 1 else prev
                    if fm(a) <= 0:
                        a = prev
                return self._refine(fm, a, b)
            prev = mpmath.mpf(ts[-1]) if fm(mpmath.mpf(ts[-1])) > 0 else prev
            lo = ts[-1] + h
        return None

    def _refine(self, fm, a, b):
        fa, fb = fm(a), fm(b)
        if fa < 0 or fb > 0:
            raise RuntimeError(f"bad bracket [{a}, {b}]: {fa}, {fb}")
        if fb == 0:
            return b
        # a few bisections to get inside the quadratic basin, then Anderson-Bjorck
        for _ in range(8):
            mid = (a + b) / 2
            fmid = fm(mid)
            if fmid > 0:
                a, fa = mid, fmid
            else:
                b, fb = mid, fmid
        r = mpmath.findroot(fm, (a, b), solver="anderson", tol=mpmath.mpf(10) ** (-2 * self.dps + 10), maxsteps=200)
        if not (a <= r <= b):
            raise RuntimeError(f"root {r} outside [{a}, {b}]")
        return r

    # ---- the run ---------------------------------------------------------------
    def solve(self, t_end: float, max_events: int = 5000):
        n = self.n
        t = mpmath.mpf(0)
        z = self.z0
        q = mpmath.matrix([z[i] for i in range(n)])
        qd = mpmath.matrix([z[n + i] for i in range(n)])
        stuck = self.s.start_stuck
        self.impacts, self.sticks, self.releases = [], [], []
        self.anchors = []  # (t0, stuck, coeffs)
        prev = None
        T = mpmath.mpf(t_end)
        for _ in range(max_events):
            if stuck:
                zr = self.reduced_from_full(q, qd)
                c = self.stuck_phase.coeffs(t, zr)
            else:
                c = self.free.coeffs(t, _stack(q, qd))
            self.anchors.append((t, stuck, c))
            te = self.next_event(stuck, t, c, t_end)
            if te is None:
                break
            if stuck:
                zr = self.stuck_phase.state(te, t, c)
                q, qd = self.full_from_reduced(zr)
                t = te
                stuck = False
                prev = None
                self.releases.append(te)
                continue
            z = self.free.state(te, t, c)
            q = mpmath.matrix([z[i] for i in range(n)])
            qd = mpmath.matrix([z[n + i] for i in range(n)])
            t = te
            vn = (self.w.T * qd)[0]
            if vn <= 0:
                raise RuntimeError(f"graze at t = {te}")
            chatter = prev is not None and te - prev < self.eps
            r = 0 if chatter else self.R
            qd = qd - self.w * ((1 + r) * vn / self.ww)
            self.impacts.append(te)
            prev = te
            if chatter and self.lam_of(te, q, qd) <= 0:
                stuck = True
                prev = None
                self.sticks.append(te)
                q = q + self.w * ((self.d - (self.w.T * q)[0]) / self.ww)
                qd = qd - self.w * ((self.w.T * qd)[0] / self.ww)
        else:
            raise RuntimeError("too many events")
        t0, st, c = self.anchors[-1]
        if st:
            qf, qdf = self.full_from_reduced(self.stuck_phase.state(T, t0, c))
        else:
            z = self.free.state(T, t0, c)
            qf = mpmath.matrix([z[i] for i in range(n)])
            qdf = mpmath.matrix([z[n + i] for i in range(n)])
        self.final = np.array([float(x) for x in list(qf) + list(qdf)])
        self.final_mp = list(qf) + list(qdf)
        return self.impacts

    def dense_w(self, times: np.ndarray) -> np.ndarray:
        starts = np.array([float(a[0]) for a in self.anchors])
        idx = np.searchsorted(starts, times, side="right") - 1
        out = np.empty(len(times))
        n = self.n
        for k in np.unique(idx):
            msk = idx == k
            t0, st, c = self.anchors[k]
            cf = np.array([complex(x) for x in c])
            if st:
                out[msk] = self.fd
            else:
                z = self.free.f_state(times[msk], t0, cf)
                out[msk] = z[:, :n] @ self.fw
        return out


def _block(A, B, C, D):
    n, m = A.rows, A.cols
    M = mpmath.matrix(2 * n, 2 * m)
    for i in range(n):
        for j in range(m):
            M[i, j] = A[i, j]
            M[i, m + j] = B[i, j]
            M[n + i, j] = C[i, j]
            M[n + i, m + j] = D[i, j]
    return M


def _stack(a, b):
    return mpmath.matrix(list(a) + list(b))
