"""scripts/orbits (beamstop_tools.orbits) over the library's `beamstop orbits`:
the single impact oscillator x'' + c x' + k x = A cos(w t) with a rigid stop
at x = d (c = 0.1, k = 1, w = 1, d = 1, R = 0.8) continued in A, against
what is known in closed form: the linear orbit's amplitude A / sqrt((k -
w^2)^2 + (c w)^2) = 10 A and its multipliers, grazing at A = 0.1."""
from __future__ import annotations

import cmath
import json
import math

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from beamstop_tools import orbits

OSCILLATOR = {
    "name": "ImpactOscillator",
    "structure": {"type": "chain", "masses": 1, "m": 1.0, "k": 1.0, "c": 0.1},
    "loads": [{"type": "point_harmonic", "name": "A", "mass": 1, "amplitude": 0.05, "omega": 1.0, "waveform": "cos"}],
    "stops": [{"name": "stop", "mass": 1, "gap": 1.0, "side": "positive",
               "law": {"type": "restitution", "R": 0.8, "eps": 1e-6}}],
    "experiment": {"start": 0, "stop": 100, "step": 0.1},
}


@pytest.fixture(scope="module")
def continued(tmp_path_factory):
    d = tmp_path_factory.mktemp("orbits")
    scene = d / "oscillator.json"
    scene.write_text(json.dumps(OSCILLATOR))
    return orbits.continue_orbits(scene, "A.amplitude", 0.05, 0.2, points=40, out=d / "out"), d


def test_tables_and_grazing(continued):
    result, d = continued
    branch = pq.read_table(d / "out" / "branch.parquet")
    special = pq.read_table(d / "out" / "special.parquet")
    assert branch.schema.field("multipliers_re").type == pa.list_(pa.float64())
    assert branch.schema.field("stable").type == pa.bool_()
    rows = branch.to_pylist()
    assert rows[0]["A.amplitude"] == 0.05 and rows[-1]["A.amplitude"] == 0.2
    grazing = [s for s in special.to_pylist() if s["type"] == "GR"]
    assert len(grazing) == 1 and abs(grazing[0]["A.amplitude"] - 0.1) < 1e-8
    # Below grazing: the linear orbit, amplitude 10 A, multipliers
    # exp((-c/2 +- i sqrt(k - c^2/4)) 2 pi / w); above: one impact per period.
    exact = cmath.exp(complex(-0.05, math.sqrt(1 - 0.0025)) * 2 * math.pi)
    for r in rows:
        if r["A.amplitude"] < 0.0999:
            assert r["impacts_per_period"] == 0 and abs(r["peak"] - 10 * r["A.amplitude"]) < 1e-9
            for z in (complex(a, b) for a, b in zip(r["multipliers_re"], r["multipliers_im"])):
                assert min(abs(z - exact), abs(z - exact.conjugate())) < 1e-9
        elif r["A.amplitude"] > 0.1001:
            assert r["impacts_per_period"] == 1 and r["stable"]
            # The stop limits the displacement: the peak is the gap.
            assert abs(r["peak"] - 1.0) < 1e-12


def test_plot_and_sweep_points_on_the_branch(continued, tmp_path):
    result, _ = continued
    # A "sweep" made of the branch's own sections matches, a point moved off it does not.
    rows = result.branch.to_pylist()
    fake = [{"A.amplitude": r["A.amplitude"], "period": 1, "impacts_per_period": r["impacts_per_period"],
             "poincare": list(r["section"]) * 3, "error": None} for r in rows[::7]]
    fake.append({"A.amplitude": 0.15, "period": 1, "impacts_per_period": 1.0, "poincare": [5.0], "error": None})
    matched, total, missed = orbits.on_branches(result, pa.Table.from_pylist(fake))
    assert (matched, total, missed) == (len(fake) - 1, len(fake), [0.15])
    orbits.plot(result, tmp_path / "orbits.png", pa.Table.from_pylist(fake))
    assert (tmp_path / "orbits.png").stat().st_size > 10_000


def test_bad_input_names_the_field(tmp_path, capsys):
    scene = tmp_path / "oscillator.json"
    scene.write_text(json.dumps(OSCILLATOR))
    code = orbits.main([str(scene), "--param", "gap=0:1", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and "no parameter 'gap'" in err and "A.amplitude" in err
    code = orbits.main([str(scene), "--param", "A.amplitude=0.2:0.2", "--out", str(tmp_path / "o")])
    assert code == 2 and "two different finite ends" in capsys.readouterr().err
    code = orbits.main([str(scene), "--param", "A.amplitude=0.05:0.2", "--start", "0.5", "--out", str(tmp_path / "o")])
    assert code == 2 and "outside the range" in capsys.readouterr().err


def test_a_sweep_needs_the_scenes_fmu(tmp_path, capsys):
    scene = tmp_path / "oscillator.json"
    scene.write_text(json.dumps(OSCILLATOR))
    code = orbits.main([str(scene), "--param", "A.amplitude=0.05:0.2", "--sweep-points", "5", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and "ImpactOscillator.fmu is missing" in err and "beamstop package" in err
