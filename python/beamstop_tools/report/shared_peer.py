#!/usr/bin/env python3
"""The FMUs against the project's reference peers (benches/peers/: scipy's
DOP853 ported to numba, the whole event loop compiled, one call per
simulation), measured as benches/peers/README.md ("How the issues
measure") says, in one run:

    scripts/bench-peers [--quick] [--cases NAME,...] [--out DIR] [--reps N]
    python -m beamstop_tools.report.shared_peer [same options]   (numba: python/requirements-bench.txt)

Cases (`--cases`, default all; the scene's modes changed where the name says):

    soft      scenes/spring_stop_soft.json, 5 modes, 0.5 s      (SpringStopSoft)
    hard      scenes/spring_stop_hard.json, 20 modes, 0.5 s     (SpringStopHard)
    hertz20   scenes/hertz_stop.json, 20 modes, 0.2 s           (HertzStop)
    hertz32   the same, 32 modes
    rot6      scenes/rotating_beam.json, 6 modes, 0.05 s        (RotatingBeamImpact)
    rot32     the same, 32 modes
    rot40     the same, 40 modes
    rot64     the same, 64 modes (a case the scene check refuses is recorded as
              refused)
    spinup    scenes/spin_up.json, 4 modes, 30 s                (SpinUpBeam; no peer:
              error against the tolerance asked only)

FMUs: every case's FMU is packed at the start of the run by
`target/release/beamstop package` from its scene (modes set, renamed
`<Name>_bench<modes>` so that target/fmu's standard FMUs are not
overwritten; each is moved into the work folder), so that all of them carry
the same build of the library.

What is timed, interleaved in one process (the peer and the FMU alternate
within each round, every setting once per round, the order reversed every
other round; a setting faster than 5 ms is run up to 10 times in a row in
its slot; garbage collection off; fastest of `--reps` rounds):
- the FMU: one fmi2DoStep over the horizon through fmpy's FMU2Slave (the
  library loaded once; the instance made, set up and initialised outside
  the timing, a fresh one for every call), at its default settings and at
  each decade of its tolerance parameter's admitted range (the
  modelDescription's min and max): HertzStop `solver.integration_tolerance`,
  RotatingBeamImpact `solver.tolerance`; the spring-stop FMUs have no
  tolerance parameter (closed-form phases) and run at their defaults;
- the peer: `Peer(scene).run(t_end, rtol, cap=c)` without an output grid,
  the FMU's own scene, rtol 1e-3 ... 1e-13 (decades), cap 2, 3, 4, 5 and
  none (the step bounded by cap / omega_max per phase).

Error: the largest |tip.w - reference| on 2001 points over the horizon
(untimed runs: the FMU stepped to each point, whose trajectory does not
depend on the communication step; the peer with its dense output on the
grid), over the gap (the rotating beams: over max |tip.w| of the
reference). The reference is the peer at rtol 1e-14, cap 3, checked against
the peer at 1e-14 with the other caps and against the FMU's tightest
tolerance (all in checks.csv). SpinUpBeam: its own run at the tightest
tolerance, checked against the same scene with solver.method = radau.

Ratio at an error level: the fastest peer run whose error is at most the
level over the fastest FMU run whose error is at most the level.

Writes OUT/summary.md (the ratio tables, the error against the tolerance
asked), OUT/runs.csv (every timed setting: error, contacts, fastest time),
OUT/checks.csv (the references' checks), OUT/tolerance.csv (the FMUs'
error against the tolerance asked, SpinUpBeam included). OUT is
report/shared_peer, or target/report-quick/shared_peer with --quick (a
smoke run: three tolerances, two caps, one round).
"""
from __future__ import annotations

import argparse
import gc
import hashlib
import importlib
import importlib.metadata
import json
import math
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

from .. import ROOT, engine
from .common import QUICK_NOTE, log, md_table, out_dir, write_csv

NAME = "shared_peer"
LEVELS = (1e-4, 1e-6, 1e-8, 1e-10)
N_GRID = 2001
PEER_RTOLS = tuple(10.0 ** -k for k in range(3, 14))
PEER_CAPS = (2.0, 3.0, 4.0, 5.0, None)
REF_RTOL, REF_CAP = 1e-14, 3.0
SLOT = 0.005       # s: a setting faster than this is run several times in its slot
SLOT_MAX = 10      # at most this many calls in a row
COMMAND = "scripts/bench-peers"


