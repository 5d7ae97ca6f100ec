"""TappingArm (scenes/tapping_arm.json): the swinging hub's first strike
through the FMI 3.0 FMU with early return (each event's exact time), against
an independent model of the same equations (tapping_arm_reference.py:
modes from the characteristic equation, integrals by quadrature, scipy's
DOP853). At the scene's tolerance (1e-10) the two agree on the onset and
separation times to 1e-12 s and on the tip's deflection after the strike to
1e-9 of its size. A swing beyond its ranges (A Omega past the speed limit
included) is refused naming the field, its value and the allowed range."""

import json

import numpy as np
import pytest
from fmpy import simulate_fmu

from conftest import ROOT
from tapping_arm_reference import Model
from test_rotating_fmu import Unit

SCENE = json.loads((ROOT / "scenes" / "tapping_arm.json").read_text())
FMU2 = ROOT / "target" / "fmu" / "TappingArm.fmu"
FMU3 = ROOT / "target" / "fmu3" / "TappingArm.fmu"


def test_first_strike_matches_an_independent_model():
    r = simulate_fmu(str(FMU3), early_return_allowed=True, use_event_mode=True,
                     output=["stop.contacts", "stop.contact", "tip.w", "theta", "theta_dot"])
    t = r["time"]
    onsets = t[1:][r["stop.contacts"][1:] > r["stop.contacts"][:-1]]
    ends = t[1:][r["stop.contact"][:-1] & ~r["stop.contact"][1:]]
    assert len(onsets) == 1 and len(ends) == 1, (onsets, ends)
    # The hub follows its profile: theta0 + A sin(Omega t), A Omega at t = 0.
    hub = SCENE["hub"]["prescribed"]
    theta = SCENE["initial"]["theta"] + hub["A"] * np.sin(hub["Omega"] * t)
    assert np.abs(r["theta"] - theta).max() < 1e-15
    assert abs(r["theta_dot"][0] - hub["A"] * hub["Omega"]) < 1e-15
    ref = Model(SCENE).run(t[-1])
    # The strike near the end of the swing (it ends at a quarter period).
    period = 2 * np.pi / hub["Omega"]
    assert 0.2 < ref["onset"] / period < 0.25 and 0.5 < ref["speed"] < 1.0, ref
    assert abs(onsets[0] - ref["onset"]) < 1e-12, (onsets[0], ref["onset"])
    assert abs(ends[0] - ref["separation"]) < 1e-12, (ends[0], ref["separation"])
    assert abs(r["tip.w"][-1] - ref["tip_w"]) < 1e-9 * abs(ref["tip_w"]), (r["tip.w"][-1], ref["tip_w"])


@pytest.mark.parametrize("name, value, words", [
    ("Omega", 400.0, ["hub.prescribed.Omega = 400.0", "A Omega = 120.0", "(0, 292.5"]),
    ("A", -1.0, ["'A' = -1.0", "[0, 10000]"]),
    ("Omega", 0.0, ["'Omega' = 0.0", "(0, 8775.7"])])
def test_a_swing_beyond_its_ranges_is_refused_naming_the_field(name, value, words):
    u = Unit(FMU2)
    u.slave.setupExperiment(startTime=0.0)
    u.slave.enterInitializationMode()
    u.log.clear()
    with pytest.raises(Exception):
        u.set(name, value)
    message = " ".join(u.log.errors())
    assert all(w in message for w in words), message
    u.slave.exitInitializationMode()  # the refused value changed nothing
    assert u.get(name) == float(u.vars[name].start)
    u.close()
