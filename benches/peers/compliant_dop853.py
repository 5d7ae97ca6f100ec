# The project's reference peer, given to the project with its issues; copied unchanged below this line (benches/peers/README.md).
"""compliant_dop853: numba-compiled event-driven DOP853 peers for beamstop's compliant-stop scenes.

One integrator (a port of scipy's solve_ivp DOP853: same tableau, same error norm and step
control, same 7th-order dense output; the event loop compiled), two models:

  model 0  base-excited clamped-free cantilever, N mass-normalised modes (relative to the
           moving clamp), tip stop at x = L a gap g0 above the rest position, mounted on the base:
             q_j'' + 2 zeta w_j q_j' + w_j^2 q_j = -Gam_j a_b(t) - F phi_j(L)
             a_b(t) = A sin(Omega t)  (scene 'amplitude' = base acceleration amplitude)
             p = phi(L).q - g0 (penetration), F >= 0 while p > 0:
               spring_dashpot:  F = max(0, k p + c p')
               hertz (LN):      F = max(0, K p^1.5 (1 + a p'/v0)), a = 3(1-e^2)/4,
                                v0 = p' at the onset (the approach speed)
               hertz (HC):      the same with a = 3(1-e)/2;  hertz linear: K p^1.5 + C p'
           (the equations written again from the scene file, independently of beamstop)
  model 1  rotating hub beam, first-order model (KRB87 / DWZ; ../notes/rotating-beam.md)
           (section 3), z = [theta, B_1..B_N], J(z) z'' = Q, Hertz tip contact with a plane
           (section 4), the same force laws with p = gamma = -n.(r_tip - p0).

Phases: 0 free, 1 penetrated (p > 0); within 1 the flag 'pressed' says whether the raw force
is positive (a force zero while penetrated is an event, so the kink lies on a step boundary).
Events (onset p = 0 upward, separation p = 0 downward, raw force through 0) are located by
Brent's method on the dense output; a local maximum of p between two accepted steps (a graze
shorter than a step) is caught by a Brent search for p' = 0 on the dense output.
The step may be capped (hmax per phase): an explicit method without a cap can sit on its
stability boundary (|h w| ~ 6 for DOP853 on the imaginary axis) when the high modes carry no
error-controlled content.
"""
import math
import os
import numpy as np
import numba as nb
from scipy.integrate._ivp import dop853_coefficients as _c
from scipy.optimize import brentq

A = np.ascontiguousarray(_c.A, dtype=np.float64)      # (16, 16)
B = np.ascontiguousarray(_c.B, dtype=np.float64)      # (12,)
C = np.ascontiguousarray(_c.C, dtype=np.float64)      # (16,)
E3 = np.ascontiguousarray(_c.E3, dtype=np.float64)    # (13,)
E5 = np.ascontiguousarray(_c.E5, dtype=np.float64)    # (13,)
D = np.ascontiguousarray(_c.D, dtype=np.float64)      # (4, 16)
NS = 12

LAW_SPRING, LAW_HERTZ = 0, 1
DAMP_LINEAR, DAMP_LN, DAMP_HC = 0, 1, 2


# ------------------------------------------------------------------ clamped-free modes
def cf_roots(n):
    """b_j: roots of cos b cosh b = -1, i.e. cos b + sech b = 0."""
    f = lambda b: math.cos(b) + 1.0 / math.cosh(b)
    out = []
    for j in range(1, n + 1):
        c = (j - 0.5) * math.pi
        lo, hi = (1.0, 2.5) if j == 1 else (c - 0.6, c + 0.6)
        out.append(brentq(f, lo, hi, xtol=1e-15, rtol=8.9e-16, maxiter=200))
    return np.array(out)


def cf_shape(b, xi, d=0):
    """clamped-free W(xi) = cosh - cos - sigma (sinh - sin), int_0^1 W^2 = 1, written with
    decaying exponentials only; d-th derivative with respect to xi."""
    xi = np.asarray(xi, float)
    E = math.exp(-b)
    s, c = math.sin(b), math.cos(b)
    den = 1.0 + (2.0 * s - E) * E
    sig = (1.0 + (2.0 * c + E) * E) / den           # (sinh b - sin b)/(cosh b + cos b)
    ap = (s - c - E) / den                          # (1 - sig) e^b / 2
    am = 0.5 * (1.0 + sig)
    bx = b * xi
    ep = np.exp(b * (xi - 1.0))
    em = np.exp(-bx)
    if d == 0:
        return -np.cos(bx) + sig * np.sin(bx) + ap * ep + am * em
    if d == 1:
        return b * (np.sin(bx) + sig * np.cos(bx) + ap * ep - am * em)
    if d == 2:
        return b * b * (np.cos(bx) - sig * np.sin(bx) + ap * ep + am * em)
    raise ValueError(d)


