#!/usr/bin/env python3
"""Error against run time for the rotating hub beam's Hertz tip contact
(DWZ: Duan, Wang & Zhang, "Impact dynamics of a flexible beam with
rotation"; scene scenes/rotating_beam.json, 0 to 0.05 s: the first
collision cluster, about a dozen contacts, then free flight).

    python -m beamstop_tools.report.rotating_peers [--out report/rotating] [--reps 5]
        [--scipy-budget 300] [--work-dir DIR] [--summary-only] [--quick]

1. runs `cargo run --release --example rotating_peer` (examples/rotating_peer.rs):
   beamstop's RotatingSimulation at solver.tolerance 1e-4..1e-12 and the
   compiled DOP853 peer (its own event loop on the library's assembled
   matrices; uncapped and capped) at rtol 1e-4..1e-13, timed in the same
   binary, plus untimed reference candidates (beamstop 1e-13, DOP853 1e-14);
2. runs scipy's Radau and BDF (solve_ivp, phase by phase with terminal
   events, finite-difference Jacobians) on a right-hand side written here
   from the equations of the derivation (below), independently of the Rust
   code: its own mode shapes, modal integrals (the shortening integrals
   from their definition, not by parts), mass matrix solve and contact
   kinematics; it is also checked against the library's z'' at the random
   contact states the example dumps;
3. writes report/rotating/peers.csv, peers.png (error against run time,
   log-log, all methods) and peers.md.

Equations (first-order model, no gravity or modal damping in this scene):
clamped-free shapes W_i(x/L) of unit mean square, z = [theta, B];
`J(z) z'' = Q` with
`J = [[J_h + J_b + B^T (M - D) B, Gamma^T], [Gamma, M]]`,
`Q_theta = tau - 2 theta' B^T (M - D) B' + Q_c,theta`,
`Q_B = theta'^2 (M - D) B - K B + Q_c,B`,
`M = int mu phi phi^T`, `K = int EI phi'' phi''^T`, `Gamma = int mu (R + x) phi`,
`D = int mu (R + x) e(x)`, `e(x) = int_0^x phi' phi'^T` (DWZ eqs. 1, 13, 14),
`J_b = int mu (R + x)^2`. The tip `r = A(theta) [R + L - B^T e(L) B / 2, w.B]`;
gap `n . (r - p0)`, penetration `g = -gap`, `Q_c = F d gap / dz`;
Lankarani-Nikravesh `F = K g^1.5 (1 + 3 (1 - e^2) / 4 g' / v0)` (DWZ eqs. 2-4
with hysteretic damping), `v0` the approach speed at the onset.

Measures against the reference (the tightest run, `dop853cap` at rtol 1e-14,
checked against beamstop at 1e-13 and the tightest scipy Radau run): the
first contact's peak force (relative), the number of contacts (onsets; an
onset farther than 1e-5 s from every reference onset is extra, a reference
onset with none that near is missed), and at 0.05 s the tip position (over
L) and theta. `err` = the largest of the peak-force, tip and theta errors.
Timing: the fastest of several runs (the machine is shared: the least
disturbed run): native runs as the example times them (at least `--reps`,
short ones repeated until 0.3 s); scipy: `--reps` runs, a run longer than
2 s once. The
scipy peak force is read off its dense output after the timed run.

`--quick` (a smoke run, about 10 s, to target/report-quick/rotating): the
example's quick settings (two tolerances each), one timed run, scipy at rtol
1e-5 only; the reference is then the tightest capped peer run.
"""
from __future__ import annotations

import json
import math
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402
from scipy.optimize import brentq, minimize_scalar  # noqa: E402

from .. import engine  # noqa: E402
from .common import QUICK_NOTE, fnum, log, md_table  # noqa: E402
from .peers import (LONG_RUN, MATCH, SOLVERS, equal_error_table, fastest_within, match_onsets,  # noqa: E402
                    peer_arguments, scipy_ladder, work_precision_panel)
from .common import write_csv as common_write_csv  # noqa: E402

SCIPY_TOLS = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
BOUNDS = (1e-4, 1e-6, 1e-8, 1e-10)
REFERENCE = ("dop853cap", 1e-14)
WORK_UNIT = {
    "beamstop": "DOP853 steps (accepted + rejected)",
    "dop853": "step attempts",
    "dop853cap": "step attempts",
    "scipy-Radau": "f evaluations",
    "scipy-BDF": "f evaluations",
}


# ------------------------------------------------------------------ native side