class Case:
    def __init__(self, key, scene, t_end, modes=None, peer=True):
        self.key, self.scene_file, self.t_end, self.modes, self.peer = key, scene, t_end, modes, peer

    def scene(self) -> dict:
        s = json.loads((ROOT / "scenes" / self.scene_file).read_text())
        if self.modes is not None:
            if "structure" in s:
                s["structure"]["modes"] = self.modes
            else:
                s["n_modes"] = self.modes
        return s

    def n_modes(self, scene) -> int:
        return int(scene["structure"]["modes"] if "structure" in scene else scene["n_modes"])


CASES = {
    "soft": Case("soft", "spring_stop_soft.json", 0.5),
    "hard": Case("hard", "spring_stop_hard.json", 0.5),
    "hertz20": Case("hertz20", "hertz_stop.json", 0.2),
    "hertz32": Case("hertz32", "hertz_stop.json", 0.2, modes=32),
    "rot6": Case("rot6", "rotating_beam.json", 0.05),
    "rot32": Case("rot32", "rotating_beam.json", 0.05, modes=32),
    "rot40": Case("rot40", "rotating_beam.json", 0.05, modes=40),
    "rot64": Case("rot64", "rotating_beam.json", 0.05, modes=64),
    "spinup": Case("spinup", "spin_up.json", 30.0, peer=False),
}
QUICK_CASES = ("soft", "hertz20", "rot6", "spinup")
TOLERANCE_PARAMETERS = ("solver.integration_tolerance", "solver.tolerance")


# ------------------------------------------------------------------ the FMU side

def package(scene: dict, name: str, work: Path) -> Path:
    """`beamstop package` of `scene` renamed `name`, moved into `work`."""
    scene = dict(scene, name=name)
    path = work / f"{name}.json"
    path.write_text(json.dumps(scene, indent=1))
    p = engine.beamstop(["package", path])
    if p.returncode != 0:
        raise RuntimeError((p.stderr or p.stdout).strip())
    built = Path(p.stdout.strip().splitlines()[-1])
    dest = work / built.name
    shutil.move(str(built), dest)
    return dest


def check_scene(scene: dict, name: str, work: Path) -> str | None:
    """None if `beamstop check` accepts the scene, else its message."""
    path = work / f"{name}.json"
    path.write_text(json.dumps(dict(scene, name=name), indent=1))
    p = engine.beamstop(["check", path])
    return None if p.returncode == 0 else (p.stderr or p.stdout).strip()


class FmuRunner:
    """One FMU through fmpy's FMU2Slave, its library loaded once: an
    instance is made, set up and initialised (`start`), stepped, terminated
    and freed with fmi2FreeInstance (fmpy's freeInstance would unload the
    library)."""

    def __init__(self, path: Path):
        from fmpy.fmi2 import FMU2Slave

        self.fmu = engine.Fmu(path)
        md = self.fmu.md
        self.slave = FMU2Slave(guid=md.guid, unzipDirectory=self.fmu.dir,
                               modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
        self.tip = [self.fmu.vr["tip.w"]]
        self.contacts = [self.fmu.vr["stop.contacts"]] if "stop.contacts" in self.fmu.vr else None
        self.tol_name = next((n for n in TOLERANCE_PARAMETERS if n in self.fmu.vars), None)

    def tolerances(self) -> list[float]:
        """Each decade of the tolerance parameter's admitted range, loosest first."""
        if self.tol_name is None:
            return []
        v = self.fmu.vars[self.tol_name]
        hi, lo = float(v.max), float(v.min)
        ks = range(math.ceil(-math.log10(hi) - 1e-9), math.floor(-math.log10(lo) + 1e-9) + 1)
        return [10.0 ** -k for k in ks]

    def default_tolerance(self):
        return None if self.tol_name is None else float(self.fmu.vars[self.tol_name].start)

    def start(self, tol):
        s = self.slave
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        if tol is not None:
            s.setReal([self.fmu.vr[self.tol_name]], [float(tol)])
        s.exitInitializationMode()

    def free(self):
        try:
            self.slave.terminate()
        finally:
            self.slave.fmi2FreeInstance(self.slave.component)
            self.slave.component = None

    def timed(self, tol, t_end: float) -> float:
        self.start(tol)
        try:
            t0 = time.perf_counter()
            self.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=t_end)
            el = time.perf_counter() - t0
        finally:
            self.free()
        return el

    def grid(self, tol, t_end: float, n: int = N_GRID) -> tuple[np.ndarray, int | None]:
        """tip.w at n points over [0, t_end], stepping to each; the contacts counted."""
        self.start(tol)
        try:
            s, w = self.slave, np.empty(n)
            w[0] = s.getReal(self.tip)[0]
            ts = np.linspace(0.0, t_end, n)
            for k in range(1, n):
                s.doStep(currentCommunicationPoint=ts[k - 1], communicationStepSize=ts[k] - ts[k - 1])
                w[k] = s.getReal(self.tip)[0]
            c = s.getInteger(self.contacts)[0] if self.contacts else None
        finally:
            self.free()
        return w, c


