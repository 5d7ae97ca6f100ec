"""The sweep tool's pieces on known answers: the period test on synthetic
stroboscopic sequences with a known period, the Hermite peak and maxima on
signals with a known maximum, expressions, and every kind of bad input
refused with a message naming the field, the value and what is allowed."""
from __future__ import annotations

import math

import numpy as np
import pytest

from beamstop_tools.sweep import measures
from beamstop_tools.sweep.cli import main
from beamstop_tools.sweep.errors import SweepError
from beamstop_tools.sweep.expr import Expression
from beamstop_tools.sweep.fmu import Stop, read_fmu
from conftest import FMU_DIR

PINNED = str(FMU_DIR / "PinnedBeamStop.fmu")


@pytest.mark.parametrize("p", [1, 2, 3, 4, 8])
def test_period_of_a_synthetic_sequence_with_known_period(p):
    rng = np.random.default_rng(p)
    base = rng.normal(size=p)
    k = np.arange(60)
    x = base[k % p] + 1e-9 * rng.normal(size=60)          # noise far below the tolerance
    v = np.cos(2 * np.pi * (k % p) / p) + 1e-9 * rng.normal(size=60)
    got = measures.response_period(x, v, 1e-6, 16, (np.ptp(base) + 1.0, 2.0))
    assert got == p


def test_no_period_for_a_quasi_periodic_sequence_and_for_period_beyond_the_limit():
    k = np.arange(200)
    golden = (math.sqrt(5) - 1) / 2
    assert measures.response_period(np.cos(2 * np.pi * golden * k), np.sin(2 * np.pi * golden * k), 1e-4, 16) is None
    x = np.arange(17)[k % 17] * 1.0
    assert measures.response_period(x, None, 1e-6, 16) is None
    assert measures.response_period(x, None, 1e-6, 17) == 17


def test_period_one_is_judged_against_the_whole_recording_not_the_poincare_samples():
    # the Poincare samples of a period-1 orbit repeat to rounding: their own range is ~0
    x = -0.77458335 + 1e-13 * np.sin(np.arange(50))
    assert measures.response_period(x, x, 1e-4, 16, (2.0, 20.0)) == 1
    # against its own tiny range the same sequence would not count as periodic
    assert measures.response_period(x, x, 1e-4, 16) is None


def test_hermite_max_is_exact_for_a_cubic():
    # p(s) = -2 s^3 + s^2 + s on [0, h]: maximum where p' = -6 s^2 + 2 s + 1 = 0
    h = 0.3
    p = lambda s: -2 * s ** 3 + s ** 2 + s  # noqa: E731
    dp = lambda s: -6 * s ** 2 + 2 * s + 1  # noqa: E731
    s_star = (2 + math.sqrt(4 + 24)) / 12
    got = measures.hermite_max(p(0), p(h), dp(0), dp(h), h)
    expected = p(s_star) if s_star < h else max(p(0), p(h))
    assert abs(got - expected) < 1e-14
    h = 1.0
    assert abs(measures.hermite_max(p(0), p(h), dp(0), dp(h), h) - p(s_star)) < 1e-14


def test_maxima_of_a_sampled_sine_are_its_amplitude():
    t = np.linspace(0, 10, 161)                    # 16 samples per period
    y = 0.37 + 1.3 * np.sin(2 * np.pi * t + 0.3)
    v = 1.3 * 2 * np.pi * np.cos(2 * np.pi * t + 0.3)
    m = measures.maxima(t, y, v, np.ones(len(t) - 1, bool))
    assert len(m) == 10
    assert np.max(np.abs(m - 1.67)) < 1e-4 * 1.3           # the samples alone miss it by 2e-2
    assert np.max(y) < 1.67 - 1e-3
    assert abs(measures.peak(y, m) - 1.67) < 1e-4


def test_expressions():
    e = Expression("-2e-4*shaker.omega**2 + q0[1]/2", "--set x", {"shaker.omega", "q0[1]"})
    assert e.names == {"shaker.omega", "q0[1]"}
    assert e.value({"shaker.omega": 100.0, "q0[1]": 1.0}) == pytest.approx(-1.5)
    assert Expression("0.7*pi**2", "f", set()).value({}) == pytest.approx(0.7 * math.pi ** 2)
    for bad, msg in (("__import__('os')", "unknown name '__import__'"), ("1;2", "not an arithmetic expression"),
                     ("omega.real", "unknown name 'omega.real'"), ("[1][0]", "may hold only")):
        with pytest.raises(SweepError, match=msg):
            Expression(bad, "--set x", {"omega"})