def run_example(tmp: Path, reps: int, quick: bool) -> str:
    p = engine.example("rotating_peer", ["--json", tmp / "native.json", "--reps", reps] + (["--quick"] if quick else []),
                       tee=True, echo=True, check=False)
    if p.returncode != 0:
        raise SystemExit(f"rotating_peer failed ({p.returncode})")
    return p.stdout


# ----------------------------------------------- the independent Python equations

def gauss(a: float, b: float, panels: int, order: int = 20):
    """Composite Gauss-Legendre nodes and weights on [a, b]."""
    x, w = np.polynomial.legendre.leggauss(order)
    edges = np.linspace(a, b, panels + 1)
    lo, hi = edges[:-1, None], edges[1:, None]
    nodes = (0.5 * (hi - lo) * x + 0.5 * (hi + lo)).ravel()
    weights = (0.5 * (hi - lo) * w).ravel()
    return nodes, weights


class Shapes:
    """Clamped-free shapes W_j(xi) of unit mean square, in the overflow-free
    form: with E = exp(-b), s = sin b, c = cos b, den = 1 + (2 s - E) E,
    sigma = (1 + (2 c + E) E) / den, a = (s - c - E) / den,
    W = -cos(b xi) + sigma sin(b xi) + a exp(b (xi - 1)) + (1 + sigma) / 2 exp(-b xi);
    b the roots of cos b + sech b = 0."""

    def __init__(self, n: int):
        f = lambda b: math.cos(b) + 1.0 / math.cosh(b)  # noqa: E731
        # One root in each ((j - 1) pi, j pi).
        self.b = np.array([brentq(f, (j - 1) * math.pi + 0.1, j * math.pi - 0.1, xtol=1e-15, rtol=1e-15)
                           for j in range(1, n + 1)])
        b = self.b
        e = np.exp(-b)
        s, c = np.sin(b), np.cos(b)
        den = 1.0 + (2.0 * s - e) * e
        self.sigma = (1.0 + (2.0 * c + e) * e) / den
        self.a = (s - c - e) / den

    def __call__(self, xi, k: int = 0) -> np.ndarray:
        """d^k W / d xi^k at the points xi: shape (len(xi), n)."""
        xi = np.atleast_1d(np.asarray(xi, dtype=float))[:, None]
        b, sg, a = self.b, self.sigma, self.a
        bx = b * xi
        ex1, ex0 = np.exp(b * (xi - 1.0)), np.exp(-bx)
        if k == 0:
            return -np.cos(bx) + sg * np.sin(bx) + a * ex1 + 0.5 * (1 + sg) * ex0
        if k == 1:
            return b * (np.sin(bx) + sg * np.cos(bx) + a * ex1 - 0.5 * (1 + sg) * ex0)
        if k == 2:
            return b ** 2 * (np.cos(bx) - sg * np.sin(bx) + a * ex1 + 0.5 * (1 + sg) * ex0)
        raise ValueError(k)


