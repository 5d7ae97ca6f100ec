# The project's reference peer, given to the project with its issues; copied unchanged below this line (benches/peers/README.md).
"""Peer 1: a numba-compiled event-driven DOP853 (a port of scipy's solve_ivp DOP853:
same tableau, same step control, same 7th-order dense output, events located by
Brent's method on the dense output) for the pinned beam with a rigid stop: modal
restitution (eq. 28), chatter threshold, sticking with the closed-form Lagrange
multiplier, release when the multiplier changes sign. The whole event loop runs
compiled (one call per simulation).

P = params(F, Omega, R, d, zeta, eps, x_stop=0.4, N=4) in the VSM12 scaled units (see params());
run(P, t_end, rtol, atol) returns the impact times, the state and the step statistics."""
import math
import numpy as np
import numba as nb
from scipy.integrate._ivp import dop853_coefficients as _c

A = np.ascontiguousarray(_c.A, dtype=np.float64)      # (16, 16)
B = np.ascontiguousarray(_c.B, dtype=np.float64)      # (12,)
C = np.ascontiguousarray(_c.C, dtype=np.float64)      # (16,)
E3 = np.ascontiguousarray(_c.E3, dtype=np.float64)    # (13,)
E5 = np.ascontiguousarray(_c.E5, dtype=np.float64)    # (13,)
D = np.ascontiguousarray(_c.D, dtype=np.float64)      # (4, 16)
NS = 12
EPS = np.finfo(float).eps


def params(F, Omega, R, d, zeta, eps, x_stop=0.4, N=4):
    j = np.arange(1, N + 1)
    om = (j * np.pi) ** 2
    phi = np.sqrt(2) * np.sin(j * np.pi * x_stop)
    alpha = np.sqrt(2) * (1 - np.cos(j * np.pi)) / (j * np.pi)
    # P: om(4) phi(4) alpha*F(4) Omega zeta d R eps
    return np.concatenate([om, phi, alpha * F, [Omega, zeta, d, R, eps]]).astype(np.float64)


@nb.njit(cache=True, inline='always')
def rhs(t, y, P, stick, out):
    s = math.sin(P[12] * t)
    z = P[13]
    pa = 0.0
    pp = 0.0
    for j in range(4):
        om = P[j]
        a = -2.0 * z * om * y[4 + j] - om * om * y[j] + P[8 + j] * s
        out[j] = y[4 + j]
        out[4 + j] = a
        pa += P[4 + j] * a
        pp += P[4 + j] * P[4 + j]
    if stick:
        lam = -pa / pp
        for j in range(4):
            out[4 + j] += P[4 + j] * lam


@nb.njit(cache=True)
def lam_of(t, y, P):
    s = math.sin(P[12] * t)
    z = P[13]
    pa = 0.0
    pp = 0.0
    for j in range(4):
        om = P[j]
        a = -2.0 * z * om * y[4 + j] - om * om * y[j] + P[8 + j] * s
        pa += P[4 + j] * a
        pp += P[4 + j] * P[4 + j]
    return -pa / pp


@nb.njit(cache=True)
def event(t, y, P, stick, t_start, v_start):
    if stick:
        return lam_of(t, y, P)
    dt = t - t_start
    if dt <= 0.0:
        return v_start
    g = -P[14]
    for j in range(4):
        g += P[4 + j] * y[j]
    return g / dt


@nb.njit(cache=True)
def rms(x):
    s = 0.0
    for i in range(x.shape[0]):
        s += x[i] * x[i]
    return math.sqrt(s / x.shape[0])


@nb.njit(cache=True)
def dense_eval(t, t_old, h, y_old, F, out):
    x = (t - t_old) / h
    for i in range(8):
        out[i] = 0.0
    for k in range(7):
        f = F[6 - k]
        for i in range(8):
            out[i] += f[i]
            if k % 2 == 0:
                out[i] *= x
            else:
                out[i] *= 1.0 - x
    for i in range(8):
        out[i] += y_old[i]


@nb.njit(cache=True)
def ev_dense(t, t_old, h, y_old, F, P, stick, t_start, v_start, tmp):
    dense_eval(t, t_old, h, y_old, F, tmp)
    return event(t, tmp, P, stick, t_start, v_start)