@pytest.mark.parametrize("args, message", [
    (["--param", "dd=0:1:3"], "--param: 'dd' is not a parameter of PinnedBeamStop; its parameters are F, omega, zeta, R, eps, d,"),
    (["--param", "d=0:1.8"], "'0:1.8' is not FROM:TO:POINTS"),
    (["--param", "d=0:1.8:many"], "POINTS = 'many' is not a whole number"),
    (["--param", "d=0:1.8:0"], "POINTS = 0; allowed: 1 or more"),
    (["--param", "d0:1:3"], "expected NAME=FROM:TO:POINTS"),
    (["--param", "d=0:2000:3"], "d = 2000.0 is outside its declared range [-1000.0, 1000.0]"),
    (["--param", "R=0:1.5:4"], "R = 1.5 is outside its declared range [0.0, 1.0]"),
    (["--param", "d=0:1:3", "--set", "F=1e9"], "F = 1000000000.0 is outside its declared range"),
    (["--param", "d=0:1:3", "--set", "G=1"], "--set: 'G' is not a parameter of PinnedBeamStop"),
    (["--param", "d=0:1:3", "--set", "F=2*G"], "--set F: unknown name 'G'"),
    (["--param", "d=0:1:3", "--set", "d=1"], "'d' is also swept"),
    (["--param", "d=0:1:3", "--set", "omega=0"], "omega = 0.0 at point 0; the forcing frequency must be > 0"),
    (["--param", "d=0:1:3", "--record", "2"], "--record: 2 periods; allowed: 3 or more"),
    (["--param", "d=0:1:3", "--discard", "-1"], "--discard: -1.0 periods; allowed: a finite number >= 0"),
    (["--param", "d=0:1:3", "--continuation", "up"], "'d', which is fixed (set before initialisation only); "
                                                      "continuation needs a tunable one: F, omega, R, eps"),
    (["--param", "d=0:1:3", "--output", "impacts"], "--output: 'impacts' is not a Real output of PinnedBeamStop"),
    (["--param", "d=0:1:3", "--forcing", "zeta2"], "--forcing: 'zeta2' is not a parameter"),
    (["--param", "d=0:1:3", "--param", "F=1:2:2", "--param", "R=0:1:2"], "at most two parameters"),
])
def test_bad_input_is_refused_naming_field_value_and_range(args, message, capsys, tmp_path):
    argv = [PINNED, "--out", str(tmp_path / "out"), "--no-progress"] + args
    if "--record" not in args:
        argv += ["--record", "10"]
    if "--discard" not in args:
        argv += ["--discard", "1"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err, err
    assert not (tmp_path / "out").exists()


def test_an_fmu_without_a_load_needs_the_forcing_parameter_named(capsys, tmp_path):
    argv = [str(FMU_DIR / "RotatingBeamImpact.fmu"), "--param", "J_h=0.05:0.06:2", "--discard", "1",
            "--record", "5", "--out", str(tmp_path)]
    assert main(argv) == 2
    assert "RotatingBeamImpact has no harmonic load; name the parameter that holds the forcing frequency" \
        in capsys.readouterr().err


def test_a_missing_fmu_is_named(capsys, tmp_path):
    assert main([str(tmp_path / "nope.fmu"), "--param", "d=0:1:2", "--discard", "1", "--record", "5",
                 "--out", str(tmp_path)]) == 2
    assert "nope.fmu' does not exist" in capsys.readouterr().err


@pytest.mark.parametrize("fmu, forcing, stop", [
    # renamed variables (the scene's `names`): found like the default ones
    ("PinnedBeamStop", "omega", Stop("stop", True, "impacts", "sticking", "stuck_time", "sticks", "w_stop", "v_stop")),
    ("WaggBishopCantilever4", "base.omega",
     Stop("tip_stop", True, "tip_stop.impacts", "tip_stop.sticking", "tip_stop.stuck_time", "tip_stop.sticks",
          "tip_stop.w", "tip_stop.v")),
    ("SpringStopHard", "shaker.omega", Stop("stop", False, "stop.contacts", None, None, None, "stop.w", "stop.v")),
    ("RotatingBeamImpact", None, Stop("surface", False, "stop.contacts", None, None, None, None, None)),
])
def test_stops_and_forcing_are_read_from_the_model_description(fmu, forcing, stop):
    info = read_fmu(FMU_DIR / f"{fmu}.fmu")
    assert info.forcing == forcing
    assert info.stops == [stop]
    for name in (stop.counter, stop.sticking, stop.stuck_time, stop.sticks, stop.w, stop.v):
        assert name is None or name in info.value_references
    assert (info.default_output, info.default_rate) == ((stop.w, stop.v) if stop.w else ("theta", None))