class RotatingBeamPy:
    """The rotating beam with tip Hertz contact, from the derivation's
    equations (module doc), for the scene dict of the Rust spec."""

    def __init__(self, scene: dict):
        bm = scene["beam"]
        self.L = L = bm["length"]
        if "mass_per_length" in bm:
            mu, ei = bm["mass_per_length"], bm["bending_stiffness"]
        else:
            mu, ei = bm["rho"] * bm["A"], bm["E"] * bm["I"]
        self.mu, self.ei = mu, ei
        self.n = n = scene["n_modes"]
        if scene.get("order", "first") != "first":
            raise ValueError("first-order model only")
        if scene.get("gravity", 0.0) != 0.0 or scene.get("modal_damping", 0.0) != 0.0:
            raise ValueError("no gravity or modal damping terms here")
        self.jh = scene["hub_inertia"]
        self.R = R = scene.get("hub_radius", 0.0)
        sh = Shapes(n)
        self.shapes = sh
        xi, wt = gauss(0.0, 1.0, 40)
        w0, w1, w2 = sh(xi, 0), sh(xi, 1), sh(xi, 2)
        x = L * xi
        # e(x) = int_0^x phi' phi'^T (phi' = W' / L) by its own quadrature at every node.
        ee = np.empty((len(xi), n, n))
        for k, xk in enumerate(xi):
            s_, v_ = gauss(0.0, xk, 1, 40)
            d = sh(s_, 1)
            ee[k] = (d * v_[:, None]).T @ d / L
        self.M = mu * L * (w0 * wt[:, None]).T @ w0
        self.K = ei / L ** 3 * (w2 * wt[:, None]).T @ w2
        self.Gamma = mu * L * ((R + x) * wt) @ w0
        self.D = mu * L * np.einsum("k,kij->ij", (R + x) * wt, ee)
        self.CL = ((w1 * wt[:, None]).T @ w1) / L
        self.w = sh(np.array([1.0]), 0)[0]
        self.Jb = mu * L * float(((R + x) ** 2) @ wt)
        self.MmD = self.M - self.D
        self.unit_norm = float(np.max(np.abs(np.diag((w0 * wt[:, None]).T @ w0) - 1.0)))
        surf = scene["surface"]
        nrm = np.array(surf["normal"], dtype=float)
        self.normal = nrm / np.linalg.norm(nrm)
        self.p0 = np.array(surf["point"], dtype=float)
        law = surf["law"]
        if law.get("damping") != "lankarani_nikravesh":
            raise ValueError("Lankarani-Nikravesh damping only")
        self.Kc = law["K"]
        e = law["e"]
        self.alpha = 0.75 * (1.0 - e * e)
        ini = scene.get("initial", {})
        self.y0 = np.zeros(2 * (n + 1))
        self.y0[0] = ini.get("theta", 0.0)
        self.y0[n + 1] = ini.get("theta_dot", 0.0)
        if ini.get("B"):
            self.y0[1:n + 1] = ini["B"]
        if ini.get("B_dot"):
            self.y0[n + 2:] = ini["B_dot"]

    def tip(self, z):
        """Tip position and d r_tip / dz (2 x (n+1))."""
        n = self.n
        b = z[1:]
        cb = self.CL @ b
        X = self.R + self.L - 0.5 * b @ cb
        Y = self.w @ b
        c, s = math.cos(z[0]), math.sin(z[0])
        r = np.array([c * X - s * Y, s * X + c * Y])
        dr = np.empty((2, n + 1))
        dr[:, 0] = [-s * X - c * Y, c * X - s * Y]
        # d/dB of A [X, Y] with dX/dB = -C_L B, dY/dB = w.
        dr[0, 1:] = c * (-cb) - s * self.w
        dr[1, 1:] = s * (-cb) + c * self.w
        return r, dr

    def contact(self, y):
        """(penetration, its rate, d gap / dz)."""
        m = self.n + 1
        r, dr = self.tip(y[:m])
        grad = self.normal @ dr
        gap = float(self.normal @ (r - self.p0))
        return -gap, -float(grad @ y[m:]), grad

    def raw_force(self, g: float, gd: float, v0: float) -> float:
        if g <= 0.0:
            return 0.0
        h = self.alpha / v0 if v0 > 0.0 else 0.0
        return self.Kc * g ** 1.5 * (1.0 + h * gd)

    def zdd(self, y, force_on: bool, v0: float):
        n, m = self.n, self.n + 1
        z, zd = y[:m], y[m:]
        b, bd, thd = z[1:], zd[1:], zd[0]
        mdb = self.MmD @ b
        J = np.empty((m, m))
        J[0, 0] = self.jh + self.Jb + b @ mdb
        J[0, 1:] = self.Gamma
        J[1:, 0] = self.Gamma
        J[1:, 1:] = self.M
        Q = np.empty(m)
        Q[0] = -2.0 * thd * (mdb @ bd)
        Q[1:] = thd * thd * mdb - self.K @ b
        if force_on:
            g, gd, grad = self.contact(y)
            Q += self.raw_force(g, gd, v0) * grad
        return np.linalg.solve(J, Q)

    def rhs(self, force_on: bool, v0: float):
        m = self.n + 1

        def f(t, y):
            return np.concatenate((y[m:], self.zdd(y, force_on, v0)))
        return f

    def run(self, method: str, rtol: float, t_end: float, pos: float, vel: float) -> dict:
        """Phase by phase: open (gap event), pressed (force and penetration
        events), penetrated (negated force and penetration events)."""
        m = self.n + 1
        atol = np.r_[np.full(m, rtol * pos), np.full(m, rtol * vel)]
        t, y = 0.0, self.y0.copy()
        g0, gd0, _ = self.contact(y)
        onsets, speeds, first_contact_segments = [], [], []
        phase, v0 = "open", 0.0
        if g0 > 0 or (g0 == 0 and gd0 > 0):
            phase, v0 = "pressed", max(gd0, 0.0)
            onsets.append(0.0)
            speeds.append(gd0)
        nfev = njev = nlu = 0
        first_done = False
        while t < t_end:
            pressed = phase == "pressed"
            f = self.rhs(pressed, v0)

            def pen_event(tt, yy):
                return self.contact(yy)[0]

            if phase == "open":
                def gap_event(tt, yy):
                    return -self.contact(yy)[0]
                gap_event.terminal, gap_event.direction = True, -1
                events = [gap_event]
            else:
                sign = 1.0 if pressed else -1.0

                def force_event(tt, yy, v0=v0, sign=sign):
                    g, gd, _ = self.contact(yy)
                    return sign * self.raw_force(g, gd, v0)
                force_event.terminal, force_event.direction = True, -1
                pen_event.terminal, pen_event.direction = True, -1
                events = [force_event, pen_event]
            dense = pressed and not first_done
            sol = solve_ivp(f, (t, t_end), y, method=method, rtol=rtol, atol=atol, events=events,
                            dense_output=dense)
            nfev += sol.nfev
            njev += sol.njev
            nlu += sol.nlu
            if sol.status < 0:
                raise RuntimeError(f"{method} rtol {rtol:g} at t = {t}: {sol.message}")
            if sol.status == 1:
                te, i = min((e[0], i) for i, e in enumerate(sol.t_events) if len(e))
                y_new = sol.y_events[i][0]
            else:
                te, y_new = t_end, sol.y[:, -1]
            if dense:
                first_contact_segments.append((t, te, sol.sol, v0))
            t, y = te, y_new
            if sol.status == 1:
                g, gd, _ = self.contact(y)
                if phase == "open":
                    phase, v0 = "pressed", max(gd, 0.0)
                    onsets.append(t)
                    speeds.append(gd)
                elif phase == "pressed":
                    phase = "penetrated" if (i == 0 and g > 0) else "open"
                else:
                    phase = "pressed" if i == 0 else "open"
                if phase == "open" and onsets:
                    first_done = True
        r, _ = self.tip(y[:m])
        return {"onsets": onsets, "onset_speeds": speeds, "segments": first_contact_segments,
                "theta": float(y[0]), "theta_dot": float(y[m]), "tip_x": float(r[0]), "tip_y": float(r[1]),
                "v_l": float(self.w @ y[1:m]), "nfev": nfev, "njev": njev, "nlu": nlu}

    def first_peak(self, segments) -> float:
        """The first contact's largest force from the pressed phases' dense output."""
        best = 0.0
        for (a, b, sol, v0) in segments:
            def force(t, sol=sol, v0=v0):
                g, gd, _ = self.contact(sol(t))
                return self.raw_force(g, gd, v0)
            ts = np.linspace(a, b, 2001)
            fs = np.array([force(t) for t in ts])
            k = int(np.argmax(fs))
            lo, hi = ts[max(k - 1, 0)], ts[min(k + 1, len(ts) - 1)]
            res = minimize_scalar(lambda t: -force(t), bounds=(lo, hi), method="bounded",
                                  options={"xatol": 1e-16 + 1e-12 * (hi - lo)})
            best = max(best, fs[k], -res.fun)
        return best


