"""beamstop itself: natively (examples/measure.rs) and the FMU driven
through fmpy's FMU2Slave (`engine.Session`). Event times come from the simulation's
structured events (examples/measure.rs prints them as JSON), never from log
text: the FMU runs the same code, and its outputs are checked against the
native run's."""
from __future__ import annotations

import json
import os
import tempfile
import time

import numpy as np

from .. import ROOT, engine
from .models import Scene


def measure(scene: Scene, *, event_tolerance=None, step=0.0, repeats=20, dense_dt=None, modes=None,
            set_extra=None, t_end=None):
    cfg = {
        "scene": scene.scene_file,
        "set": {**scene.set_values, **(set_extra or {})},
        "t_end": scene.t_end if t_end is None else t_end,
        "step": step,
        "repeats": repeats,
        "dense_dt": scene.dense_dt if dense_dt is None else dense_dt,
    }
    if event_tolerance is not None:
        cfg["event_tolerance"] = event_tolerance
    if modes is not None:
        cfg["modes"] = modes
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(cfg, f)
        path = f.name
    try:
        p = engine.example("measure", [path], capture=True, check=False)
    finally:
        os.unlink(path)
    if p.returncode != 0:
        return {"error": (p.stderr or p.stdout).strip(), "config": cfg}
    out = json.loads(p.stdout)
    out["config"] = cfg
    return out


def native_final(scene: Scene, out) -> np.ndarray:
    q = np.array(out["final"]["q"], float)
    qd = np.array(out["final"]["qd"], float)
    if scene.phi is not None:  # chain: beamstop's modal coordinates -> x
        q, qd = scene.phi @ q, scene.phi @ qd
    return np.concatenate([q, qd])


# ---- the FMU through fmpy -------------------------------------------------------

class FmuRunner:
    def __init__(self, scene: Scene):
        self.scene = scene
        self.fmu = engine.Fmu(ROOT / scene.fmu)
        self.vr = self.fmu.vr
        pre = scene.fmu_prefix
        n = scene.n
        self.out_w = self.vr[f"{pre}w" if pre else "w_stop"]
        self.out_state = [self.vr[f"q[{j}]"] for j in range(1, n + 1)] + [self.vr[f"qd[{j}]"] for j in range(1, n + 1)]

    def _instance(self):
        return engine.Session(self.fmu, "report").start(self.scene.set_values).slave

    def run(self, h: float, repeats: int = 5):
        """Median wall time of the doStep loop (reading w at the stop after
        each step, as a master would); the event times from the native run
        of the same scene and step (examples/measure.rs, structured: the
        trajectory does not depend on who drives the code)."""
        t_end = self.scene.t_end
        nsteps = max(1, int(round(t_end / h)))
        grid = np.array([min((k + 1) * h, t_end) for k in range(nsteps)])
        grid[-1] = t_end
        walls = []
        ws = None
        for _ in range(repeats + 1):
            fmu = self._instance()
            out_w = [self.out_w]
            ws_local = np.empty(nsteps)
            t = 0.0
            t0 = time.perf_counter()
            for k in range(nsteps):
                tn = grid[k]
                fmu.doStep(currentCommunicationPoint=t, communicationStepSize=tn - t)
                ws_local[k] = fmu.getReal(out_w)[0]
                t = tn
            walls.append(time.perf_counter() - t0)
            final = np.array(fmu.getReal(self.out_state))
            fmu.terminate()
            fmu.freeInstance()
            ws = ws_local
        walls = sorted(walls[1:])  # the first is a warm-up
        native_run = measure(self.scene, step=h, repeats=1, dense_dt=0.0)
        if "error" in native_run:
            raise RuntimeError(native_run["error"])
        ev = {"impact": native_run["impacts"], "sticking starts": native_run["sticks"], "release": native_run["releases"]}
        n = self.scene.n
        if self.scene.phi is not None:
            final = np.concatenate([self.scene.phi @ final[:n], self.scene.phi @ final[n:]])
        return {
            "wall_time_s": walls[len(walls) // 2],
            "wall_times_s": walls,
            "impacts": ev["impact"],
            "sticks": ev["sticking starts"],
            "releases": ev["release"],
            "final": final,
            "grid": grid,
            "w": ws,
            "steps": nsteps,
        }
