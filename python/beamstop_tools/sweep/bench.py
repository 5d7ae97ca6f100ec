"""How fast the sweep runs: points per second and the overhead per point,
in-process (no Dask), on 1 and 2 local workers, and on an external
`dask scheduler` with `dask worker` processes started here on loopback (the
way a cluster is used). Prints figures; asserts nothing (speed belongs here,
not in timed tests).

    python -m beamstop_tools.sweep.bench [--points 500] [--discard 100] [--record 100]

The sweep: PinnedBeamStop, the gap d from 0 to 1.8 at omega = 0.7 omega_1,
F = 72, eps = 1e-3 (VSM12 Figure 9), `discard + record` forcing periods
per point. Overhead per point = (workers x wall time - compute time inside
the points) / points: what scheduling, transfers and writing the parts cost.
"""
from __future__ import annotations

import argparse
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from . import spec as spec_mod
from .engine import dask_client, run_sweep
from .fmu import read_fmu
from .runner import plan_for, run_points
from .. import ROOT



def load() -> str:
    return "load average %.2f %.2f %.2f" % os.getloadavg()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def measure(label, spec, client, out, started_client):
    meta = run_sweep(spec, out, client, progress=False, restart=True)
    n, wall, comp, w = meta["points_computed"], meta["wall_seconds"], meta["compute_seconds"], meta["workers"]
    total = time.perf_counter() - started_client
    print(f"{label:34s} {w} worker(s): {n} points in {wall:6.2f} s = {n / wall:6.1f} points/s; compute "
          f"{comp / n * 1e3:6.2f} ms/point; overhead {(w * wall - comp) / n * 1e3:6.2f} ms/point; "
          f"with cluster start {total:6.2f} s  [{load()}]", flush=True)
    return meta


def external(spec, out, workers: int):
    """`dask scheduler` and `dask worker` as separate processes on loopback."""
    port = free_port()
    bindir = Path(sys.executable).parent
    dask = str(bindir / "dask") if (bindir / "dask").exists() else "dask"
    address = f"tcp://127.0.0.1:{port}"
    commands = [[dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                [dask, "worker", address, "--nworkers", str(workers), "--nthreads", "1", "--no-dashboard",
                 "--host", "127.0.0.1"]]
    print("external cluster:\n  " + "\n  ".join(" ".join(Path(c[0]).name if i == 0 else a for i, a in enumerate(c))
                                                for c in commands)
          + f"\n  scripts/sweep ... --scheduler {address}", flush=True)
    started = time.perf_counter()
    procs = [subprocess.Popen(commands[0], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        time.sleep(1.0)
        procs.append(subprocess.Popen(commands[1], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                      cwd=str(ROOT)))
        from distributed import Client
        client = Client(address, timeout="30s")
        try:
            client.wait_for_workers(workers, timeout=60)
            return measure("external scheduler + workers", spec, client, out, started)
        finally:
            client.close()
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m beamstop_tools.sweep.bench", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fmu", default=str(ROOT / "target" / "fmu" / "PinnedBeamStop.fmu"))
    ap.add_argument("--points", type=int, default=500)
    ap.add_argument("--discard", type=float, default=100)
    ap.add_argument("--record", type=int, default=100)
    ap.add_argument("--samples-per-period", type=int, default=16)
    ap.add_argument("--skip-external", action="store_true")
    args = ap.parse_args(argv)
    info = read_fmu(args.fmu)
    spec = spec_mod.build(info, [f"d=0:1.8:{args.points}"], ["F=72", "omega=0.7*pi**2", "eps=1e-3"],
                          args.discard, args.record, args.samples_per_period)
    print(f"{info.model_name}: {args.points} gaps, {args.discard:g} + {args.record} forcing periods per point, "
          f"{args.samples_per_period} samples per recorded period; {os.cpu_count()} cores; {load()}", flush=True)
    work = Path(tempfile.mkdtemp(prefix="beamstop-sweep-bench-"))
    try:
        data = Path(info.path).read_bytes()
        plan = plan_for(spec)
        points = [(p.index, p.values, p.period) for p in spec.points]
        run_points(data, plan, points[:2])                      # load the FMU first
        t = time.perf_counter()
        rows = run_points(data, plan, points)["rows"]
        wall = time.perf_counter() - t
        comp = sum(r["seconds"] for r in rows)
        print(f"{'in-process, no Dask':34s} 1 process  : {len(rows)} points in {wall:6.2f} s = "
              f"{len(rows) / wall:6.1f} points/s; compute {comp / len(rows) * 1e3:6.2f} ms/point  [{load()}]", flush=True)
        for n in (1, 2):
            started = time.perf_counter()
            with dask_client(None, n) as client:
                measure("LocalCluster", spec, client, work / f"local{n}", started)
        if not args.skip_external:
            external(spec, work / "external", 2)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