# ------------------------------------------------------------------ scipy sweep

def scipy_sweep(beam: RotatingBeamPy, native: dict, reps: int, budget: float, quick: bool):
    t_end, pos, vel = native["t_end"], native["pos_scale"], native["vel_scale"]
    rows, skipped = [], []
    for method, rtol, first, el, ms in scipy_ladder(lambda m, rtol: beam.run(m, rtol, t_end, pos, vel),
                                                    (1e-5,) if quick else SCIPY_TOLS, reps, budget, skipped, stat=min,
                                                    methods=("Radau",) if quick else ("Radau", "BDF")):
        peak = beam.first_peak(first["segments"])
        row = dict(solver=f"scipy-{method}", tol=rtol, ms=ms, runs=len(el), onsets=first["onsets"],
                   onset_speeds=first["onset_speeds"], peaks=[peak], theta=first["theta"],
                   theta_dot=first["theta_dot"], tip_x=first["tip_x"], tip_y=first["tip_y"], v_l=first["v_l"],
                   steps=first["nfev"], contact_steps=None, lu=first["nlu"], njev=first["njev"])
        rows.append(row)
        log(f"scipy {method} {rtol:.0e}: {ms:9.1f} ms ({len(el)} run(s)), {len(first['onsets'])} contacts, "
            f"first peak {peak:.6f} N, nfev {first['nfev']}, nlu {first['nlu']}")
    return rows, skipped


# ------------------------------------------------------------------- measures