def cf_sigma(b):
    E = math.exp(-b)
    s, c = math.sin(b), math.cos(b)
    return (1.0 + (2.0 * c + E) * E) / (1.0 + (2.0 * s - E) * E)


def gauss01(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


# ------------------------------------------------------------------ model 0: cantilever
def cantilever_params(scene, overrides=None):
    """P vector, y0, sensor vector, atol unit scales, info dict from a beamstop modal scene."""
    ov = overrides or {}
    st = scene['structure']
    assert st['type'] == 'beam' and st['support'] == 'clamped-free', st
    N = int(st['modes'])
    L, E_, I_, rho, Ar = st['length'], st['E'], st['I'], st['rho'], st['A']
    EI, rhoA = E_ * I_, rho * Ar
    mb = rhoA * L
    b = cf_roots(N)
    om = b ** 2 * math.sqrt(EI / (rhoA * L ** 4))
    zeta = ov.get('zeta', scene['damping']['zeta'])
    phiL = cf_shape_tip(b) / math.sqrt(mb)                    # phi_j(L), int rhoA phi^2 = 1
    Gam = math.sqrt(mb) * 2.0 * np.array([cf_sigma(x) for x in b]) / b   # int rhoA phi_j dx
    loads = [l for l in scene['loads'] if l['type'] == 'base_excitation']
    assert len(loads) == 1 and loads[0]['waveform'] == 'sin' and len(scene['loads']) == 1
    amp = ov.get('amplitude', loads[0]['amplitude'])
    Om = ov.get('omega', loads[0]['omega'])
    (stop,) = scene['stops']
    assert stop['side'] == 'positive' and abs(stop['x'] - L) < 1e-15, stop
    gap = stop['gap']
    law = stop['law']
    k = c = Kh = Ch = a = 0.0
    damp = DAMP_LINEAR
    if law['type'] == 'spring_dashpot':
        lt = LAW_SPRING
        k, c = ov.get('k', law['k']), ov.get('c', law.get('c', 0.0))
    elif law['type'] == 'hertz':
        lt = LAW_HERTZ
        Kh = ov.get('K', law['K'])
        dm = law.get('damping', 'linear')
        if dm == 'linear':
            damp, Ch = DAMP_LINEAR, ov.get('C', law.get('C', 0.0))
        else:
            e = ov.get('e', law['e'])
            damp = DAMP_LN if dm == 'lankarani_nikravesh' else DAMP_HC
            a = 3.0 * (1.0 - e * e) / 4.0 if damp == DAMP_LN else 1.5 * (1.0 - e)
    else:
        raise ValueError(law)
    # P: [N, Omega, gap, law, k, c, K, C, damp, a | om(N) | 2 zeta om(N) | phiL(N) | -Gam amp (N)]
    P = np.concatenate([[N, Om, gap, lt, k, c, Kh, Ch, damp, a], om, 2 * zeta * om, phiL, -Gam * amp])
    y0 = np.zeros(2 * N)
    sens = np.concatenate([phiL, np.zeros(N)])              # tip.w (relative to the base)
    qs = gap / abs(phiL[0])
    unit = np.concatenate([np.full(N, qs), np.full(N, qs * om[0])])
    # the highest free frequency and a contact estimate
    info = dict(N=N, om=om, phiL=phiL, Gam=Gam, gap=gap, w_max_free=om[-1] * math.sqrt(1 + 0 * zeta),
                Omega=Om, law=law['type'])
    Kc = np.diag(om ** 2)
    if lt == LAW_SPRING:
        Kc = Kc + k * np.outer(phiL, phiL)
    info['w_max_contact_linear'] = math.sqrt(np.linalg.eigvalsh(Kc)[-1])
    return P.astype(np.float64), y0, sens, unit, info


def cf_shape_tip(b):
    return np.array([cf_shape(x, 1.0) for x in b], dtype=float)


# ------------------------------------------------------------------ model 1: rotating hub beam
def rotating_params(scene, overrides=None, nq=240):
    ov = overrides or {}
    bm = scene['beam']
    L = bm['length']
    if 'mass_per_length' in bm:
        mu, EI = bm['mass_per_length'], bm['bending_stiffness']
    else:
        mu, EI = bm['rho'] * bm['A'], bm['E'] * bm['I']
    N = int(scene['n_modes'])
    assert scene.get('order', 'first') == 'first'
    assert scene.get('hub', 'torque') == 'torque'
    R = scene.get('hub_radius', 0.0)
    g = scene.get('gravity', 0.0)
    assert g == 0.0, 'gravity not implemented in the peer'
    zeta = ov.get('zeta', scene.get('modal_damping', 0.0))
    Jh = ov.get('J_h', scene['hub_inertia'])
    b = cf_roots(N)
    xg, wg = gauss01(nq)
    W0 = np.array([cf_shape(x, xg, 0) for x in b])
    W1 = np.array([cf_shape(x, xg, 1) for x in b])
    # dimensionless integrals (rho A = L = 1), section 3 table of EQUATIONS.md
    m_hat = np.einsum('ig,jg,g->ij', W0, W0, wg)
    gam_hat = W0 @ (wg * xg)                          # int xi W  (= 2/b^2)
    sig_hat = W0 @ wg                                 # int W     (= 2 sigma/b)
    d_hat = np.einsum('ig,jg,g->ij', W1, W1, wg * 0.5 * (1 - xg ** 2))
    s_hat = np.einsum('ig,jg,g->ij', W1, W1, wg * (1 - xg))
    c_hat = np.einsum('ig,jg,g->ij', W1, W1, wg)
    m = mu * L                                        # M = m I (mass-orthogonal shapes)
    K = EI / L ** 3 * b ** 4                          # diagonal
    Gam = mu * L ** 2 * gam_hat + mu * L * R * sig_hat
    Dm = mu * L * d_hat + mu * R * s_hat
    MmD = m * np.eye(N) - Dm
    CL = c_hat / L
    wL = np.array([cf_shape(x, 1.0) for x in b])
    Jb = mu * ((R + L) ** 3 - R ** 3) / 3.0
    om = np.sqrt(K / m)
    sf = scene['surface']
    n = np.array(sf['normal'], float)
    n = n / np.linalg.norm(n)
    p0 = np.array(sf['point'], float)
    law = sf['law']
    assert law['type'] == 'hertz'
    Kh = ov.get('K', law['K'])
    dm = law.get('damping', 'linear')
    Ch = a = 0.0
    if dm == 'linear':
        damp, Ch = DAMP_LINEAR, ov.get('C', law.get('C', 0.0))
    else:
        e = ov.get('e', law['e'])
        damp = DAMP_LN if dm == 'lankarani_nikravesh' else DAMP_HC
        a = 3.0 * (1.0 - e * e) / 4.0 if damp == DAMP_LN else 1.5 * (1.0 - e)
    tau = ov.get('torque', 0.0)
    ini = scene.get('initial', {})
    th0 = ov.get('theta0', ini.get('theta', 0.0))
    thd0 = ov.get('theta_dot0', ini.get('theta_dot', 0.0))
    B0 = np.array(ini.get('B', [0.0] * N), float)
    Bd0 = np.array(ini.get('B_dot', [0.0] * N), float)
    # P: [N, Jh, Jb, m, R, L, nx, ny, px, py, K, C, damp, a, tau | Gam(N) | K(N) | 2 zeta om m (N) | wL(N) | MmD(NxN) | CL(NxN)]
    P = np.concatenate([[N, Jh, Jb, m, R, L, n[0], n[1], p0[0], p0[1], Kh, Ch, damp, a, tau],
                        Gam, K, 2 * zeta * om * m, wL, MmD.ravel(), CL.ravel()])
    y0 = np.concatenate([[th0], B0, [thd0], Bd0])
    sens = np.zeros(2 * N + 2)
    sens[1:N + 1] = wL                                  # tip.w: deflection in the rotating frame
    info = dict(N=N, om=om, b=b, m_hat=m_hat, gam_hat=gam_hat, sig_hat=sig_hat, d_hat=d_hat,
                s_hat=s_hat, c_hat=c_hat, wL=wL, Jb=Jb, Gam=Gam)
    # linearised spectrum at rest: free hub system (for the step cap)
    J = np.zeros((N + 1, N + 1))
    J[0, 0] = Jh + Jb
    J[0, 1:] = J[1:, 0] = Gam
    J[1:, 1:] = m * np.eye(N)
    Kz = np.zeros((N + 1, N + 1))
    Kz[1:, 1:] = np.diag(K)
    ev = np.linalg.eigvals(np.linalg.solve(J, Kz)).real
    info['w_max_free'] = math.sqrt(ev.max())
    info['J'] = J
    info['Kz'] = Kz
    # contact direction at rest (theta0, B = 0): d gap / dz
    c0, s0 = math.cos(th0), math.sin(th0)
    npr = np.array([c0 * n[0] + s0 * n[1], -s0 * n[0] + c0 * n[1]])
    Jn = np.concatenate([[(R + L) * npr[1]], wL * npr[1]])
    info['Jn0'] = Jn
    unit_q = 1e-3                                       # 1 mm
    unit = np.concatenate([[unit_q / L], np.full(N, unit_q), [unit_q / L * om[0]], np.full(N, unit_q * om[0])])
    return P.astype(np.float64), y0, sens, unit, info


def rotating_contact_wmax(info, Kh, gamma):
    """highest frequency with the tip held by the linearised Hertz spring 1.5 K gamma^0.5."""
    kc = 1.5 * Kh * math.sqrt(gamma)
    Jn = info['Jn0']
    Kz = info['Kz'] + kc * np.outer(Jn, Jn)
    ev = np.linalg.eigvals(np.linalg.solve(info['J'], Kz)).real
    return math.sqrt(ev.max())


# ------------------------------------------------------------------ compiled model code
@nb.njit(cache=True)
def _law(P0, p, pd, v0, lt, k, c, Kh, Ch, damp, a):
    """raw force (may be negative) for penetration p > 0 (p <= 0 treated as 0 for Hertz)."""
    if lt == LAW_SPRING:
        return k * p + c * pd
    pp = p if p > 0.0 else 0.0
    s = pp * math.sqrt(pp)
    if damp == DAMP_LINEAR:
        return Kh * s + Ch * pd
    return Kh * s * (1.0 + a * pd / v0)


@nb.njit(cache=True)
def _fsign(p, pd, v0, lt, k, c, Kh, Ch, damp, a):
    """a smooth function with the sign of the raw force while p > 0 (the 'pressed' event)."""
    if lt == LAW_SPRING:
        return k * p + c * pd
    if damp == DAMP_LINEAR:
        pp = p if p > 0.0 else 0.0
        return Kh * pp * math.sqrt(pp) + Ch * pd
    return 1.0 + a * pd / v0


@nb.njit(cache=True)
def rhs(model, t, y, P, ph, pressed, v0, out, wk):
    if model == 0:
        N = int(P[0])
        Om = P[1]
        s = math.sin(Om * t)
        F = 0.0
        if ph == 1 and pressed:
            p = -P[2]
            pd = 0.0
            for j in range(N):
                p += P[10 + 2 * N + j] * y[j]
                pd += P[10 + 2 * N + j] * y[N + j]
            F = _law(P[0], p, pd, v0, int(P[3]), P[4], P[5], P[6], P[7], int(P[8]), P[9])
        for j in range(N):
            om = P[10 + j]
            out[j] = y[N + j]
            out[N + j] = (-P[10 + N + j] * y[N + j] - om * om * y[j] + P[10 + 3 * N + j] * s
                          - F * P[10 + 2 * N + j])
    else:
        _rhs_rot(t, y, P, ph, pressed, v0, out, wk)


@nb.njit(cache=True)
def _rhs_rot(t, y, P, ph, pressed, v0, out, wk):
    N = int(P[0])
    Jh, Jb, m, R, L = P[1], P[2], P[3], P[4], P[5]
    nx, ny = P[6], P[7]
    tau = P[14]
    o = 15
    oG, oK, oC, ow, oM = o, o + N, o + 2 * N, o + 3 * N, o + 4 * N
    oCL = oM + N * N
    th = y[0]
    thd = y[N + 1]
    # (M - D) B, (M - D) B', B^T (M - D) B, B^T (M - D) B'
    bmb = 0.0
    bmbd = 0.0
    QB = wk[:N]
    for i in range(N):
        acc = 0.0
        for j in range(N):
            acc += P[oM + i * N + j] * y[1 + j]
        bmb += y[1 + i] * acc
        QB[i] = thd * thd * acc - P[oK + i] * y[1 + i] - P[oC + i] * y[N + 2 + i]
    for i in range(N):
        acc = 0.0
        for j in range(N):
            acc += P[oM + i * N + j] * y[N + 2 + j]
        bmbd += y[1 + i] * acc
    J00 = Jh + Jb + bmb
    Qt = tau - 2.0 * thd * bmbd
    if ph == 1 and pressed:
        # tip: X = R + L + u_L, v = w.B ; n' = A^T n
        c, s = math.cos(th), math.sin(th)
        npx = c * nx + s * ny
        npy = -s * nx + c * ny
        uL = 0.0
        vL = 0.0
        CLB = wk[N:2 * N]
        for i in range(N):
            acc = 0.0
            for j in range(N):
                acc += P[oCL + i * N + j] * y[1 + j]
            CLB[i] = acc
            uL -= 0.5 * y[1 + i] * acc
            vL += P[ow + i] * y[1 + i]
        X = R + L + uL
        rx = c * X - s * vL
        ry = s * X + c * vL
        gap = nx * (rx - P[8]) + ny * (ry - P[9])
        p = -gap
        Jn0 = -vL * npx + X * npy
        gd = Jn0 * thd
        for i in range(N):
            gd += (-CLB[i] * npx + P[ow + i] * npy) * y[N + 2 + i]
        pd = -gd
        F = _law(P[0], p, pd, v0, LAW_HERTZ, 0.0, 0.0, P[10], P[11], int(P[12]), P[13])
        Qt += F * Jn0
        for i in range(N):
            QB[i] += F * (-CLB[i] * npx + P[ow + i] * npy)
    # solve [[J00, G^T], [G, m I]] [thdd; Bdd] = [Qt; QB]
    gq = 0.0
    gg = 0.0
    for i in range(N):
        gq += P[oG + i] * QB[i]
        gg += P[oG + i] * P[oG + i]
    thdd = (Qt - gq / m) / (J00 - gg / m)
    out[0] = thd
    out[N + 1] = thdd
    for i in range(N):
        out[1 + i] = y[N + 2 + i]
        out[N + 2 + i] = (QB[i] - P[oG + i] * thdd) / m


@nb.njit(cache=True)
def gvals(model, y, P, v0, out):
    """out[0] = p (penetration), out[1] = p', out[2] = smooth sign function of the raw force."""
    if model == 0:
        N = int(P[0])
        p = -P[2]
        pd = 0.0
        for j in range(N):
            p += P[10 + 2 * N + j] * y[j]
            pd += P[10 + 2 * N + j] * y[N + j]
        out[0] = p
        out[1] = pd
        out[2] = _fsign(p, pd, v0, int(P[3]), P[4], P[5], P[6], P[7], int(P[8]), P[9])
    else:
        N = int(P[0])
        R, L = P[4], P[5]
        nx, ny = P[6], P[7]
        o = 15
        ow = o + 3 * N
        oCL = o + 4 * N + N * N
        th = y[0]
        thd = y[N + 1]
        c, s = math.cos(th), math.sin(th)
        npx = c * nx + s * ny
        npy = -s * nx + c * ny
        uL = 0.0
        vL = 0.0
        gd = 0.0
        for i in range(N):
            acc = 0.0
            for j in range(N):
                acc += P[oCL + i * N + j] * y[1 + j]
            uL -= 0.5 * y[1 + i] * acc
            vL += P[ow + i] * y[1 + i]
            gd += (-acc * npx + P[ow + i] * npy) * y[N + 2 + i]
        X = R + L + uL
        rx = c * X - s * vL
        ry = s * X + c * vL
        gap = nx * (rx - P[8]) + ny * (ry - P[9])
        gd += (-vL * npx + X * npy) * thd
        out[0] = -gap
        out[1] = -gd
        out[2] = _fsign(-gap, -gd, v0, LAW_HERTZ, 0.0, 0.0, P[10], P[11], int(P[12]), P[13])


# ------------------------------------------------------------------ DOP853 machinery
@nb.njit(cache=True)
def dense_eval(t, t_old, h, y_old, F, n, out):
    x = (t - t_old) / h
    for i in range(n):
        out[i] = 0.0
    for k in range(7):
        for i in range(n):
            out[i] += F[6 - k, i]
            if k % 2 == 0:
                out[i] *= x
            else:
                out[i] *= 1.0 - x
    for i in range(n):
        out[i] += y_old[i]


@nb.njit(cache=True)
def ev_dense(model, kind, sgn, t, t_old, h, y_old, F, P, v0, tmp, gv):
    dense_eval(t, t_old, h, y_old, F, y_old.shape[0], tmp)
    gvals(model, tmp, P, v0, gv)
    return sgn * gv[kind]


@nb.njit(cache=True)
def brent_dense(model, kind, sgn, xa, xb, fa, fb, t_old, h, y_old, F, P, v0, tmp, gv):
    """scipy's brentq (xtol = rtol = 4 eps) on sgn * gvals[kind] of the dense output."""
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
        fcur = ev_dense(model, kind, sgn, xcur, t_old, h, y_old, F, P, v0, tmp, gv)
    return xcur


@nb.njit(cache=True)
def _rms_scaled(x, scale):
    s = 0.0
    for i in range(x.shape[0]):
        s += (x[i] / scale[i]) ** 2
    return math.sqrt(s / x.shape[0])


@nb.njit(cache=True)
def select_initial_step(model, t0, y0, f0, P, ph, pressed, v0, t_bound, rtol, atol, tmp, f1, wk):
    n = y0.shape[0]
    scale = np.empty(n)
    for i in range(n):
        scale[i] = atol[i] + abs(y0[i]) * rtol
    d0 = _rms_scaled(y0, scale)
    d1 = _rms_scaled(f0, scale)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, t_bound - t0)
    for i in range(n):
        tmp[i] = y0[i] + h0 * f0[i]
    rhs(model, t0 + h0, tmp, P, ph, pressed, v0, f1, wk)
    s = 0.0
    for i in range(n):
        s += ((f1[i] - f0[i]) / scale[i]) ** 2
    d2 = math.sqrt(s / n) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100 * h0, h1, t_bound - t0)