# ------------------------------------------------------------------ the peer side

def load_peer():
    """benches/peers/compliant_dop853.py (needs numba: python/requirements-bench.txt)."""
    where = str(ROOT / "benches" / "peers")
    if where not in sys.path:
        sys.path.insert(0, where)
    try:  # a file of the checkout, not a distribution: imported by name from benches/peers
        return importlib.import_module("compliant_dop853")
    except ModuleNotFoundError as e:
        raise SystemExit(f"{e}: the peers need numba; run scripts/bench-peers, or "
                         "pip install -r python/requirements-bench.txt") from e


# ------------------------------------------------------------------ one case

def setting_label(r: dict) -> str:
    if r["solver"] == "fmu":
        return "default" if r["default"] else f"tol {r['tol']:.0e}"
    cap = "none" if r["cap"] is None else f"{r['cap']:g}"
    return f"rtol {r['tol']:.0e}, cap {cap}"


def interleave(a: list, b: list) -> list:
    """a and b merged evenly by their fractional positions (a first on ties)."""
    keyed = [((i + 0.5) / len(a), 0, x) for i, x in enumerate(a)] + [((i + 0.5) / len(b), 1, x) for i, x in enumerate(b)]
    return [x for _, _, x in sorted(keyed, key=lambda k: (k[0], k[1]))]


def pack_case(case: Case, work: Path) -> dict:
    """The case's FMU(s), packed now (every case before any run: one build
    of the library), or the scene check's refusal."""
    scene = case.scene()
    modes = case.n_modes(scene)
    name = f"{scene['name']}_bench{modes}"
    packed = dict(case=case, scene=scene, modes=modes, name=name, refused=check_scene(scene, name, work))
    if packed["refused"]:
        log(f"[{case.key}] refused by `beamstop check`: {packed['refused']}")
        return packed
    log(f"[{case.key}] packing {name}")
    packed["fmu"] = package(scene, name, work)
    if not case.peer:   # SpinUpBeam's check: the same scene with the Radau IIA integrator
        radau = dict(scene, solver=dict(scene.get("solver", {}), method="radau"))
        packed["radau"] = package(radau, f"{name}_radau", work)
    return packed