def measures(r: dict, ref: dict, length: float) -> dict:
    p = r["peaks"][0] if r["peaks"] else math.nan
    peak = abs(p - ref["peaks"][0]) / ref["peaks"][0]
    tip = math.hypot(r["tip_x"] - ref["tip_x"], r["tip_y"] - ref["tip_y"]) / length
    th = abs(r["theta"] - ref["theta"])
    missed, extra, dt = match_onsets(ref["onsets"], r["onsets"])
    err = max(peak, tip, th)
    return dict(peak_err=peak, tip_err=tip, theta_err=th, err=err if math.isfinite(err) else math.inf,
                contacts=len(r["onsets"]), missed=missed, extra=extra, onset_dt=dt, peak=p)


# ------------------------------------------------------------------- output

def plot(rows, path: Path, ref_label: str, t_end: float):
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2), sharex=True)
    panels = [("peak_err", "first contact: |peak force - ref| / ref"),
              ("end_err", f"at t = {t_end:g} s: max(|tip - ref| / L, |theta - ref|)")]
    for ax, (key, label) in zip(axes, panels):
        work_precision_panel(ax, rows, key, "err", "tol")
        ax.set_xlabel(f"run time [ms] (fastest of the runs; 0 to {t_end:g} s simulated)")
        ax.set_ylabel(label)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"Rotating beam, Hertz tip contact (DWZ scene, 6 modes): error vs run time (ref: {ref_label})\n"
                 "labels: tolerance; ringed: a contact missed or extra", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


#: peers.csv: column -> (the row's key, None for the solver's work unit; its format, None: as is)
CSV = {"solver": ("solver", None), "tol": ("tol", ".0e"), "ms": ("ms", ".4f"), "runs": ("runs", None),
       "contacts": ("contacts", None), "missed": ("missed", None), "extra": ("extra", None),
       "onset_dt_s": ("onset_dt", ".3e"), "first_peak_N": ("peak", ".9f"), "peak_rel_err": ("peak_err", ".3e"),
       "tip_err_over_L": ("tip_err", ".3e"), "theta_err_rad": ("theta_err", ".3e"), "err": ("err", ".3e"),
       "theta": ("theta", ".15e"), "theta_dot": ("theta_dot", ".15e"), "tip_x": ("tip_x", ".15e"),
       "tip_y": ("tip_y", ".15e"), "work": ("steps", None), "work_unit": (None, None),
       "contact_steps": ("contact_steps", None), "lu": ("lu", None)}


def write_csv(rows, path: Path):
    def fmt(spec):
        return lambda x: "" if x is None else (format(x, spec) if spec else x)

    table = [{c: WORK_UNIT[r["solver"]] if key is None else r.get(key) for c, (key, _) in CSV.items()} for r in rows]
    common_write_csv(path, list(CSV), table, [fmt(spec) for _, spec in CSV.values()])


