"""Tests of the independent spring-stop reference (python/beamstop_tools/report/springstop_reference.py).

These check the reference itself, not beamstop: no FMU, no native code.
The modal data the checks use (beta_j, omega_j, W_j(L), int W_j) are computed
here from the textbook cosh/cos form in extended precision (mpmath), not
taken from the module under test.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import mpmath as mp
import numpy as np
import pytest
from scipy.integrate import cumulative_simpson

from beamstop_tools.report import springstop_reference as ref

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"


def scene(name: str) -> dict:
    return json.loads((SCENES / f"spring_stop_{name}.json").read_text())


def modal_data(sc: dict, n: int):
    """omega_j, W_j(L), int_0^L W_j dx of the mass-normalised clamped-free
    modes, from W~ = cosh - cos - s (sinh - sin) in 60+ digits."""
    st = sc["structure"]
    L, E, I, rho, A = (float(st[k]) for k in ("length", "E", "I", "rho", "A"))
    mu = rho * A
    omega, w_tip, int_w = [], [], []
    for j in range(1, n + 1):
        guess = 1.875 if j == 1 else (j - 0.5) * math.pi
        mp.mp.dps = 40
        b = mp.findroot(lambda z: mp.cos(z) * mp.cosh(z) + 1, guess)
        mp.mp.dps = 40 + int(float(b))  # cosh - s sinh cancels ~ beta / ln 10 digits
        b = mp.findroot(lambda z: mp.cos(z) * mp.cosh(z) + 1, b)
        s = (mp.cosh(b) + mp.cos(b)) / (mp.sinh(b) + mp.sin(b))
        W = lambda x: mp.cosh(b * x) - mp.cos(b * x) - s * (mp.sinh(b * x) - mp.sin(b * x))
        m2 = mp.quad(lambda x: W(x) ** 2, mp.linspace(0, 1, j + 2))
        norm = 1 / mp.sqrt(m2 * mu * L)
        omega.append(float(b ** 2 * mp.sqrt(E * I / (mu * L ** 4))))
        w_tip.append(float(W(1) * norm))
        int_w.append(float(mp.quad(W, mp.linspace(0, 1, j + 2)) * norm * L))
    mp.mp.dps = 15
    return np.array(omega), np.array(w_tip), np.array(int_w), mu


def test_mode_shapes_and_modal_data():
    ref.self_test(verbose=False)
    sc = scene("hard")
    omega, w_tip, int_w, _ = modal_data(sc, 8)
    m = ref.build_model(sc, 8)
    np.testing.assert_allclose(m.omega, omega, rtol=1e-13)
    np.testing.assert_allclose(m.W_tip, w_tip, rtol=1e-12)
    np.testing.assert_allclose(m.intW, int_w, rtol=1e-12)
    # the stable form is still exact where the textbook form has lost its digits
    xi = np.linspace(0.0, 1.0, 11)
    for j in (15, 30):
        md = ref.cantilever_mode(j)
        mp.mp.dps = 40 + int(md.beta)
        b = mp.findroot(lambda z: mp.cos(z) + 1 / mp.cosh(z), md.beta)
        s = (mp.cosh(b) + mp.cos(b)) / (mp.sinh(b) + mp.sin(b))
        exact = [float(mp.cosh(b * x) - mp.cos(b * x) - s * (mp.sinh(b * x) - mp.sin(b * x))) for x in xi]
        mp.mp.dps = 15
        assert np.max(np.abs(md(xi) - exact)) < 1e-12


def _oscillator_from_rest(omega, zeta, b, Om, t):
    """q'' + 2 zeta omega q' + omega^2 q = b sin(Om t), q(0) = q'(0) = 0: (q, q')."""
    D = (omega ** 2 - Om ** 2) ** 2 + (2 * zeta * omega * Om) ** 2
    A = b * (omega ** 2 - Om ** 2) / D          # steady state A sin + B cos
    B = -b * 2 * zeta * omega * Om / D
    wd = omega * math.sqrt(1 - zeta ** 2)
    C1 = -B                                      # transient e^{-zeta omega t} (C1 cos + C2 sin)
    C2 = (zeta * omega * C1 - A * Om) / wd
    e = np.exp(-zeta * omega * t)
    c, s = np.cos(wd * t), np.sin(wd * t)
    q = A * np.sin(Om * t) + B * np.cos(Om * t) + e * (C1 * c + C2 * s)
    qd = (A * Om * np.cos(Om * t) - B * Om * np.sin(Om * t)
          + e * ((-zeta * omega * C1 + wd * C2) * c + (-zeta * omega * C2 - wd * C1) * s))
    return q, qd


@pytest.mark.parametrize("name", ["soft", "hard"])
def test_no_stop_matches_closed_form(name):
    """k = 0: every mode is a damped oscillator under a sine load, solved exactly."""
    sc = scene(name)
    n = 8
    omega, w_tip, int_w, mu = modal_data(sc, n)
    ld = sc["loads"][0]
    amp, Om = float(ld["amplitude"]), float(ld["omega"])
    zeta = float(sc["damping"]["zeta"])
    res = ref.simulate(sc, n, 0.5, 1e-4, k=0.0)
    t = res["t"]
    w = np.zeros_like(t)
    v = np.zeros_like(t)
    for j in range(n):
        q, qd = _oscillator_from_rest(omega[j], zeta, -mu * amp * int_w[j], Om, t)
        w += w_tip[j] * q
        v += w_tip[j] * qd
    assert len(res["onsets"]) == 0 and not res["contact"].any() and not res["force"].any()
    scale_w, scale_v = np.max(np.abs(w)), np.max(np.abs(v))
    assert scale_w > float(sc["stops"][0]["gap"])  # the stop would have been hit
    err_w = np.max(np.abs(res["tip_w"] - w)) / scale_w
    err_v = np.max(np.abs(res["tip_v"] - v)) / scale_v
    assert err_w < 1e-10, err_w
    assert err_v < 1e-10, err_v


def test_energy_balance_with_contacts():
    """kinetic + strain + stop-spring energy = base work - modal damping dissipation,
    at every output time, the powers integrated by Simpson's rule on a fine grid."""
    sc = scene("hard")
    n = 5
    omega, w_tip, int_w, mu = modal_data(sc, n)
    ld = sc["loads"][0]
    amp, Om = float(ld["amplitude"]), float(ld["omega"])
    zeta = float(sc["damping"]["zeta"])
    k = float(sc["stops"][0]["law"]["k"])
    gap = float(sc["stops"][0]["gap"])
    dt = 2e-6
    res = ref.simulate(sc, n, 0.2, dt)
    t, q, qd = res["t"], res["q"], res["qd"]
    assert len(res["onsets"]) >= 6
    p = q @ w_tip - gap
    # the contact flag and force follow the penetration (c = 0)
    assert np.all(res["contact"][p > 1e-12 * gap] == 1)
    assert np.all(res["contact"][p < -1e-12 * gap] == 0)
    np.testing.assert_allclose(res["force"], k * np.maximum(p, 0.0) * (res["contact"] == 1),
                               rtol=1e-12, atol=1e-12 * k * gap)

    energy = 0.5 * np.sum(qd ** 2, axis=1) + 0.5 * np.sum((omega * q) ** 2, axis=1) \
        + 0.5 * k * np.maximum(p, 0.0) ** 2
    p_base = -mu * amp * np.sin(Om * t) * (qd @ int_w)   # -mu a_b int w_t dx
    p_damp = np.sum(2 * zeta * omega * qd ** 2, axis=1)
    work = cumulative_simpson(p_base, x=t, initial=0.0)
    dissipated = cumulative_simpson(p_damp, x=t, initial=0.0)
    scale = np.max(np.abs(work))
    assert dissipated[-1] > 0.1 * work[-1]
    err = np.max(np.abs(energy - (work - dissipated))) / scale
    assert err < 1e-8, err


def test_soft_converged_under_tolerance_halving():
    sc = scene("soft")
    gap = float(sc["stops"][0]["gap"])
    a = ref.simulate(sc, 5, 0.5, 1e-4, rtol=1e-13)
    b = ref.simulate(sc, 5, 0.5, 1e-4, rtol=5e-14)
    assert len(a["onsets"]) == len(b["onsets"]) >= 5
    np.testing.assert_allclose(a["onsets"], b["onsets"], rtol=0, atol=1e-12)
    d = np.max(np.abs(a["tip_w"] - b["tip_w"]))
    assert d < 1e-10 * gap, d / gap


@pytest.mark.parametrize("n", [5, 20])
def test_dop853_against_closed_form_phases(n):
    """The integrator against the integrator-free method (each phase solved in
    closed form, switches by root finding on it) on the hard scene."""
    sc = scene("hard")
    gap = float(sc["stops"][0]["gap"])
    a = ref.simulate(sc, n, 0.5, 1e-4)
    b = ref.simulate(sc, n, 0.5, 1e-4, method="exact")
    assert len(a["onsets"]) == len(b["onsets"]) >= 15
    np.testing.assert_allclose(a["onsets"], b["onsets"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(a["separations"], b["separations"], rtol=0, atol=1e-12)
    d = np.max(np.abs(a["tip_w"] - b["tip_w"]))
    assert d < 1e-10 * gap, d / gap


def test_dashpot_contact():
    """c > 0: contact ends when k p + c p' reaches 0 (with p still > 0), so the
    force never goes negative; DOP853 and the closed-form phases agree."""
    sc = scene("hard")
    gap = float(sc["stops"][0]["gap"])
    a = ref.simulate(sc, 5, 0.3, 1e-4, c=5.0)
    b = ref.simulate(sc, 5, 0.3, 1e-4, c=5.0, method="exact")
    assert len(a["onsets"]) == len(b["onsets"]) >= 5
    np.testing.assert_allclose(a["onsets"], b["onsets"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(a["separations"], b["separations"], rtol=0, atol=1e-12)
    assert np.max(np.abs(a["tip_w"] - b["tip_w"])) < 1e-10 * gap
    assert a["force"].min() >= 0.0
    # k p + c p' = 0 at a separation: the tip leaves with p = -c p' / k > 0
    k = float(sc["stops"][0]["law"]["k"])
    p_sep = a["separation_tip_w"] - gap
    assert np.all(p_sep > 0.0) and np.all(a["separation_tip_v"] < 0.0)
    np.testing.assert_allclose(k * p_sep, -5.0 * a["separation_tip_v"], rtol=1e-9)
    # contact starts at p = 0 with p' > 0: the force jumps to c p'
    np.testing.assert_allclose(a["onset_tip_w"], gap, rtol=1e-13)
    assert np.all(a["onset_tip_v"] > 0.0)


def test_switches_at_the_gap_without_dashpot():
    sc = scene("hard")
    gap = float(sc["stops"][0]["gap"])
    a = ref.simulate(sc, 5, 0.3, 1e-4)
    np.testing.assert_allclose(a["onset_tip_w"], gap, rtol=1e-13)
    np.testing.assert_allclose(a["separation_tip_w"], gap, rtol=1e-13)
    assert np.all(a["onset_tip_v"] > 0.0) and np.all(a["separation_tip_v"] < 0.0)