def run_case(packed: dict, peer_mod, reps: int, quick: bool, checks: list, tolerance_rows: list) -> dict:
    case, scene, modes, name = packed["case"], packed["scene"], packed["modes"], packed["name"]
    if packed["refused"]:
        return dict(case=case, scene=scene, modes=modes, refused=packed["refused"], rows=[])
    fmu = FmuRunner(packed["fmu"])
    T = case.t_end
    tg = np.linspace(0.0, T, N_GRID)
    rotating = "structure" not in scene

    # FMU settings: default, then the admitted decades
    tols = fmu.tolerances()
    if quick and tols:
        tols = [tols[0], tols[len(tols) // 2], tols[-1]]
    fmu_rows = [dict(case=case.key, solver="fmu", default=True, tol=fmu.default_tolerance(), cap=None)]
    fmu_rows += [dict(case=case.key, solver="fmu", default=False, tol=t, cap=None) for t in tols]
    log(f"[{case.key}] FMU untimed runs on {N_GRID} points ({len(fmu_rows)} settings)")
    for r in fmu_rows:
        t0 = time.perf_counter()
        try:
            r["w"], r["contacts"] = fmu.grid(None if r["default"] else r["tol"], T)
            r["status"] = "ok"
        except Exception as e:  # fmpy raises on a status above warning
            r["w"], r["contacts"], r["status"] = None, None, f"failed: {e}"
        log(f"  {setting_label(r)}: {r['status']} ({time.perf_counter() - t0:.2f} s)")

    if not case.peer:
        return spin_up(case, scene, modes, FmuRunner(packed["radau"]), fmu, fmu_rows, checks, tolerance_rows)

    # the peer: reference and untimed runs
    p = peer_mod.Peer(scene)
    log(f"[{case.key}] peer (omega_max free {p.w_free:.4g} rad/s, contact {p.w_contact:.4g}): reference "
        f"rtol {REF_RTOL:g} cap {REF_CAP:g}")
    t0 = time.perf_counter()
    ref = p.run(T, REF_RTOL, cap=REF_CAP, tgrid=tg)
    log(f"  first call (numba compile or cache load included): {time.perf_counter() - t0:.1f} s, status {ref['status']}")
    if ref["status"] != 0:
        raise RuntimeError(f"{case.key}: the peer's reference run failed (status {ref['status']})")
    w_ref = ref["w"]
    scale = float(np.max(np.abs(w_ref))) if rotating else float(scene["stops"][0]["gap"])
    scale_name = "max |tip.w|" if rotating else "gap"
    n_ref = len(ref["onsets"])

    def err(w):
        return math.inf if w is None or not np.all(np.isfinite(w)) else float(np.max(np.abs(w - w_ref)) / scale)

    for cap in PEER_CAPS:
        if cap == REF_CAP:
            continue
        r = p.run(T, REF_RTOL, cap=cap, tgrid=tg)
        checks.append(dict(case=case.key, reference=f"peer rtol {REF_RTOL:g} cap {REF_CAP:g}",
                           against=f"peer rtol {REF_RTOL:g} cap {'none' if cap is None else f'{cap:g}'}",
                           difference=err(r["w"]), scale=scale_name))
    tight = [r for r in fmu_rows if not r["default"] and r["status"] == "ok"]
    if tight:
        t = min(tight, key=lambda r: r["tol"])
        checks.append(dict(case=case.key, reference=f"peer rtol {REF_RTOL:g} cap {REF_CAP:g}",
                           against=f"FMU {fmu.tol_name} {t['tol']:.0e}", difference=err(t["w"]), scale=scale_name))
    else:
        d = fmu_rows[0]
        checks.append(dict(case=case.key, reference=f"peer rtol {REF_RTOL:g} cap {REF_CAP:g}",
                           against="FMU default (no tolerance parameter)", difference=err(d["w"]), scale=scale_name))

    rtols = PEER_RTOLS if not quick else (1e-4, 1e-8, 1e-12)
    caps = PEER_CAPS if not quick else (3.0, None)
    peer_rows = [dict(case=case.key, solver="peer", default=False, tol=rt, cap=c) for rt in rtols for c in caps]
    log(f"[{case.key}] peer untimed runs on {N_GRID} points ({len(peer_rows)} settings)")
    for r in peer_rows:
        out = p.run(T, r["tol"], cap=r["cap"], tgrid=tg)
        r["status"] = "ok" if out["status"] == 0 else f"status {out['status']}"
        r["contacts"], r["steps"], r["w"] = len(out["onsets"]), out["nsteps"], out["w"]
    for r in fmu_rows + peer_rows:
        r["err"] = err(r["w"]) if r["status"] == "ok" else math.inf
        r["ref_contacts"] = n_ref
    for r in fmu_rows:
        if r["tol"] is not None and r["status"] == "ok":
            tolerance_rows.append(dict(case=case.key, fmu=name, parameter=fmu.tol_name,
                                       tolerance=r["tol"], default=r["default"], error=r["err"], scale=scale_name,
                                       reference=f"peer rtol {REF_RTOL:g} cap {REF_CAP:g}"))

    # timed, interleaved
    timed_fmu = [r for r in fmu_rows if r["status"] == "ok"]
    timed_peer = [r for r in peer_rows if r["status"] == "ok"]
    for r in timed_fmu + timed_peer:
        r["times"] = []
    order = interleave(timed_peer, timed_fmu)
    log(f"[{case.key}] timing: {len(timed_peer)} peer and {len(timed_fmu)} FMU settings, {reps} rounds")
    t_case = time.perf_counter()
    gc.disable()
    try:
        for rnd in range(reps):
            for r in (order if rnd % 2 == 0 else order[::-1]):
                if r["status"] != "ok":
                    continue
                n = 1 if not r["times"] else max(1, min(SLOT_MAX, math.ceil(SLOT / min(r["times"]))))
                for _ in range(n):
                    if r["solver"] == "fmu":
                        try:
                            r["times"].append(fmu.timed(None if r["default"] else r["tol"], T))
                        except Exception as e:  # fmi2Discard: the step's work cap reached
                            r["status"] = f"one fmi2DoStep over the horizon failed: {e}"
                            log(f"  FMU {setting_label(r)}: {r['status']}")
                            break
                    else:
                        t0 = time.perf_counter()
                        p.run(T, r["tol"], cap=r["cap"])
                        r["times"].append(time.perf_counter() - t0)
            gc.collect()
    finally:
        gc.enable()
    log(f"  {time.perf_counter() - t_case:.0f} s")
    for r in timed_fmu + timed_peer:
        if r["status"] == "ok":
            r["ms"] = 1e3 * min(r["times"])
            r["calls"] = len(r["times"])
    rows = fmu_rows + peer_rows
    for r in rows:
        r["setting"] = setting_label(r)
    return dict(case=case, scene=scene, modes=modes, name=name, rows=rows, scale=scale_name, ref_contacts=n_ref,
                fmu_tol_name=fmu.tol_name, refused=None)


def spin_up(case, scene, modes, radau, fmu, fmu_rows, checks, tolerance_rows) -> dict:
    """SpinUpBeam: the error against its own tightest run, checked against Radau."""
    ok = [r for r in fmu_rows if r["status"] == "ok" and not r["default"]]
    ref = min(ok, key=lambda r: r["tol"])
    w_ref = ref["w"]
    scale = float(np.max(np.abs(w_ref)))
    rname = f"FMU {fmu.tol_name} {ref['tol']:.0e} (solver.method auto: exponential)"
    for t in (radau.tolerances()[-1], 10 * radau.tolerances()[-1]):
        try:
            w, _ = radau.grid(t, case.t_end)
            d = float(np.max(np.abs(w - w_ref)) / scale)
        except Exception as e:
            log(f"  radau {t:.0e}: {e}")
            d = math.inf
        checks.append(dict(case=case.key, reference=rname, against=f"FMU solver.method radau, {fmu.tol_name} {t:.0e}",
                           difference=d, scale="max |tip.w|"))
    for r in fmu_rows:
        if r["status"] != "ok":
            continue
        r["err"] = float(np.max(np.abs(r["w"] - w_ref)) / scale)
        if r is not ref:
            tolerance_rows.append(dict(case=case.key, fmu=f"{scene['name']}_bench{modes}", parameter=fmu.tol_name,
                                       tolerance=r["tol"], default=r["default"], error=r["err"],
                                       scale="max |tip.w|", reference=rname))
    return dict(case=case, scene=scene, modes=modes, rows=[], refused=None, spinup=True)


# ------------------------------------------------------------------ tables

def fastest(rows, solver, level):
    ok = [r for r in rows if r["solver"] == solver and r.get("ms") is not None and r["err"] <= level]
    return min(ok, key=lambda r: r["ms"], default=None)


def ratio_rows(results) -> tuple[list, list]:
    table, detail = [], []
    for res in results:
        if res.get("spinup"):
            continue
        label = f"{res['scene']['name']} ({res['modes']} modes)"
        if res.get("refused"):
            table.append([label] + ["refused"] * len(LEVELS))
            continue
        cells, dcells = [label], [label]
        for lv in LEVELS:
            pr, fr = fastest(res["rows"], "peer", lv), fastest(res["rows"], "fmu", lv)
            if fr is None:
                cells.append("FMU not reached")
            elif pr is None:
                cells.append("peer not reached")
            else:
                cells.append(f"{pr['ms'] / fr['ms']:.3g}")
            dcells.append(f"{fr['setting'] if fr else '-'} / {pr['setting'] if pr else '-'}")
        table.append(cells)
        detail.append(dcells)
    return table, detail


def tolerance_table(tolerance_rows) -> tuple[list, list]:
    cases = []
    for r in tolerance_rows:
        if r["case"] not in cases:
            cases.append(r["case"])
    tols = sorted({r["tolerance"] for r in tolerance_rows if not r["default"]}, reverse=True)
    header = ["tolerance asked"] + [CASE_TITLE.get(c, c) for c in cases]
    body = []
    for t in tols:
        row = [f"{t:.0e}"]
        for c in cases:
            m = [r for r in tolerance_rows if r["case"] == c and not r["default"] and r["tolerance"] == t]
            row.append(f"{m[0]['error']:.1e} ({m[0]['error'] / t:.2g})" if m else "-")
        body.append(row)
    return header, body


CASE_TITLE = {
    "soft": "SpringStopSoft, 5 modes", "hard": "SpringStopHard, 20 modes",
    "hertz20": "HertzStop, 20 modes", "hertz32": "HertzStop, 32 modes",
    "rot6": "RotatingBeamImpact, 6 modes", "rot32": "RotatingBeamImpact, 32 modes",
    "rot40": "RotatingBeamImpact, 40 modes", "rot64": "RotatingBeamImpact, 64 modes",
    "spinup": "SpinUpBeam, 4 modes",
}


def version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def checkout() -> str:
    """The commit, the library's build time (taken when the FMUs are packed)."""
    try:
        head = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=ROOT, capture_output=True,
                              text=True).stdout.strip()
    except OSError:
        head = "?"
    lib = ROOT / "target" / "release" / "libbeamstop_fmu.so"
    built = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(lib.stat().st_mtime)) if lib.exists() else "?"
    return f"checkout {head}, target/release/libbeamstop_fmu.so built {built}"