def summary(out: Path, rows, ref, checks, eq, native, skipped, elapsed, reps, cf, load, quick):
    t_end = native["t_end"]
    spec = native["scene"]
    L = []
    L.append("# Rotating hub beam: error against run time (beamstop, DOP853, scipy)\n")
    L.append(f"Generated by `python -m beamstop_tools.report.rotating_peers` ({elapsed:.0f} s). Every number below is "
             f"measured in that run, on a shared 2-core machine (load average {load[0]:.1f} at the start, "
             f"{load[1]:.1f} at the end); times are the fastest of several runs, and still vary by tens of "
             "per cent between reports: read the ratios to that precision.\n")
    if quick:
        L.append(QUICK_NOTE)
    on = ref["onsets"]
    L.append(f"Scene `scenes/rotating_beam.json` (DWZ: Duan, Wang & Zhang): aluminium beam, "
             f"{spec['n_modes']} clamped-free modes (omega_N = {native['omega_n']:.4g} rad/s), first-order model, "
             f"J_h = {spec['hub_inertia']} kg m^2, tip on the plane at t = 0 with theta' = "
             f"{spec['initial']['theta_dot']} rad/s, Hertz K = {spec['surface']['law']['K']:.3g} N/m^1.5, "
             f"Lankarani-Nikravesh e = {spec['surface']['law']['e']}; 0 to {t_end:g} s: **{len(on)} contacts** "
             f"(onsets from 0 to {1e3 * max(on):.3f} ms; the reference's first contact peaks at "
             f"{ref['peaks'][0]:.6f} N), then free flight.\n")
    L.append("Solvers. **beamstop**: `RotatingSimulation` (DOP853, its default `solver.method`, over the whole "
             "motion; switches located on the dense output, the state at a switch or an output by a step of its "
             "own), `solver.tolerance` = tol, one `advance_to(0.05)`. "
             "**dop853 / dop853cap**: the same DOP853 (`numerics/src/solve/dop853.rs`) with the peer's own event loop "
             "(`examples/rotating_peer.rs`: 4 interior dense-output samples per step, gap minima between samples, "
             "Brent on the 7th-order dense output, restart at each switch) on the library's assembled matrices "
             "(its right-hand side evaluated by block elimination of J, no allocation); `dop853` lets the error "
             "control resolve the contact, `dop853cap` also caps the step at 3 / omega_max of the phase (in "
             "contact omega_max includes the linearised Hertz stiffness). rtol = tol, atol = tol x "
             f"{native['pos_scale']:g} (m, rad) on theta and B, tol x {native['vel_scale']:g} (m/s, rad/s) on "
             "the rates. **scipy-Radau / scipy-BDF**: `solve_ivp` phase by phase with terminal events, "
             "finite-difference Jacobians, on the independent Python equations (this module), same rtol and "
             "atol.\n")

    L.append("## The equations, checked independently\n")
    L.append(f"The Python right-hand side (own mode shapes, modal integrals with e(x) integrated from its "
             f"definition, J z'' = Q solved densely, contact from the tip's kinematics) against the library's "
             f"`RotatingBeam::accelerations` at {eq['states']} random states pressed 1e-5 m into the plane "
             f"(forces {eq['force_min']:.3g} to {eq['force_max']:.3g} N): **max |dz''| / |z''| = "
             f"{fnum(eq['max_rel'])}**. The mode shapes' mean squares differ from 1 by at most "
             f"{fnum(eq['unit_norm'])}. The compiled peer's right-hand side against the library's at the same "
             f"states: {fnum(native['rhs_check']['max_rel_diff'])}.\n")

    L.append("## Reference\n")
    L.append(f"The tightest run, **{REFERENCE[0]} at rtol {REFERENCE[1]:.0e}** (untimed). Its agreement with "
             "the other tight runs (independent integrators and event locators; scipy also with independent "
             "equations):\n")
    L.append(md_table(["run", "contacts (missed / extra)", "max onset dt [s]", "first peak rel.", "tip / L",
                       "theta [rad]"],
                      [[c["label"], f"{c['contacts']} ({c['missed']} / {c['extra']})", fnum(c["onset_dt"]),
                        fnum(c["peak_err"]), fnum(c["tip_err"]), fnum(c["theta_err"])] for c in checks]))
    L.append("")

    L.append("## Work-precision table\n")
    L.append(f"peak: |first-contact peak force - ref| / ref; tip: |tip position - ref| / L at {t_end:g} s; theta: "
             f"|theta - ref| at {t_end:g} s; err = the largest of the three; contacts: onsets (missed / extra: "
             f"an onset more than {MATCH:g} s from every reference onset); ms: the fastest of the timed runs "
             f"(native: at least {reps}, short ones repeated until 0.3 s; scipy: {reps}, one if over "
             f"{LONG_RUN:g} s). "
             "Work: beamstop DOP853 steps (accepted + rejected, of which accepted in contact), peer DOP853 step "
             "attempts (accepted in contact), scipy f evaluations / LU decompositions.\n")
    tab = []
    for s in SOLVERS:
        for r in sorted((r for r in rows if r["solver"] == s and r.get("ms") is not None), key=lambda r: -r["tol"]):
            work = str(r["steps"])
            if r.get("contact_steps") is not None:
                work += f" ({r['contact_steps']})"
            if r.get("lu") not in (None, ""):
                work += f" / {r['lu']} LU"
            tab.append([s, f"{r['tol']:.0e}", f"{r['ms']:.2f}", f"{r['contacts']} ({r['missed']} / {r['extra']})",
                        fnum(r["peak_err"]), fnum(r["tip_err"]), fnum(r["theta_err"]), fnum(r["err"]), work])
    L.append(md_table(["solver", "tol", "ms", "contacts (missed / extra)", "peak", "tip / L", "theta", "err", "work"],
                      tab))
    if skipped:
        L.append("\nNot run: " + "; ".join(skipped) + ".")
    L.append("")

    L.append("## Run time at equal error\n")
    L.append("The fastest run of each solver with err within the bound and every contact found (no extra); "
             "ratio = its time / beamstop's fastest run within the same bound (above 1: slower than beamstop).\n")
    bs, eq_rows = equal_error_table(rows, BOUNDS, "err", lambda r: f"{r['ms']:.2f} ms (tol {r['tol']:.0e})")
    hdr = ["solver"]
    for b in BOUNDS:
        hdr += [f"time to err <= {b:g}", "/ beamstop"]
    L.append(md_table(hdr, eq_rows))
    L.append("")
    L.append("## What the numbers say\n")
    L.append(findings(rows, bs, cf, native["omega_n"]))
    (out / "peers.md").write_text("\n".join(L) + "\n")