@nb.njit(cache=True)
def brentq_dense(xa, xb, fa, fb, t_old, h, y_old, F, P, stick, t_start, v_start, tmp):
    # port of scipy's brentq (xtol = rtol = 4 eps, as solve_ivp's event location)
    xtol = 4 * 2.220446049250313e-16
    rtol = 4 * 2.220446049250313e-16
    xpre, xcur = xa, xb
    fpre, fcur = fa, fb
    xblk = 0.0
    fblk = 0.0
    spre = 0.0
    scur = 0.0
    if fpre == 0.0:
        return xpre
    if fcur == 0.0:
        return xcur
    for it in range(200):
        if fpre != 0.0 and fcur != 0.0 and (fpre < 0.0) != (fcur < 0.0):
            xblk = xpre
            fblk = fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre = xcur
            xcur = xblk
            xblk = xpre
            fpre = fcur
            fcur = fblk
            fblk = fpre
        delta = (xtol + rtol * abs(xcur)) / 2
        sbis = (xblk - xcur) / 2
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2 * abs(stry) < min(abs(spre), 3 * abs(sbis) - delta):
                spre = scur
                scur = stry
            else:
                spre = sbis
                scur = sbis
        else:
            spre = sbis
            scur = sbis
        xpre = xcur
        fpre = fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0 else -delta
        fcur = ev_dense(xcur, t_old, h, y_old, F, P, stick, t_start, v_start, tmp)
    return xcur


@nb.njit(cache=True)
def select_initial_step(t0, y0, f0, P, stick, t_bound, rtol, atol, tmp, f1):
    scale = atol + np.abs(y0) * rtol
    d0 = rms(y0 / scale)
    d1 = rms(f0 / scale)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, t_bound - t0)
    for i in range(8):
        tmp[i] = y0[i] + h0 * f0[i]
    rhs(t0 + h0, tmp, P, stick, f1)
    d2 = rms((f1 - f0) / scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100 * h0, h1, t_bound - t0)


