"""The sweep tool end to end on Dask, each result checked against an
independent computation: a plain fmpy loop written here that steps the FMU
from rest in steps of a sample (not one long step), counts impacts, reads
the Poincare samples and samples the sticking flag finely. Also: resuming
after losing finished work recomputes only what is missing; continuation
chains split over tasks (FMU state serialized between them) equal one
fmpy instance continued by hand; an external `dask scheduler` with `dask
worker` processes gives the same table as the local cluster."""
from __future__ import annotations

import math
import os
import socket
import subprocess
import sys
import time

import numpy as np
import pyarrow.parquet as pq
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from conftest import FMU_DIR, ROOT

PINNED = FMU_DIR / "PinnedBeamStop.fmu"
OMEGA = 0.7 * math.pi ** 2
GAPS = [0.1, 0.4, 0.7, 1.0, 1.3, 1.6]
DISCARD, RECORD, SPP = 40, 12, 16
BASE = ["--set", "F=72", "--set", "omega=0.7*pi**2", "--set", "eps=1e-3",
        "--discard", str(DISCARD), "--record", str(RECORD), "--samples-per-period", str(SPP), "--no-plots"]


def sweep(*args, check=True, tmpdir=None):
    env = None if tmpdir is None else {**os.environ, "TMPDIR": str(tmpdir)}
    run = subprocess.run([sys.executable, "-m", "beamstop_tools.sweep", *map(str, args)], cwd=ROOT,
                         capture_output=True, text=True, timeout=300, env=env)
    if check:
        assert run.returncode == 0, run.stderr
    return run


def rows_of(path):
    return {(r["direction"], r["point"]): r for r in pq.read_table(path).to_pylist()}


class Plain:
    """The FMU through fmpy, nothing of beamstop_tools.sweep."""

    def __init__(self):
        md = read_model_description(str(PINNED))
        self.guid = md.guid
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(PINNED)),
                           modelIdentifier=md.coSimulation.modelIdentifier, instanceName="plain")
        self.s.instantiate()
        self.used = False

    def start(self, **values):
        if self.used:
            self.s.reset()
        self.used = True
        self.s.setupExperiment(startTime=0.0)
        self.s.enterInitializationMode()
        self.s.setReal([self.vr[k] for k in values], list(values.values()))
        self.s.exitInitializationMode()

    def read(self):
        w, v = self.s.getReal([self.vr["w_stop"], self.vr["v_stop"]])
        return w, v, self.s.getInteger([self.vr["impacts"]])[0], self.s.getBoolean([self.vr["sticking"]])[0]

    def march(self, t0, periods, per_period, T):
        """Steps of T / per_period from t0; the samples (w, v, impacts, sticking) at each."""
        out, now = [self.read()], t0
        for k in range(1, periods * per_period + 1):
            t = t0 + k * T / per_period
            self.s.doStep(now, t - now)
            now = t
            out.append(self.read())
        return out, now