def contact_frequency(beam: RotatingBeamPy, ref: dict, omega_n: float) -> dict:
    """The contact's linearised frequency at the deepest penetration of the
    fastest reference onset, with the tip's effective mass along the normal
    at the initial state, `m = 1 / (g.J^-1.g)`, `g = d gap / dz`; and Weyl's
    bound on the highest frequency in contact, `sqrt(omega_N^2 + omega_c^2)`."""
    m = beam.n + 1
    y = beam.y0.copy()
    _, _, grad = beam.contact(y)
    J = np.zeros((m, m))
    J[0, 0] = beam.jh + beam.Jb
    J[0, 1:] = J[1:, 0] = beam.Gamma
    J[1:, 1:] = beam.M
    mass = 1.0 / float(grad @ np.linalg.solve(J, grad))
    v0 = max(ref["onset_speeds"])
    depth = (1.25 * mass * v0 * v0 / beam.Kc) ** 0.4
    omega_c = math.sqrt(1.5 * beam.Kc * math.sqrt(depth) / mass)
    return dict(mass=mass, v0=v0, depth=depth, omega_c=omega_c, omega_max=math.hypot(omega_n, omega_c))


def findings(rows, bs, cf, omega_n) -> str:
    parts = []
    for b in BOUNDS:
        peers = [fastest_within(rows, s, b, "err") for s in ("dop853", "dop853cap")]
        peers = [p for p in peers if p]
        if bs[b] and peers:
            p = min(peers, key=lambda r: r["ms"])
            ratio = p["ms"] / bs[b]["ms"]
            parts.append(f"at err <= {b:g} the compiled peer ({p['solver']}, rtol {p['tol']:.0e}) needs "
                         f"{p['ms']:.2f} ms, beamstop {bs[b]['ms']:.1f} ms (peer / beamstop = {ratio:.3g})")
    sc = []
    for s in ("scipy-Radau", "scipy-BDF"):
        for b in BOUNDS:
            r = fastest_within(rows, s, b, "err")
            if r and bs[b]:
                sc.append(f"{s} reaches {b:g} in {r['ms']:.0f} ms ({r['ms'] / bs[b]['ms']:.3g} x beamstop)")
            elif bs[b]:
                sc.append(f"{s} does not reach {b:g} in the tolerances run")
    bsr = [r for r in rows if r["solver"] == "beamstop" and r.get("ms")]
    capr = [r for r in rows if r["solver"] == "dop853cap" and r.get("ms")]
    per_bs = statistics.median(r["ms"] / r["steps"] for r in bsr) * 1e3 if bsr else math.nan
    per_cap = statistics.median(r["ms"] / r["steps"] for r in capr) * 1e3 if capr else math.nan
    share = statistics.median(r["contact_steps"] / r["steps"] for r in capr) if capr else math.nan
    p6 = [p for p in (fastest_within(rows, s, 1e-6, "err") for s in ("dop853", "dop853cap")) if p]
    steps_ratio = (bs[1e-6]["steps"] / min(p6, key=lambda r: r["ms"])["steps"]) if (p6 and bs.get(1e-6)) else None
    return ("Against the compiled peer: " + "; ".join(parts) + ". "
            + ("Against scipy: " + "; ".join(sc) + ". " if sc else "")
            + f"Per step: a beamstop step costs {per_bs:.1f} us (median over the tolerances, events and "
            f"outputs included), a DOP853 step attempt {per_cap:.1f} us (events and peak search included). "
            f"The contact is only mildly stiff: the tip's effective mass along the normal is {cf['mass']:.4f} kg, "
            f"and at the deepest penetration of the fastest onset ({cf['v0']:.3g} m/s, {cf['depth']:.3g} m) the "
            f"linearised Hertz contact has omega_c = {cf['omega_c']:.4g} rad/s, so the highest frequency in "
            f"contact is at most {cf['omega_max']:.4g} rad/s against omega_N = {omega_n:.4g} rad/s in free flight "
            f"({cf['omega_max'] / omega_n:.2g} times). The explicit order-8 method resolves that at a modest "
            f"step count (accepted steps in contact: {share:.0%} of its step attempts, median over the "
            "tolerances). beamstop integrates the whole motion with the same method (free flight included: the "
            "rotating beam is nonlinear everywhere) on the general equations (gravity, damping, torque, "
            "prescribed hub), with a dense-output state at each output and switch and the peak force's own step"
            + (f"; it takes {steps_ratio:.2g} times the peer's steps at err <= 1e-6." if steps_ratio else "."))


