"""Runs a sweep on Dask: a LocalCluster of worker processes by default, or
the scheduler at --scheduler ADDRESS. The FMU's bytes are scattered to every
worker once; each task runs many points on the worker's one FMU instance;
continuation chains are chains of dependent tasks (each segment starts from
the FMU state the previous one serialized), all chains in parallel.
Finished tasks are written as they arrive, so an interrupted run resumes."""
from __future__ import annotations

import logging
import math
import os
import platform
import sys
import time
from contextlib import contextmanager
from importlib import metadata as importlib_metadata
from pathlib import Path

from .errors import SweepError
from .runner import plan_for, run_chain, run_points
from .store import Store


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None):
    """A distributed Client: to ADDRESS, or to a LocalCluster of `workers`
    single-threaded worker processes (default: one per core)."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as err:
            raise SweepError(f"--scheduler: cannot reach '{scheduler}' ({err}); start one with "
                             f"`dask scheduler` and workers with `dask worker ADDRESS`") from None
        try:
            client.wait_for_workers(1, timeout=60)
        except TimeoutError:
            client.close()
            raise SweepError(f"--scheduler: '{scheduler}' has no worker after 60 s; start some with "
                             f"`dask worker {scheduler}`") from None
        try:
            yield client
        finally:
            client.close()
        return
    n = workers or os.cpu_count() or 1
    if n < 1:
        raise SweepError(f"--workers: {n}; allowed: 1 or more")
    # the workers import beamstop_tools.sweep: the package is installed in the venv (scripts/venv.sh)
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                           silence_logs=logging.ERROR)
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def worker_count(client) -> int:
    return max(1, len(client.scheduler_info().get("workers", {})))


def versions() -> dict:
    out = {"python": platform.python_version()}
    for pkg in ("fmpy", "numpy", "dask", "distributed", "pyarrow"):
        try:
            out[pkg] = importlib_metadata.version(pkg)
        except importlib_metadata.PackageNotFoundError:
            out[pkg] = None
    return out


def _batches(items: list, size: int) -> list[list]:
    return [items[i:i + size] for i in range(0, len(items), size)]


def run_sweep(spec, out: Path, client, points_per_task: int | None = None, restart: bool = False,
              progress: bool = True, command: str | None = None) -> dict:
    """Runs what is not done yet and writes DIR/points.parquet. Returns
    figures of the run (points computed, wall time, compute time)."""
    from distributed import as_completed
    from tqdm import tqdm

    parameters = [a.name for a in spec.axes] + [n for n, _ in spec.sets if n not in {a.name for a in spec.axes}]
    store = Store(out, spec.settings(), parameters, restart)
    done = store.done()
    plan = plan_for(spec)
    workers = worker_count(client)
    started = time.perf_counter()
    fmu = client.scatter(Path(spec.info.path).read_bytes(), broadcast=True, hash=False)
    as_tuple = {p.index: (p.index, p.values, p.period) for p in spec.points}
    futures, sizes = [], {}
    if spec.continuation == "none":
        todo = [p.index for p in spec.points if (None, p.index) not in done]
        size = points_per_task or max(1, min(200, math.ceil(len(todo) / (4 * workers)))) if todo else 1
        for batch in _batches(todo, size):
            f = client.submit(run_points, fmu, plan, [as_tuple[i] for i in batch], pure=False)
            futures.append(f)
            sizes[f.key] = (f"points-{batch[0]:07d}", False)
    else:
        todo = []
        for direction, chain, order in spec.chains():
            k, state = store.chain_state(direction, order, done)
            rest = order[k:]
            todo += rest
            size = points_per_task or max(1, math.ceil(len(order) / 8))
            previous = state
            for seg_no, batch in enumerate(_batches(rest, size)):
                f = client.submit(run_chain, fmu, plan, direction, chain, [as_tuple[i] for i in batch], previous,
                                  pure=False)
                futures.append(f)
                sizes[f.key] = (f"{direction}-{chain:05d}-{k + seg_no * size:06d}", True)
                previous = f
    total = len(spec.points) * (2 if spec.continuation == "both" else 1)
    if len(todo) < total:
        print(f"resuming {out}: {total - len(todo)} of {total} points done, {len(todo)} to compute", file=sys.stderr)
    computed, compute_seconds, failures = 0, 0.0, 0
    with tqdm(total=len(todo), unit="pt", disable=not progress, file=sys.stderr, smoothing=0.1,
              desc=spec.info.model_name) as bar:
        for f in as_completed(futures):
            result = f.result()
            name, chained = sizes[f.key]
            store.write_part(name, result["rows"], result.get("state"), result.get("time"), chained)
            computed += len(result["rows"])
            compute_seconds += sum(r["seconds"] for r in result["rows"])
            failures += sum(1 for r in result["rows"] if r["error"])
            bar.update(len(result["rows"]))
    wall = time.perf_counter() - started
    workers = max(workers, worker_count(client))
    info = spec.info
    meta = {
        "settings": spec.settings(), "fmu_path": str(info.path), "guid": info.guid,
        "model_identifier": info.model_identifier, "generation_tool": info.generation_tool,
        "versions": versions(), "command": command,
        "sticking_from": "stuck_time counters (exact)" if plan.stuck_times else
                         ("sampled sticking flag" if plan.sticking else "no rigid stop"),
        "workers": workers, "points_computed": computed, "wall_seconds": wall,
        "compute_seconds": compute_seconds, "failed_points": failures,
    }
    store.finish(meta)
    return meta