def smallest_period(x, v, tol):
    """The test's own period search: smallest p with x, v repeating."""
    x, v = np.asarray(x), np.asarray(v)
    for p in range(1, len(x) // 2):
        if np.allclose(x[p:], x[:-p], rtol=0, atol=tol[0]) and np.allclose(v[p:], v[:-p], rtol=0, atol=tol[1]):
            return p
    return None


@pytest.fixture(scope="module")
def gap_sweep(tmp_path_factory):
    out, tmp = tmp_path_factory.mktemp("gap"), tmp_path_factory.mktemp("gap_tmp")
    run = sweep(PINNED, "--param", f"d={GAPS[0]}:{GAPS[-1]}:{len(GAPS)}", *BASE, "--out", out, "--workers", 2,
                "--points-per-task", 2, tmpdir=tmp)
    return out, run, tmp


def test_the_workers_remove_their_extracted_fmus(gap_sweep):
    """Each worker extracts the FMU to a temporary folder: gone when the
    sweep ends (a study of many sweeps does not fill the disk)."""
    left = sorted(p.name for p in gap_sweep[2].iterdir())
    assert not [name for name in left if name.startswith("beamstop-sweep-")], left


def test_each_point_matches_a_plain_fmpy_loop(gap_sweep):
    out, _, _ = gap_sweep
    rows = rows_of(out / "points.parquet")
    assert len(rows) == len(GAPS)
    plain = Plain()
    T = 2 * math.pi / OMEGA
    fine = 64
    for i, d in enumerate(GAPS):
        r = rows[(None, i)]
        assert r["d"] == pytest.approx(d, abs=1e-12) and r["error"] is None
        plain.start(F=72.0, omega=OMEGA, eps=1e-3, d=d)
        # the transient in steps of a sample (the tool takes one step: results must not depend on it)
        _, now = plain.march(0.0, DISCARD, SPP, T)
        samples, _ = plain.march(now, RECORD, fine, T)
        w = np.array([s[0] for s in samples])
        v = np.array([s[1] for s in samples])
        strob_w, strob_v = w[::fine], v[::fine]
        assert np.max(np.abs(np.array(r["poincare"]) - strob_w)) < 1e-9 * max(1.0, np.max(np.abs(w)))
        assert np.max(np.abs(np.array(r["poincare_rate"]) - strob_v)) < 1e-9 * max(1.0, np.max(np.abs(v)))
        impacts = samples[-1][2] - samples[0][2]
        assert r["impacts"] == impacts and r["impacts_per_period"] == impacts / RECORD
        assert r["period"] == smallest_period(strob_w, strob_v, (1e-4 * np.ptp(w), 1e-4 * np.ptp(v)))
        # the peak: at least the largest of its own samples, never above the stop; where the 64-sample
        # maximum lies away from impacts, the Hermite-refined peak is within 1e-4 of the range from it
        # (an impact inside a sampling interval is seen through the samples around it only)
        assert np.max(w[::fine // SPP]) - 1e-12 <= r["peak"] <= max(np.max(w), d) + 1e-12
        k = int(np.argmax(w))
        counts = [s[2] for s in samples]
        if counts[max(k - 4, 0)] == counts[min(k + 4, len(counts) - 1)]:
            assert r["peak"] >= np.max(w) - 1e-4 * np.ptp(w)
            assert r["peak"] - np.max(w) < 1e-4 * np.ptp(w)
        # sticking: the tool's measure against the flag sampled 64 times per period
        stuck = np.array([s[3] for s in samples], bool)
        if stuck.any():
            assert r["sticking"]
        assert abs(r["stuck_fraction"] - stuck.mean()) < 3.0 / fine + 1e-12
    plain.s.terminate()
    # the gaps cover sticking and period-1 double impacts (VSM12 Figure 9)
    assert rows[(None, 0)]["sticking"] and not rows[(None, 5)]["sticking"]
    assert rows[(None, 4)]["period"] == 1 and rows[(None, 4)]["impacts_per_period"] == 2


def test_the_table_carries_guid_settings_and_versions(gap_sweep):
    out, run, _ = gap_sweep
    table = pq.read_table(out / "points.parquet")
    meta = __import__("json").loads(table.schema.metadata[b"beamstop.sweep"])
    assert meta["guid"] == read_model_description(str(PINNED)).guid
    assert meta["settings"]["param"] == [{"name": "d", "from": GAPS[0], "to": GAPS[-1], "points": len(GAPS)}]
    assert meta["settings"]["set"] == ["F=72", "omega=0.7*pi**2", "eps=1e-3"]
    for pkg in ("fmpy", "dask", "distributed", "pyarrow", "numpy", "python"):
        assert meta["versions"][pkg]
    for column in ("d", "F", "omega", "eps", "impacts_per_period", "sticking", "period", "peak", "poincare"):
        assert column in table.column_names
    assert str(table.schema.field("sticking").type) == "bool"
    assert f"{len(GAPS)} points computed" in run.stdout


def test_resume_recomputes_only_the_lost_points(gap_sweep, tmp_path):
    out, _, _ = gap_sweep
    first = rows_of(out / "points.parquet")
    parts = sorted((out / "parts").glob("*.parquet"))
    assert len(parts) == 3                       # 6 points, 2 per task
    kept = {p: p.stat().st_mtime_ns for p in parts[1:]}
    parts[0].unlink()
    (out / "points.parquet").unlink()
    run = sweep(PINNED, "--param", f"d={GAPS[0]}:{GAPS[-1]}:{len(GAPS)}", *BASE, "--out", out, "--workers", 1)
    assert "4 of 6 points done, 2 to compute" in run.stderr
    assert "2 points computed" in run.stdout
    assert {p: p.stat().st_mtime_ns for p in parts[1:]} == kept
    again = rows_of(out / "points.parquet")
    for key, r in first.items():
        for col in ("poincare", "impacts", "period", "peak", "sticking", "stuck_fraction"):
            assert again[key][col] == r[col], (key, col)
    # other settings in the same directory are refused, naming what differs
    run = sweep(PINNED, "--param", f"d={GAPS[0]}:{GAPS[-1]}:{len(GAPS) + 1}", *BASE, "--out", out, check=False)
    assert run.returncode == 2 and "holds a sweep with other settings (param:" in run.stderr


def test_continuation_chains_equal_one_instance_continued_by_hand(tmp_path):
    lo, hi, n = 0.6, 0.8, 4
    run = sweep(PINNED, "--param", f"omega={lo}*pi**2:{hi}*pi**2:{n}", "--set", "F=72", "--set", "d=0.9",
                "--set", "eps=1e-3", "--discard", 10, "--record", 5, "--samples-per-period", 4,
                "--continuation", "both", "--points-per-task", 1, "--workers", 2, "--no-plots", "--out", tmp_path)
    rows = rows_of(tmp_path / "points.parquet")
    assert len(rows) == 2 * n
    omegas = np.linspace(lo * math.pi ** 2, hi * math.pi ** 2, n)
    plain = Plain()
    for direction, order in (("up", range(n)), ("down", reversed(range(n)))):
        now = None
        for i in order:
            T = 2 * math.pi / omegas[i]
            if now is None:
                plain.start(F=72.0, d=0.9, eps=1e-3, omega=omegas[i])
                now = 0.0
            else:
                plain.s.setReal([plain.vr["omega"]], [omegas[i]])
            t0 = (math.ceil(now / T - 1e-9) + 10) * T
            plain.s.doStep(now, t0 - now)
            samples, now = plain.march(t0, 5, 4, T)
            r = rows[(direction, i)]
            assert r["omega"] == omegas[i] and r["error"] is None
            assert r["t_record"] == t0
            assert r["poincare"] == [s[0] for s in samples[::4]], (direction, i)
            assert r["impacts"] == samples[-1][2] - samples[0][2]
    # the chains differ from independent runs from rest (the state is carried): the last point of 'up'
    assert rows[("up", n - 1)]["t_record"] > 10 * 2 * math.pi / omegas[-1] * 3


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_an_external_scheduler_gives_the_local_table(gap_sweep, tmp_path):
    local = rows_of(gap_sweep[0] / "points.parquet")
    port = _free_port()
    dask = os.path.join(os.path.dirname(sys.executable), "dask")
    address = f"tcp://127.0.0.1:{port}"
    worker_tmp = tmp_path / "worker_tmp"
    worker_tmp.mkdir()
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        time.sleep(1.0)
        procs.append(subprocess.Popen([dask, "worker", address, "--nworkers", "2", "--nthreads", "1",
                                       "--no-dashboard", "--host", "127.0.0.1"], cwd=ROOT,
                                      env={**os.environ, "TMPDIR": str(worker_tmp)},
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        run = sweep(PINNED, "--param", f"d={GAPS[0]}:{GAPS[-1]}:{len(GAPS)}", *BASE, "--out", tmp_path,
                    "--scheduler", address)
        assert "worker(s)" in run.stdout
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            p.wait(timeout=30)
    assert not [p.name for p in worker_tmp.iterdir() if p.name.startswith("beamstop-sweep-")], \
        "a stopped worker left its extracted FMU"
    remote = rows_of(tmp_path / "points.parquet")
    assert remote.keys() == local.keys()
    for key, r in local.items():
        for col in ("poincare", "poincare_rate", "impacts", "period", "peak", "sticking", "stuck_fraction"):
            assert remote[key][col] == r[col], (key, col)
