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
from conftest import FULL, ROOT

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


# ---------------------------------------------------------------- the command line itself

def _beamstop(*args, **kw):
    import subprocess
    from beamstop_tools import engine
    return subprocess.run([str(engine.binary()), *map(str, args)], capture_output=True, text=True, **kw)


def _scene(tmp_path, **changes):
    scene = json.loads(json.dumps(OSCILLATOR))
    scene.update(changes)
    path = tmp_path / "oscillator.json"
    path.write_text(json.dumps(scene))
    return path


def _rows(path):
    import csv
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.parametrize("args", [["--help"], ["-h"], ["help"], ["help", "orbits"], ["orbits", "--help"],
                                  ["orbits", "x.json", "--param", "--help"], ["run", "--help"], ["describe", "-h"],
                                  ["package", "--help"], ["check", "--help"]])
def test_help_prints_the_usage_and_succeeds(args):
    done = _beamstop(*args)
    assert done.returncode == 0 and "usage" in done.stdout and done.stderr == "", (args, done.stdout, done.stderr)
    if "orbits" in args:
        assert "--param NAME=FROM:TO" in done.stdout


def test_output_into_a_reader_that_stops_early_ends_quietly():
    """`beamstop variants | head -1`: a reader gone before the output ends
    the command as it ends a Unix tool (SIGPIPE), not with a panic."""
    import os
    import signal
    import subprocess
    from beamstop_tools import engine
    read, write = os.pipe()
    os.close(read)  # the reader is gone before the first line
    try:
        done = subprocess.run([str(engine.binary()), "variants"], stdout=write, stderr=subprocess.PIPE, text=True)
    finally:
        os.close(write)
    assert done.returncode == -signal.SIGPIPE and done.stderr == "", (done.returncode, done.stderr)


def test_every_option_takes_its_value_after_an_equals_sign(tmp_path):
    # The linear orbit at A = 0.05 is x = (A / c) sin t: [q; q'] = [0, 0.5] at t0 = 0.
    scene = _scene(tmp_path)
    spaced = ["--param", "A.amplitude=0.05:0.08", "--from-state", "0,0.5", "--points", "10", "--transient", "5",
              "--max-period", "2", "--max-branches", "1", "--phase", "0", "--forcing", "A.omega", "--set", "stop.R=0.8",
              "--progress", "5"]
    joined = [f"{a}={b}" for a, b in zip(spaced[::2], spaced[1::2])]
    for words, out in ((spaced, "spaced"), (joined, "joined")):
        done = _beamstop("orbits", scene, *words, f"--out={tmp_path / out}")
        assert done.returncode == 0, done.stderr
    assert (tmp_path / "spaced" / "branch.csv").read_text() == (tmp_path / "joined" / "branch.csv").read_text()
    assert len(_rows(tmp_path / "joined" / "branch.csv")) > 5
    done = _beamstop("run", scene, "--stop=1", "--step=0.5", f"--out={tmp_path / 'run'}")
    assert done.returncode == 0 and (tmp_path / "run" / "ImpactOscillator.csv").exists(), done.stderr


@pytest.mark.parametrize("words, said", [
    (["--set", "stop.R=0.7", "--set", "stop.R=0.9"], "--set stop.R=0.9: the parameter 'stop.R' is already given by --set stop.R=0.7"),
    (["--set", "stop.R=0.7", "--tie", "stop.R=2*A.amplitude^1"], "--tie stop.R=2*A.amplitude^1: the parameter 'stop.R' is already given by --set stop.R=0.7"),
    (["--tie", "stop.R=2*A.amplitude", "--tie", "stop.R=3*A.amplitude"], "--tie stop.R=3*A.amplitude: the parameter 'stop.R' is already given by --tie"),
    (["--set", "A.amplitude=0.1"], "--set A.amplitude=0.1: 'A.amplitude' is the continued parameter"),
    (["--tie", "A.amplitude=2*A.amplitude"], "--tie A.amplitude=2*A.amplitude: 'A.amplitude' is the continued parameter"),
    (["--points", "10", "--points=20"], "--points is given twice (10 and 20)"),
    (["--bogus", "1"], "unknown option --bogus"),
])
def test_a_parameter_held_or_tied_twice_is_refused(tmp_path, words, said):
    scene = _scene(tmp_path)
    done = _beamstop("orbits", scene, "--param", "A.amplitude=0.05:0.2", "--out", tmp_path / "o", *words)
    assert done.returncode == 1 and said in done.stderr, done.stderr