def build_info(work: Path, head: str) -> list[str]:
    lines = []
    hashes = set()
    for f in sorted(work.glob("*.fmu")):
        with zipfile.ZipFile(f) as z:
            so = [n for n in z.namelist() if n.startswith("binaries/")][0]
            hashes.add(hashlib.sha256(z.read(so)).hexdigest()[:16])
    lines.append(f"{head}; the FMUs' library sha256 {', '.join(sorted(hashes))} "
                 f"({'one build' if len(hashes) == 1 else 'SEVERAL BUILDS'}); "
                 f"numba {version('numba')}, numpy {np.__version__}, Python {platform.python_version()}")
    return lines


def write_report(out: Path, results, checks, tolerance_rows, reps, quick, elapsed, work, argv_cases, head):
    out.mkdir(parents=True, exist_ok=True)
    cols = ["case", "solver", "setting", "tol", "cap", "default", "status", "err", "contacts", "ref_contacts",
            "steps", "ms", "calls"]
    runs = [dict((k, r.get(k)) for k in cols) for res in results for r in res["rows"]]
    for r in runs:
        r["cap"] = "none" if r["solver"] == "peer" and r["cap"] is None else r["cap"]
    write_csv(out / "runs.csv", cols, runs)
    write_csv(out / "checks.csv", ["case", "reference", "against", "difference", "scale"], checks)
    write_csv(out / "tolerance.csv", ["case", "fmu", "parameter", "tolerance", "default", "error", "scale", "reference"],
              tolerance_rows)

    table, detail = ratio_rows(results)
    L = ["# The FMUs against the reference peers (benches/peers/)\n"]
    L.append(f"Generated by `{COMMAND}{' ' + ' '.join(argv_cases) if argv_cases else ''}` "
             f"(`python -m beamstop_tools.report.shared_peer`, {elapsed:.0f} s); the measurement is described "
             "at the top of python/beamstop_tools/report/shared_peer.py. Every number below is measured in that run.\n")
    if quick:
        L.append(QUICK_NOTE)
    L.append("Peer time over FMU time at equal error: the fastest peer run (`benches/peers/compliant_dop853.py`, "
             "rtol 1e-3 ... 1e-13, cap 2, 3, 4, 5 or none) whose error is at most the level, over the fastest FMU "
             "run (one fmi2DoStep over the horizon, default settings or a decade of its tolerance parameter) whose "
             f"error is at most the level; peer and FMU interleaved in one process, the fastest of {reps} rounds. "
             "Error: the largest |tip.w - reference| on 2001 points over the horizon, over the gap (the rotating "
             "beam: over max |tip.w|); reference: the peer at rtol 1e-14, cap 3 (checks below). Horizons: spring "
             "stops 0.5 s, HertzStop 0.2 s, RotatingBeamImpact 0.05 s.\n")
    L.append(md_table(["case", *(f"error <= {lv:.0e}" for lv in LEVELS)], table))
    L.append("")
    refused = [res for res in results if res.get("refused")]
    for res in refused:
        L.append(f"{res['scene']['name']} at {res['modes']} modes: `beamstop check` refuses the scene "
                 f"({re.sub(r'^.*?[.]json: ', '', res['refused'].splitlines()[-1])}).")
    failed = [r for res in results for r in res["rows"] if r["status"] != "ok"]
    for r in failed:
        L.append(f"{CASE_TITLE.get(r['case'], r['case'])}, {r['solver']} {r['setting']}: "
                 f"{r['status'].rstrip('.')}; not in the tables.")
    if refused or failed:
        L.append("")
    L.append("The runs chosen (FMU / peer):\n")
    L.append(md_table(["case", *(f"<= {lv:.0e}" for lv in LEVELS)], detail))
    L.append("")
    L.append("## Error against the tolerance asked\n")
    L.append("The FMUs' error (as above; SpinUpBeam, 30 s: against its own run at 1e-13, over max |tip.w|) at each "
             "decade of the tolerance parameter's admitted range (HertzStop `solver.integration_tolerance`, "
             "RotatingBeamImpact and SpinUpBeam `solver.tolerance`); in brackets the error over the tolerance.\n")
    header, body = tolerance_table(tolerance_rows)
    L.append(md_table(header, body))
    L.append("")
    L.append("## The references' checks\n")
    L.append(md_table(["case", "reference", "against", "largest difference"],
                      [[c["case"], c["reference"], c["against"], f"{c['difference']:.1e} of the {c['scale']}"]
                       for c in checks]))
    L.append("")
    mism = [r for res in results for r in res["rows"]
            if r.get("ms") is not None and r.get("contacts") is not None and r["contacts"] != r.get("ref_contacts")
            and r["err"] <= LEVELS[0]]
    if mism:
        L.append(f"Runs within 1e-4 whose contact count differs from the reference's: "
                 + "; ".join(f"{r['case']} {r['solver']} {r['setting']} ({r['contacts']} against {r['ref_contacts']})"
                             for r in mism) + ".\n")
    L.append("Build: " + "; ".join(build_info(work, head)) + ".\n")
    L.append("Files: runs.csv (every setting: error, contacts, fastest time in ms, timed calls), checks.csv, "
             "tolerance.csv.\n")
    (out / "summary.md").write_text("\n".join(L))
    log(f"wrote {out / 'summary.md'}")