@nb.njit(cache=True)
def simulate(P, y0, t_end, rtol, atol, max_events, A, B, C, E3, E5, D):
    """Returns (impacts, n_imp, sticks(start,end), n_st, y_final, nsteps, nfev, ok)."""
    R = P[15]
    epsc = P[16]
    d = P[14]
    pp = 0.0
    for j in range(4):
        pp += P[4 + j] * P[4 + j]
    impacts = np.empty(max_events)
    sticks = np.empty((max_events, 2))
    n_imp = 0
    n_st = 0
    y = y0.copy()
    t = 0.0
    K = np.empty((16, 8))
    F = np.empty((7, 8))
    ynew = np.empty(8)
    fnew = np.empty(8)
    f = np.empty(8)
    tmp = np.empty(8)
    tmp2 = np.empty(8)
    yold = np.empty(8)
    err5 = np.empty(8)
    err3 = np.empty(8)
    last_imp = -np.inf
    nsteps = 0
    nfev = 0
    # start stuck?
    g0 = -d
    v0 = 0.0
    for j in range(4):
        g0 += P[4 + j] * y[j]
        v0 += P[4 + j] * y[4 + j]
    stick = abs(g0) < 1e-14 and abs(v0) < 1e-14 and lam_of(0.0, y, P) <= 0.0
    stick_start = 0.0
    ok = True
    nseg = 0
    while t < t_end and nseg < max_events:
        nseg += 1
        if stick:
            g = -d
            v = 0.0
            for j in range(4):
                g += P[4 + j] * y[j]
                v += P[4 + j] * y[4 + j]
            for j in range(4):
                y[j] += (-g) / pp * P[4 + j]
                y[4 + j] -= v / pp * P[4 + j]
        t_start = t
        v_start = 0.0
        for j in range(4):
            v_start += P[4 + j] * y[4 + j]
        # one solve_ivp call: integrate until the terminal event or t_end
        rhs(t, y, P, stick, f)
        nfev += 1
        h_abs = select_initial_step(t, y, f, P, stick, t_end, rtol, atol, tmp, tmp2)
        nfev += 1
        g_old = event(t, y, P, stick, t_start, v_start)
        hit = False
        while True:
            min_step = 10 * abs(np.nextafter(t, np.inf) - t)
            if h_abs < min_step:
                h_abs = min_step
            accepted = False
            rejected = False
            while not accepted:
                if h_abs < min_step:
                    return impacts, n_imp, sticks, n_st, y, nsteps, nfev, False
                t_new = t + h_abs
                if t_new > t_end:
                    t_new = t_end
                h = t_new - t
                h_abs = abs(h)
                # rk step
                for i in range(8):
                    K[0, i] = f[i]
                for s in range(1, NS):
                    for i in range(8):
                        tmp[i] = 0.0
                    for k in range(s):
                        a = A[s, k] * h
                        if a != 0.0:
                            for i in range(8):
                                tmp[i] += K[k, i] * a
                    for i in range(8):
                        tmp[i] += y[i]
                    rhs(t + C[s] * h, tmp, P, stick, K[s])
                for i in range(8):
                    ynew[i] = 0.0
                for k in range(NS):
                    bk = B[k] * h
                    if bk != 0.0:
                        for i in range(8):
                            ynew[i] += K[k, i] * bk
                for i in range(8):
                    ynew[i] += y[i]
                rhs(t + h, ynew, P, stick, fnew)
                nfev += NS
                for i in range(8):
                    K[NS, i] = fnew[i]
                # error norm
                for i in range(8):
                    err5[i] = 0.0
                    err3[i] = 0.0
                for k in range(NS + 1):
                    c5 = E5[k]
                    c3 = E3[k]
                    for i in range(8):
                        err5[i] += K[k, i] * c5
                        err3[i] += K[k, i] * c3
                e5 = 0.0
                e3 = 0.0
                for i in range(8):
                    sc = atol + max(abs(y[i]), abs(ynew[i])) * rtol
                    e5 += (err5[i] / sc) ** 2
                    e3 += (err3[i] / sc) ** 2
                if e5 == 0.0 and e3 == 0.0:
                    err = 0.0
                else:
                    err = h_abs * e5 / math.sqrt((e5 + 0.01 * e3) * 8)
                if err < 1.0:
                    if err == 0.0:
                        fac = 10.0
                    else:
                        fac = min(10.0, 0.9 * err ** (-1.0 / 8.0))
                    if rejected:
                        fac = min(1.0, fac)
                    h_abs *= fac
                    accepted = True
                else:
                    h_abs *= max(0.2, 0.9 * err ** (-1.0 / 8.0))
                    rejected = True
            nsteps += 1
            t_old = t
            for i in range(8):
                yold[i] = y[i]
            t = t_new
            for i in range(8):
                y[i] = ynew[i]
                f[i] = fnew[i]
            g_new = event(t, y, P, stick, t_start, v_start)
            if g_old <= 0.0 and g_new >= 0.0 and g_old != g_new:
                # dense output (3 extra stages), then Brent on it
                for s in range(NS + 1, 16):
                    for i in range(8):
                        acc = 0.0
                        for k in range(s):
                            acc += K[k, i] * A[s, k]
                        tmp[i] = yold[i] + acc * h
                    rhs(t_old + C[s] * h, tmp, P, stick, K[s])
                nfev += 3
                for i in range(8):
                    dy = y[i] - yold[i]
                    F[0, i] = dy
                    F[1, i] = h * K[0, i] - dy
                    F[2, i] = 2 * dy - h * (f[i] + K[0, i])
                    for r in range(4):
                        acc = 0.0
                        for k in range(16):
                            acc += D[r, k] * K[k, i]
                        F[3 + r, i] = h * acc
                te = brentq_dense(t_old, t, g_old, g_new, t_old, h, yold, F, P, stick, t_start, v_start, tmp)
                dense_eval(te, t_old, h, yold, F, y)
                t = te
                hit = True
                break
            g_old = g_new
            if t >= t_end:
                break
        if not hit:
            break
        if stick:
            sticks[n_st, 0] = stick_start
            sticks[n_st, 1] = t
            n_st += 1
            stick = False
            last_imp = -np.inf
        else:
            vi = 0.0
            for j in range(4):
                vi += P[4 + j] * y[4 + j]
            chatter = (t - last_imp) < epsc
            r = 0.0 if chatter else R
            for j in range(4):
                y[4 + j] -= (1.0 + r) * vi / pp * P[4 + j]
            if n_imp < max_events:
                impacts[n_imp] = t
            n_imp += 1
            last_imp = t
            if chatter:
                stick = True
                stick_start = t
    if stick:
        sticks[n_st, 0] = stick_start
        sticks[n_st, 1] = t
        n_st += 1
    return impacts, n_imp, sticks, n_st, y, nsteps, nfev, ok


def fastmath_variant():
    """The same source compiled with fastmath=True (reassociation, FMA contraction)."""
    import types as _t
    src = open(__file__).read().replace("@nb.njit(cache=True", "@nb.njit(fastmath=True")
    mod = _t.ModuleType('peer_dop853_fastmath')
    mod.__file__ = __file__
    exec(compile(src, __file__ + ' [fastmath]', 'exec'), mod.__dict__)
    return mod


def run(P, t_end, rtol, atol, max_events=100000):
    imp, n, st, ns, y, nsteps, nfev, ok = simulate(P, np.zeros(8), t_end, rtol, atol, max_events, A, B, C, E3, E5, D)
    return dict(impacts=imp[:min(n, max_events)].copy(), sticks=st[:ns].copy(), final=y.copy(),
                nsteps=nsteps, nfev=nfev, ok=ok)