def test_special_points_carry_the_state_as_branch_rows_do(tmp_path):
    scene = _scene(tmp_path)
    done = _beamstop("orbits", scene, "--param", "A.amplitude=0.05:0.2", "--points", "40", "--out", tmp_path / "o")
    assert done.returncode == 0, done.stderr
    branch, special = _rows(tmp_path / "o" / "branch.csv"), _rows(tmp_path / "o" / "special.csv")
    assert list(special[0])[-2:] == ["state", "note"]
    ends = [s for s in special if s["type"] == "EP"]
    assert ends and all(len(json.loads(s["state"])) == 2 for s in special)
    # The branch's end points are rows of the branch, state and all.
    rows = {(r["A.amplitude"], r["state"]) for r in branch}
    assert all((s["A.amplitude"], s["state"]) in rows for s in ends)
    # Progress on stderr: each branch's start and end.
    assert "orbits: branch 0 (period 1 T) starts at A.amplitude = 0.05" in done.stderr
    assert "orbits: branch 0 ends:" in done.stderr


def test_a_stopped_run_leaves_the_branches_it_finished(tmp_path):
    """The impact oscillator of issue 44 (c = 0.2, w = 0.8, d = 0.5): branch 0
    ends long before the period-doubled branches do; the run is stopped as
    soon as it says so, and its tables hold branch 0."""
    import signal
    import subprocess
    from beamstop_tools import engine
    scene = _scene(tmp_path, structure={"type": "chain", "masses": 1, "m": 1.0, "k": 1.0, "c": 0.2},
                   loads=[{"type": "point_harmonic", "name": "A", "mass": 1, "amplitude": 0.0985, "omega": 0.8, "waveform": "cos"}],
                   stops=[{"name": "stop", "mass": 1, "gap": 0.5, "side": "positive",
                           "law": {"type": "restitution", "R": 0.8, "eps": 1e-9}}])
    out = tmp_path / "o"
    p = subprocess.Popen([str(engine.binary()), "orbits", str(scene), "--param", "A.amplitude=0.0985:0.3939543120718441",
                          "--points", "2000", "--out", str(out)], stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    try:
        for line in p.stderr:
            if line.startswith("orbits: branch 0 ends"):
                p.send_signal(signal.SIGSTOP)
                break
        assert p.poll() is None, "the run ended before it could be stopped"
        rows = _rows(out / "branch.csv")
        assert rows and {r["branch"] for r in rows} == {"0"}
        assert int(line.split(": ")[2].split()[0]) == len(rows)
        assert {r["branch"] for r in _rows(out / "special.csv")} == {"0"}
    finally:
        p.kill()
        p.wait()


@pytest.mark.skipif(not FULL, reason="about a minute: scripts/test --full")
def test_the_hard_spring_stop_branch_goes_on_through_its_grazings(tmp_path):
    """SpringStopHard's frequency response (`scripts/sweep-figures
    hard-orbits`, its continuation alone): a compliant onset vanishing at a
    grazing does not end the branch, which reaches the range's low end
    through the tori at 108.82 and 105.10 and the period doubling at 94.388
    (report/sweeps/hard-orbits_special.csv)."""
    w1 = 104.99411180231543
    result = orbits.continue_orbits(ROOT / "scenes" / "spring_stop_hard.json", "shaker.omega", 0.8 * w1, 1.6 * w1,
                                    start=[1.6 * w1], ties=["shaker.amplitude=-2e-4*shaker.omega^2"], points=100,
                                    max_branches=4, out=tmp_path / "hard")
    lowest = min(r["shaker.omega"] for r in result.branch.to_pylist())
    assert lowest == pytest.approx(0.8 * w1, rel=1e-12)
    special = result.special.to_pylist()
    for kind, at in [("NS", 108.8220912), ("NS", 105.1031517), ("PD", 94.38834366)]:
        assert any(s["type"] == kind and abs(s["shaker.omega"] - at) < 1e-8 * at for s in special), (kind, at, special)


# ---------------------------------------------------------------- --cover on Dask

# The oscillator of issue 44 (c = 0.2, w = 0.8, d = 0.5): a period-1 branch,
# grazing at A = 0.19698 and doubling at A = 0.25528 onto a period-2 branch.
COVERED = dict(OSCILLATOR, structure={"type": "chain", "masses": 1, "m": 1.0, "k": 1.0, "c": 0.2},
               loads=[{"type": "point_harmonic", "name": "A", "mass": 1, "amplitude": 0.1, "omega": 0.8, "waveform": "cos"}],
               stops=[{"name": "stop", "mass": 1, "gap": 0.5, "side": "positive",
                       "law": {"type": "restitution", "R": 0.8, "eps": 1e-9}}])


@pytest.fixture
def covered(tmp_path):
    """The oscillator's scene over A = 0.21 .. 0.3 (continued from 0.3), and
    a "sweep" whose periodic points lie on no branch (their samples far
    off), so that every one of them is a start."""
    scene = tmp_path / "oscillator.json"
    scene.write_text(json.dumps(COVERED))
    sweep = pa.Table.from_pylist([{"A.amplitude": a, "period": 1, "impacts_per_period": 1.0, "poincare": [5.0],
                                   "error": None} for a in AMPLITUDES])
    return scene, sweep


AMPLITUDES = [0.22, 0.24, 0.26, 0.28]
COVER = dict(start=0.3, points=8, transient=10, max_branches=8, max_period=2)


def test_cover_on_dask_merges_as_one_process_does(covered, tmp_path):
    """cover's restarts shared out among runs on a Dask cluster give the
    tables of the same runs one after the other, whatever order they end
    in; each run goes over the whole range, from the start first, and the
    merge drops what a later run found again."""
    from distributed import Client

    scene, sweep = covered
    serial = orbits.cover(scene, "A.amplitude", 0.21, 0.3, sweep, out=tmp_path / "serial", pieces_count=2, **COVER)
    with Client(processes=False, n_workers=2, threads_per_worker=1, dashboard_address=None) as client:
        dask = orbits.cover(scene, "A.amplitude", 0.21, 0.3, sweep, out=tmp_path / "dask", pieces_count=2,
                            client=client, **COVER)
    assert dask.branch.equals(serial.branch) and dask.special.equals(serial.special)
    assert pq.read_table(tmp_path / "dask" / "branch.parquet").equals(serial.branch)
    assert sorted(p.name for p in (tmp_path / "dask" / "runs").iterdir()) == ["000", "001", "first"]
    assert orbits.pieces(AMPLITUDES, [0.3], 2) == [[0.3, 0.22, 0.24], [0.3, 0.26, 0.28]]
    # Both runs found the start's branches; the second's are dropped, its own kept.
    runs = [orbits.read_csv(tmp_path / "dask" / "runs" / k / "branch.csv") for k in ("000", "001")]
    first = orbits.read_csv(tmp_path / "dask" / "runs" / "first" / "branch.csv")
    assert all(min(r.column("A.amplitude").to_pylist()) < 0.22 for r in runs)  # the whole range, not a piece
    count = lambda t: len(set(t.column("branch").to_pylist()))  # noqa: E731
    assert count(dask.branch) > count(first) and count(dask.branch) < count(runs[0]) + count(runs[1])
    assert "2 run(s) on 2 Dask worker(s)" in dask.summary and "lying on one kept before dropped" in dask.summary


def test_cover_in_one_piece_is_the_one_run_of_before(covered, tmp_path, capfd):
    """--pieces 1: the run from the start and every missed point, the tables
    of cover before it ran on Dask; beamstop's progress lines on stderr."""
    scene, sweep = covered
    one = orbits.cover(scene, "A.amplitude", 0.21, 0.3, sweep, out=tmp_path / "one", pieces_count=1, progress=True,
                       **COVER)
    err = capfd.readouterr().err
    assert "cover first: orbits: branch 0 (period 1 T) starts at A.amplitude = 0.3" in err
    assert "cover 1/1: orbits: branch 0 (period 1 T) starts" in err and "cover: run 1/1 done" in err
    before = orbits.continue_orbits(scene, "A.amplitude", 0.21, 0.3, start=[0.3] + AMPLITUDES, points=8,
                                    transient=10, max_branches=8, max_period=2, out=tmp_path / "before")
    assert one.branch.equals(before.branch) and one.special.equals(before.special)
    assert "cover: the first run and 4 starts in 1 run(s) on this process" in one.summary