@nb.njit(cache=True)
def simulate(model, P, y0, t_end, rtol, atol, hmax_free, hmax_contact, tgrid, sens, max_events, fev,
             A, B, C, E3, E5, D):
    """Integrate from 0 to t_end.  Returns
    (y_end, wgrid, onsets, n_on, seps, n_sep, n_toggle, nsteps, nrej, nfev, status)
    wgrid[k] = sens . y(tgrid[k]) from the dense output (tgrid sorted, within [0, t_end])."""
    n = y0.shape[0]
    y = y0.copy()
    t = 0.0
    K = np.empty((16, n))
    F = np.empty((7, n))
    ynew = np.empty(n)
    fnew = np.empty(n)
    f = np.empty(n)
    tmp = np.empty(n)
    tmp2 = np.empty(n)
    yold = np.empty(n)
    wk = np.empty(2 * n)
    gv = np.empty(3)
    gv_old = np.empty(3)
    gv_new = np.empty(3)
    onsets = np.empty(max_events)
    seps = np.empty(max_events)
    n_on = 0
    n_sep = 0
    n_toggle = 0
    ng = tgrid.shape[0]
    wgrid = np.full(ng, np.nan)
    ig = 0
    nsteps = 0
    nrej = 0
    nfev = 0
    status = 0
    # initial phase
    v0 = 1.0
    gvals(model, y, P, v0, gv)
    ph = 0
    pressed = False
    if gv[0] > 0.0 or (gv[0] == 0.0 and gv[1] > 0.0):
        ph = 1
        v0 = gv[1] if gv[1] > 1e-300 else 1e-300
        pressed = True
        if gv[0] > 0.0 and fev:
            gvals(model, y, P, v0, gv)
            pressed = gv[2] > 0.0
        onsets[0] = 0.0
        n_on = 1
    while ig < ng and tgrid[ig] <= t:
        s = 0.0
        for i in range(n):
            s += sens[i] * y[i]
        wgrid[ig] = s
        ig += 1
    rhs(model, t, y, P, ph, pressed, v0, f, wk)
    nfev += 1
    h_abs = select_initial_step(model, t, y, f, P, ph, pressed, v0, t_end, rtol, atol, tmp, tmp2, wk)
    nfev += 1
    seg_start = True
    nzero = 0
    while t < t_end:
        hmax = hmax_free if ph == 0 else hmax_contact
        if h_abs > hmax:
            h_abs = hmax
        min_step = 10 * abs(np.nextafter(t, np.inf) - t)
        if h_abs < min_step:
            h_abs = min_step
        # ---- one accepted step
        accepted = False
        rejected = False
        t_new = t
        h = 0.0
        while not accepted:
            if h_abs < min_step:
                status = -1
                return y, wgrid, onsets, n_on, seps, n_sep, n_toggle, nsteps, nrej, nfev, status
            t_new = t + h_abs
            if t_new > t_end:
                t_new = t_end
            h = t_new - t
            h_abs = abs(h)
            for i in range(n):
                K[0, i] = f[i]
            for s_ in range(1, NS):
                for i in range(n):
                    tmp[i] = 0.0
                for k in range(s_):
                    a = A[s_, k] * h
                    if a != 0.0:
                        for i in range(n):
                            tmp[i] += K[k, i] * a
                for i in range(n):
                    tmp[i] += y[i]
                rhs(model, t + C[s_] * h, tmp, P, ph, pressed, v0, K[s_], wk)
            for i in range(n):
                ynew[i] = 0.0
            for k in range(NS):
                bk = B[k] * h
                if bk != 0.0:
                    for i in range(n):
                        ynew[i] += K[k, i] * bk
            for i in range(n):
                ynew[i] += y[i]
            rhs(model, t + h, ynew, P, ph, pressed, v0, fnew, wk)
            nfev += NS
            for i in range(n):
                K[NS, i] = fnew[i]
            e5 = 0.0
            e3 = 0.0
            for i in range(n):
                r5 = 0.0
                r3 = 0.0
                for k in range(NS + 1):
                    r5 += K[k, i] * E5[k]
                    r3 += K[k, i] * E3[k]
                sc = atol[i] + max(abs(y[i]), abs(ynew[i])) * rtol
                e5 += (r5 / sc) ** 2
                e3 += (r3 / sc) ** 2
            if e5 == 0.0 and e3 == 0.0:
                err = 0.0
            else:
                err = h_abs * e5 / math.sqrt((e5 + 0.01 * e3) * n)
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
                nrej += 1
        nsteps += 1
        t_old = t
        for i in range(n):
            yold[i] = y[i]
        have_dense = False
        # ---- events in (t_old, t_new]
        gvals(model, yold, P, v0, gv_old)
        gvals(model, ynew, P, v0, gv_new)
        te = np.inf
        ev_kind = -1        # 0: p through 0 (onset/separation), 2: raw force through 0
        # candidate 1: p.  phase 0 wants p from <= 0 to > 0 (sgn +1); phase 1 wants p to < 0 (sgn -1)
        sg = 1.0 if ph == 0 else -1.0
        s_old = sg * gv_old[0]
        s_new = sg * gv_new[0]
        sd_old = sg * gv_old[1]
        sd_new = sg * gv_new[1]
        lo = t_old
        hi_ = t_new
        bracket = False
        need_max = False
        if s_new > 0.0 and s_old < 0.0:
            bracket = True
        elif s_new > 0.0:
            # s_old >= 0: only at a segment start (the root just left) or a tangency
            if sd_old < 0.0:
                need_max = True      # dips below, comes back within the step
            else:
                bracket = True       # leaves at once: root at t_old
                lo = t_old
                hi_ = t_old
        elif sd_old > 0.0 and sd_new < 0.0:
            need_max = True          # an interior maximum of s may cross 0
        if bracket or need_max:
            if not have_dense:
                _dense_coeffs(model, K, F, yold, ynew, fnew, t_old, h, P, ph, pressed, v0, tmp, n, A, C, D, wk)
                nfev += 3
                have_dense = True
            if need_max:
                # extremum of s: s' changes sign from + to - (interior max of s) or the
                # dip case (s' from - to +: minimum, then the crossing after it)
                if s_new > 0.0:
                    # find where s is negative after the start, then bracket the crossing
                    tm = _first_below(model, sg, t_old, t_new, h, yold, F, P, v0, tmp, gv)
                    if tm < 0.0:
                        lo = t_old
                        hi_ = t_old
                    else:
                        lo = tm
                        hi_ = t_new
                    bracket = True
                else:
                    fa = ev_dense(model, 1, sg, t_old, t_old, h, yold, F, P, v0, tmp, gv)
                    fb = ev_dense(model, 1, sg, t_new, t_old, h, yold, F, P, v0, tmp, gv)
                    if fa > 0.0 and fb < 0.0:
                        tm = brent_dense(model, 1, sg, t_old, t_new, fa, fb, t_old, h, yold, F, P, v0, tmp, gv)
                        sm = ev_dense(model, 0, sg, tm, t_old, h, yold, F, P, v0, tmp, gv)
                        if sm > 0.0:
                            lo = t_old
                            hi_ = tm
                            bracket = True
            if bracket:
                if hi_ == lo:
                    te = lo
                else:
                    fa = ev_dense(model, 0, sg, lo, t_old, h, yold, F, P, v0, tmp, gv)
                    fb = ev_dense(model, 0, sg, hi_, t_old, h, yold, F, P, v0, tmp, gv)
                    if fa > 0.0:
                        fa = -0.0
                    te = brent_dense(model, 0, sg, lo, hi_, fa, fb, t_old, h, yold, F, P, v0, tmp, gv)
                ev_kind = 0
        # candidate 2: the raw force's sign while penetrated (smooth function gvals[2])
        if ph == 1:
            fs = 1.0 if pressed else -1.0      # pressed: want it to go negative: watch -f
            f_old = -fs * gv_old[2]
            f_new = -fs * gv_new[2]
            if fev and f_new > 0.0:
                if f_old <= 0.0 or seg_start:
                    if not have_dense:
                        _dense_coeffs(model, K, F, yold, ynew, fnew, t_old, h, P, ph, pressed, v0, tmp, n, A, C, D, wk)
                        nfev += 3
                        have_dense = True
                    fa = ev_dense(model, 2, -fs, t_old, t_old, h, yold, F, P, v0, tmp, gv)
                    if fa > 0.0:
                        fa = -0.0
                    t2 = brent_dense(model, 2, -fs, t_old, t_new, fa, f_new, t_old, h, yold, F, P, v0, tmp, gv)
                    if t2 < te:
                        te = t2
                        ev_kind = 2
        # ---- grid output up to min(te, t_new)
        t_stop = t_new if ev_kind < 0 else te
        while ig < ng and tgrid[ig] <= t_stop:
            if tgrid[ig] == t_new and ev_kind < 0:
                for i in range(n):
                    tmp[i] = ynew[i]
            else:
                if not have_dense:
                    _dense_coeffs(model, K, F, yold, ynew, fnew, t_old, h, P, ph, pressed, v0, tmp, n, A, C, D, wk)
                    nfev += 3
                    have_dense = True
                dense_eval(tgrid[ig], t_old, h, yold, F, n, tmp)
            s = 0.0
            for i in range(n):
                s += sens[i] * tmp[i]
            wgrid[ig] = s
            ig += 1
        if ev_kind < 0:
            t = t_new
            for i in range(n):
                y[i] = ynew[i]
                f[i] = fnew[i]
            seg_start = False
            nzero = 0
            continue
        # ---- an event at te: state from the dense output, switch
        if te > t_old:
            dense_eval(te, t_old, h, yold, F, n, y)
            nzero = 0
        else:
            for i in range(n):
                y[i] = yold[i]
            nzero += 1
            if nzero > 100:
                status = -2
                return y, wgrid, onsets, n_on, seps, n_sep, n_toggle, nsteps, nrej, nfev, status
        t = te
        if ev_kind == 0:
            if ph == 0:
                gvals(model, y, P, v0, gv)
                v0 = gv[1] if gv[1] > 1e-300 else 1e-300
                ph = 1
                gvals(model, y, P, v0, gv)
                pressed = True      # every law pushes just after an onset (p' > 0)
                if n_on < max_events:
                    onsets[n_on] = t
                n_on += 1
            else:
                ph = 0
                pressed = False
                if n_sep < max_events:
                    seps[n_sep] = t
                n_sep += 1
        else:
            pressed = not pressed
            n_toggle += 1
        rhs(model, t, y, P, ph, pressed, v0, f, wk)
        nfev += 1
        seg_start = True
        # keep the step size (the error control adapts); the phase cap applies at the loop top
    return y, wgrid, onsets, n_on, seps, n_sep, n_toggle, nsteps, nrej, nfev, status