# ------------------------------------------------------------------ main

def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help=f"smoke run: cases {','.join(QUICK_CASES)}, three tolerances, two caps, one round")
    ap.add_argument("--cases", help=f"comma-separated, of {','.join(CASES)} (default all)")
    ap.add_argument("--out", help=f"output folder (default report/{NAME}, target/report-quick/{NAME} with --quick)")
    ap.add_argument("--reps", type=int, help="timing rounds (default 7, 1 with --quick)")
    ap.add_argument("--work-dir", help="keep the packed FMUs here (default: a temporary folder)")
    args = ap.parse_args(argv)
    out = out_dir(args.out, NAME, args.quick)
    reps = args.reps or (1 if args.quick else 7)
    keys = args.cases.split(",") if args.cases else list(QUICK_CASES if args.quick else CASES)
    unknown = [k for k in keys if k not in CASES]
    if unknown:
        ap.error(f"unknown case(s) {unknown}: {', '.join(CASES)}")
    peer_mod = load_peer() if any(CASES[k].peer for k in keys) else None

    t_start = time.perf_counter()
    results, checks, tolerance_rows = [], [], []
    tmp = None
    if args.work_dir:
        work = Path(args.work_dir)
        work.mkdir(parents=True, exist_ok=True)
    else:
        tmp = tempfile.TemporaryDirectory(prefix="shared_peer_")
        work = Path(tmp.name)
    try:
        head = checkout()
        packed = [pack_case(CASES[k], work) for k in keys]
        for pk in packed:
            results.append(run_case(pk, peer_mod, reps, args.quick, checks, tolerance_rows))
        argv_cases = []
        if args.quick:
            argv_cases.append("--quick")
        if args.cases:
            argv_cases.append(f"--cases {args.cases}")
        if args.reps:
            argv_cases.append(f"--reps {args.reps}")
        write_report(out, results, checks, tolerance_rows, reps, args.quick, time.perf_counter() - t_start, work,
                     argv_cases, head)
    finally:
        if tmp is not None:
            tmp.cleanup()


if __name__ == "__main__":
    main()