# ------------------------------------------------------------------- main

def main(argv=None):
    args = peer_arguments(argv, __doc__, "rotating", reps=5, budget=300.0)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    load_start = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(args.work_dir or td)
        tmp.mkdir(parents=True, exist_ok=True)
        if args.summary_only:
            saved = json.loads((tmp / "scipy.json").read_text())
            scipy_rows, skipped, elapsed = saved["rows"], saved["skipped"], saved["elapsed"]
            load = saved.get("load", [math.nan, math.nan])
        else:
            (tmp / "native.log").write_text(run_example(tmp, args.reps, args.quick))
        native = json.loads((tmp / "native.json").read_text())
        beam = RotatingBeamPy(native["scene"])
        # The Python equations against the library's z''.
        rels, forces = [], []
        for st in native["rhs_check"]["states"]:
            y = np.array(st["y"])
            g, gd, _ = beam.contact(y)
            forces.append(beam.raw_force(g, gd, st["v0"]))
            zdd = beam.zdd(y, True, st["v0"])
            ref = np.array(st["zdd"])
            rels.append(float(np.max(np.abs(zdd - ref)) / np.max(np.abs(ref))))
        eq = dict(states=len(rels), max_rel=max(rels), unit_norm=beam.unit_norm, force_min=min(forces),
                  force_max=max(forces))
        log(f"Python equations vs the library's z'': max rel. diff {max(rels):.2e} at {len(rels)} states "
            f"(forces {min(forces):.3g} to {max(forces):.3g} N)")
        if not args.summary_only:
            log(f"scipy sweep (budget {args.scipy_budget:.0f} s) ...")
            scipy_rows, skipped = scipy_sweep(beam, native, args.reps, args.scipy_budget, args.quick)
            for r in scipy_rows:
                r.pop("segments", None)
            elapsed = time.perf_counter() - t_start
            load = [load_start, os.getloadavg()[0]]
            (tmp / "scipy.json").write_text(json.dumps({"rows": scipy_rows, "skipped": skipped, "elapsed": elapsed,
                                                        "load": load}))
    rows = [dict(r, lu=None) for r in native["runs"]] + scipy_rows
    ref_row = next((r for r in rows if r["solver"] == REFERENCE[0] and r["tol"] == REFERENCE[1]), None)
    ref_label = f"{REFERENCE[0]} {REFERENCE[1]:.0e}"
    if ref_row is None:  # --quick: the tightest capped peer run
        ref_row = min((r for r in rows if r["solver"] == "dop853cap"), key=lambda r: r["tol"])
        ref_label = f"dop853cap {ref_row['tol']:.0e}"
    length = native["scene"]["beam"]["length"]
    for r in rows:
        r.update(measures(r, ref_row, length))
        r["end_err"] = max(r["tip_err"], r["theta_err"])
    # Agreement of the reference with the other tight runs.
    checks = []
    cands = [("beamstop", min((r["tol"] for r in rows if r["solver"] == "beamstop"), default=None)),
             ("dop853", min((r["tol"] for r in rows if r["solver"] == "dop853"), default=None)),
             ("scipy-Radau", min((r["tol"] for r in rows if r["solver"] == "scipy-Radau"), default=None)),
             ("scipy-BDF", min((r["tol"] for r in rows if r["solver"] == "scipy-BDF"), default=None))]
    for s, tol in cands:
        r = next((r for r in rows if r["solver"] == s and r["tol"] == tol), None)
        if r is not None and r is not ref_row:
            checks.append(dict(label=f"{s} {tol:.0e}", **{k: r[k] for k in ("contacts", "missed", "extra", "onset_dt",
                                                                              "peak_err", "tip_err", "theta_err")}))
    write_csv(rows, out / "peers.csv")
    plot(rows, out / "peers.png", ref_label, native["t_end"])
    cf = contact_frequency(beam, ref_row, native["omega_n"])
    summary(out, rows, ref_row, checks, eq, native, skipped, elapsed, args.reps, cf, load, args.quick)
    log(f"wrote {out / 'peers.csv'}, {out / 'peers.png'}, {out / 'peers.md'} ({time.perf_counter() - t_start:.0f} s)")


if __name__ == "__main__":
    main()