@nb.njit(cache=True)
def _first_below(model, sg, t_old, t_new, h, yold, F, P, v0, tmp, gv):
    """first of 32 samples of (t_old, t_new] where sg * p < 0, or -1."""
    for k in range(1, 33):
        tk = t_old + (t_new - t_old) * k / 32.0
        if ev_dense(model, 0, sg, tk, t_old, h, yold, F, P, v0, tmp, gv) < 0.0:
            return tk
    return -1.0


@nb.njit(cache=True)
def _dense_coeffs(model, K, F, yold, ynew, fnew, t_old, h, P, ph, pressed, v0, tmp, n, A, C, D, wk):
    for s_ in range(NS + 1, 16):
        for i in range(n):
            acc = 0.0
            for k in range(s_):
                acc += K[k, i] * A[s_, k]
            tmp[i] = yold[i] + acc * h
        rhs(model, t_old + C[s_] * h, tmp, P, ph, pressed, v0, K[s_], wk)
    for i in range(n):
        dy = ynew[i] - yold[i]
        F[0, i] = dy
        F[1, i] = h * K[0, i] - dy
        F[2, i] = 2 * dy - h * (fnew[i] + K[0, i])
        for r in range(4):
            acc = 0.0
            for k in range(16):
                acc += D[r, k] * K[k, i]
            F[3 + r, i] = h * acc


