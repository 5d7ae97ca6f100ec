"""Beam modes against an independent computation in 200-digit arithmetic
(mpmath): the textbook cosh/cos forms, which lose every digit in double
precision past mode 12, are exact here. Frequencies and shapes of the
cantilever and the clamped-clamped beam must agree to 1e-12 up to mode 100."""

import json
import subprocess

import mpmath as mp
import pytest

from conftest import native_beamstop

X = [0.0, 0.05, 0.13, 0.5, 0.77, 0.96, 1.0]
MODES = 100


def beamstop_modes(support):
    out = subprocess.run(native_beamstop() + ["modes", support, str(MODES), *map(repr, X)],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)["modes"]


def reference(support, j):
    """beta_j from cos(b) cosh(b) = -1 (clamped-free) or +1 (clamped-clamped),
    and W = cosh - cos - s (sinh - sin), unit mean square, W''(0) > 0."""
    mp.mp.dps = 200
    # The roots of cos(b) cosh(b) = -+1, divided by cosh(b) so that
    # findroot's residual check is meaningful at b ~ 300.
    if support == "clamped-free":
        f = lambda b: mp.cos(b) + 1 / mp.cosh(b)
        guess = (2 * j - 1) * mp.pi / 2
        s_of = lambda b: (mp.cosh(b) + mp.cos(b)) / (mp.sinh(b) + mp.sin(b))
    else:
        f = lambda b: mp.cos(b) - 1 / mp.cosh(b)
        guess = (2 * j + 1) * mp.pi / 2
        s_of = lambda b: (mp.cosh(b) - mp.cos(b)) / (mp.sinh(b) - mp.sin(b))
    beta = mp.findroot(f, guess)
    s = s_of(beta)
    shape = lambda x: mp.cosh(beta * x) - mp.cos(beta * x) - s * (mp.sinh(beta * x) - mp.sin(beta * x))
    curvature = lambda x: beta ** 2 * (mp.cosh(beta * x) + mp.cos(beta * x) - s * (mp.sinh(beta * x) + mp.sin(beta * x)))
    return beta, shape, curvature


@pytest.mark.parametrize("support", ["clamped-free", "clamped-clamped"])
def test_modes_match_200_digit_reference_to_mode_100(support):
    ours = beamstop_modes(support)
    worst = {"beta": 0.0, "shape": 0.0, "curvature": 0.0}
    for m in ours:
        j = m["j"]
        beta, shape, curvature = reference(support, j)
        worst["beta"] = max(worst["beta"], abs(m["beta"] - float(beta)) / float(beta))
        for x, w, c in zip(X, m["shape"], m["curvature"]):
            worst["shape"] = max(worst["shape"], abs(w - float(shape(x))))
            worst["curvature"] = max(worst["curvature"], abs(c - float(curvature(x))) / float(beta) ** 2)
    assert worst["beta"] < 1e-14, worst
    assert worst["shape"] < 1e-12, worst
    assert worst["curvature"] < 1e-12, worst


def test_reference_shapes_have_unit_mean_square():
    # The textbook forms above are normalised; check a few with quadrature.
    for support in ["clamped-free", "clamped-clamped"]:
        for j in [1, 2, 5]:
            beta, shape, _ = reference(support, j)
            mp.mp.dps = 30
            assert abs(mp.quad(lambda x: shape(x) ** 2, [0, 0.5, 1]) - 1) < 1e-20