# ------------------------------------------------------------------ Python front end
class Peer:
    """peer = Peer(scene_dict); r = peer.run(t_end, rtol, cap=None|c, tgrid=None)."""

    def __init__(self, scene, overrides=None):
        self.scene = scene
        if 'structure' in scene:
            self.model = 0
            self.P, self.y0, self.sens, self.unit, self.info = cantilever_params(scene, overrides)
            self.scale = self.info['gap']
        else:
            self.model = 1
            self.P, self.y0, self.sens, self.unit, self.info = rotating_params(scene, overrides)
            self.scale = 1e-3
        # the raw-force sign is a separate event unless it is the penetration itself
        if self.model == 0:
            lt, c, Ch, damp = int(self.P[3]), self.P[5], self.P[7], int(self.P[8])
            self.fev = not ((lt == LAW_SPRING and c == 0.0) or (lt == LAW_HERTZ and damp == DAMP_LINEAR and Ch == 0.0))
        else:
            self.fev = not (int(self.P[12]) == DAMP_LINEAR and self.P[11] == 0.0)
        self.w_free = self.info['w_max_free']
        self.w_contact = self.w_free
        if self.model == 0 and self.info['law'] == 'spring_dashpot':
            self.w_contact = self.info['w_max_contact_linear']

    def set_contact_wmax(self, w):
        self.w_contact = w

    def run(self, t_end, rtol, atol_factor=1.0, cap=None, tgrid=None, max_events=100000):
        """cap: None (no cap) or c: h <= c / w_max in each phase."""
        atol = np.ascontiguousarray(self.unit * rtol * atol_factor)
        hf = np.inf if cap is None else cap / self.w_free
        hc = np.inf if cap is None else cap / self.w_contact
        tg = np.zeros(0) if tgrid is None else np.ascontiguousarray(tgrid, dtype=np.float64)
        (y, wg, on, non, sp, nsp, ntog, nst, nrej, nfev, status) = simulate(
            self.model, self.P, self.y0.copy(), float(t_end), float(rtol), atol, hf, hc, tg,
            self.sens, max_events, self.fev, A, B, C, E3, E5, D)
        return dict(y=y, w=wg, onsets=on[:min(non, max_events)].copy(),
                    seps=sp[:min(nsp, max_events)].copy(), toggles=ntog, nsteps=nst, nrej=nrej,
                    nfev=nfev, status=status, w_end=float(self.sens @ y))
