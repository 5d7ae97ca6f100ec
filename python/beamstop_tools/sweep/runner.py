"""Runs sweep points on a worker: the FMU is extracted and instantiated once
per worker process (and thread), then reset for each independent point or
kept running along a continuation chain.

A point: set its parameters (from rest: in initialisation mode; along a
chain: the tunable ones between steps), skip the transient with ONE
fmi2DoStep up to a whole number of forcing periods (results do not depend
on the communication step), then record `record` periods at
`samples_per_period` samples each; the samples at phase 0 are the Poincare
section.
"""
from __future__ import annotations

import math
import os
import shutil
import tempfile
import threading
import time
import weakref
from dataclasses import dataclass

import numpy as np
from fmpy.fmi1 import FMICallException

from . import measures
from .. import engine


@dataclass(frozen=True)
class Plan:
    """What a worker needs to know, as plain values (it is pickled)."""
    guid: str
    model_identifier: str
    refs: dict             # name -> value reference of everything read or set
    output: str
    rate: str | None
    counters: tuple        # Integer outputs counting impacts (rigid stops, first) / contacts
    rigid_counters: int    # how many of them are rigid stops' impacts (the velocity jumps)
    sticking: tuple        # Boolean flags (used when there is no stuck time)
    stuck_times: tuple     # Real: total time held on a stop
    sticks: tuple          # Integer: stick onsets
    tunable: tuple         # parameters that may change between steps
    forcing: str
    discard: float
    record: int
    samples_per_period: int
    period_tol: float
    max_period: int


def plan_for(spec) -> Plan:
    info = spec.info
    rigid = [s for s in info.stops if s.rigid]
    counters = tuple(s.counter for s in rigid if s.counter) + tuple(s.counter for s in info.stops
                                                                  if s.counter and not s.rigid)
    stuck = tuple(s.stuck_time for s in rigid if s.stuck_time)
    sticks = tuple(s.sticks for s in rigid if s.sticks)
    flags = tuple(s.sticking for s in rigid if s.sticking) if not stuck else ()
    names = set(info.parameters) | {spec.output} | set(counters) | set(stuck) | set(sticks) | set(flags)
    if spec.rate:
        names.add(spec.rate)
    return Plan(info.guid, info.model_identifier, {n: info.value_references[n] for n in names},
                spec.output, spec.rate, counters, sum(1 for s in rigid if s.counter), flags, stuck, sticks,
                tuple(n for n, p in info.parameters.items() if p.tunable), spec.forcing, spec.discard, spec.record,
                spec.samples_per_period, spec.period_tol, spec.max_period)


class Instance:
    """One FMU instance with a logger that keeps the last messages.

    The FMU is extracted to a temporary folder only while an instance is
    made: the loaded library and the instance read nothing from it later,
    and a worker process may end without running exit handlers (Dask's end
    a process at once when its nanny goes), so the folder is removed at
    once. Where a loaded library cannot be removed (Windows), the folder is
    removed when the process exits normally."""

    def __init__(self, fmu_data: bytes, plan: Plan):
        self.fmu_data = fmu_data
        self.messages: list[str] = []
        self.plan = plan
        self._new()

    def _log(self, status, category, text):
        self.messages = (self.messages + [text])[-5:]

    def _new(self):
        folder = tempfile.mkdtemp(prefix="beamstop-sweep-")
        try:
            path = os.path.join(folder, "model.fmu")
            with open(path, "wb") as f:
                f.write(self.fmu_data)
            self.fmu = engine.Fmu(path, unzipdir=os.path.join(folder, "x"))
            self.session = engine.Session(self.fmu, "sweep", logger=self._log, logging_on=False)
        finally:
            shutil.rmtree(folder, ignore_errors=True)
            if os.path.exists(folder):
                weakref.finalize(self, shutil.rmtree, folder, ignore_errors=True)
        self.slave = self.session.slave
        self.used = False
        self.piece = None      # longest step the work cap allows, learnt from fmi2Discard

    def renew(self):
        """After a failure: a new instance (the old one may be in the Error state)."""
        try:
            self.slave.freeInstance()
        except Exception:
            pass
        self._new()

    def start(self, values: dict) -> None:
        """From rest at t = 0 with these parameter values."""
        if self.used:
            self.slave.reset()
        self.used = True
        self.session.start(values)

    def set(self, values: dict) -> None:
        self.session.set(values)

    def close(self) -> None:
        """Frees the FMU instance."""
        try:
            self.slave.freeInstance()
        except Exception:
            pass

    def failure(self, err: Exception) -> str:
        last = f": {self.messages[-1]}" if self.messages else ""
        return f"{err}{last}"


_INSTANCES: dict = {}


def instance(fmu_data: bytes, plan: Plan) -> Instance:
    """This process's (and thread's) instance of the FMU, made on first use."""
    key = (plan.guid, threading.get_ident())
    inst = _INSTANCES.get(key)
    if inst is None or inst.plan != plan:
        if inst is not None:
            inst.close()
        inst = _INSTANCES[key] = Instance(fmu_data, plan)
    return inst


def advance(inst: Instance, now: float, target: float, period: float) -> None:
    """Steps from now to target: in ONE fmi2DoStep (the results do not
    depend on the communication step), unless the FMU's work cap per call
    (fmi2Discard) forces shorter steps: then the state before the step is
    restored and the span is stepped in pieces of 16, 4, 1 forcing periods,
    remembered for the next points of this instance."""
    s = inst.slave
    while True:
        piece = inst.piece if inst.piece is not None else target - now
        snapshot = s.getFMUstate() if target - now > piece or inst.piece is None else None
        t = now
        try:
            while t < target:
                h = min(piece, target - t)
                if target - (t + h) < 1e-9 * period:
                    h = target - t
                s.doStep(t, h)
                t = t + h if t + h < target else target
            if snapshot is not None:
                s.freeFMUstate(snapshot)
            return
        except FMICallException as err:
            if getattr(err, "status", None) != 2 or snapshot is None or (inst.piece is not None and inst.piece <= period):
                raise
            s.setFMUstate(snapshot)
            s.freeFMUstate(snapshot)
            inst.piece = 16 * period if inst.piece is None else max(period, inst.piece / 4)


def _read(inst: Instance):
    s, p = inst.slave, inst.plan
    r = p.refs
    reals = s.getReal([r[p.output]] + ([r[p.rate]] if p.rate else []) + [r[n] for n in p.stuck_times])
    ints = s.getInteger([r[n] for n in p.counters + p.sticks]) if (p.counters or p.sticks) else []
    flags = s.getBoolean([r[n] for n in p.sticking]) if p.sticking else []
    return reals, ints, flags


def record_point(inst: Instance, t0: float, period: float) -> dict:
    """Steps from t0 over `record` forcing periods and measures the point."""
    p = inst.plan
    spp, n = p.samples_per_period, p.record * p.samples_per_period
    nr = 1 + (1 if p.rate else 0)
    t = np.empty(n + 1)
    y = np.empty(n + 1)
    v = np.empty(n + 1) if p.rate else None
    counts = np.zeros((n + 1, len(p.counters) + len(p.sticks)), dtype=np.int64)
    flags = np.zeros(n + 1, dtype=bool)
    stuck0 = stuck1 = None
    now = t0
    for k in range(n + 1):
        if k:
            target = t0 + (k / spp) * period
            inst.slave.doStep(now, target - now)
            now = target
        reals, ints, fl = _read(inst)
        t[k], y[k] = now, reals[0]
        if v is not None:
            v[k] = reals[1]
        if p.stuck_times:
            st = sum(reals[nr:])
            stuck0 = st if k == 0 else stuck0
            stuck1 = st
        counts[k] = ints
        flags[k] = any(fl)
    nc = len(p.counters)
    impacts = int((counts[-1, :nc] - counts[0, :nc]).sum())
    nr_ = p.rigid_counters          # a rigid impact makes the rate jump: no interpolation across it
    smooth = np.all(counts[1:, :nr_] == counts[:-1, :nr_], axis=1)
    found = measures.maxima(t, y, v, smooth)
    span = p.record * period
    if p.stuck_times:
        stuck = max(stuck1 - stuck0, 0.0)
        onsets = int((counts[-1, nc:] - counts[0, nc:]).sum())
        sticking, fraction = bool(stuck > 0 or onsets > 0), stuck / span
    else:
        sticking, fraction = bool(flags.any()), float(flags.mean())
    strob = y[::spp]
    strob_rate = v[::spp] if v is not None else None
    return {
        "t_record": t0,
        "impacts": impacts,
        "impacts_per_period": impacts / p.record,
        "sticking": sticking,
        "stuck_fraction": fraction,
        "period": measures.response_period(strob, strob_rate, p.period_tol, p.max_period,
                                           (np.ptp(y), np.ptp(v) if v is not None else 0.0)),
        "peak": measures.peak(y, found),
        "poincare": strob.tolist(),
        "poincare_rate": strob_rate.tolist() if strob_rate is not None else [],
        "maxima": found.tolist(),
    }


def _row(point, direction, chain, result, seconds, error=None):
    row = {"point": point[0], "direction": direction, "chain": chain, "forcing_period": point[2]}
    row.update(point[1])
    row.update(result)
    row["seconds"] = seconds
    row["error"] = error
    return row


def _failed(point, direction, chain, message, seconds=0.0):
    return _row(point, direction, chain, {}, seconds, message)


def run_points(fmu_data: bytes, plan: Plan, points: list) -> dict:
    """Independent points, each from rest at t = 0. `points` holds
    (index, values, forcing period)."""
    inst = instance(fmu_data, plan)
    rows = []
    for pt in points:
        started = time.perf_counter()
        try:
            inst.start(pt[1])
            t0 = plan.discard * pt[2]
            if t0 > 0:
                advance(inst, 0.0, t0, pt[2])
            result = record_point(inst, t0, pt[2])
            rows.append(_row(pt, None, None, result, time.perf_counter() - started))
        except Exception as err:  # the FMU refused: record why, go on with the next point
            rows.append(_failed(pt, None, None, inst.failure(err), time.perf_counter() - started))
            inst.renew()
    return {"rows": rows, "state": None}


def run_chain(fmu_data: bytes, plan: Plan, direction: str, chain: int, points: list, continued: dict | None) -> dict:
    """A segment of a continuation chain: each point starts from the state
    the previous one left (the tunable parameters are changed between
    steps, the time goes on). `continued` is the previous segment's result,
    holding the serialized FMU state after its last point and its time;
    without it (or after a failure) the chain starts from rest. Returns the
    rows and the serialized state after the last point."""
    inst = instance(fmu_data, plan)
    s = inst.slave
    rows = []
    live, now = False, 0.0
    if continued and continued.get("state") is not None and points:
        inst.start(points[0][1])                   # the chain's fixed parameters, then its state
        fmu_state = s.deSerializeFMUstate(continued["state"])
        s.setFMUstate(fmu_state)
        s.freeFMUstate(fmu_state)
        live, now = True, continued["time"]
    for pt in points:
        started = time.perf_counter()
        try:
            if live:
                inst.set({n: v for n, v in pt[1].items() if n in plan.tunable})
            else:
                inst.start(pt[1])
                live, now = True, 0.0
            period = pt[2]
            # the next whole forcing period (phase 0 of the new frequency), then the transient: one step
            t0 = (math.ceil(now / period - 1e-9) + plan.discard) * period
            if t0 > now:
                advance(inst, now, t0, period)
            result = record_point(inst, t0, period)
            now = t0 + plan.record * period
            rows.append(_row(pt, direction, chain, result, time.perf_counter() - started))
        except Exception as err:  # the next point starts the chain again from rest
            rows.append(_failed(pt, direction, chain, inst.failure(err), time.perf_counter() - started))
            inst.renew()
            live = False
    state = None
    if live:
        fmu_state = s.getFMUstate()
        state = bytes(s.serializeFMUstate(fmu_state))
        s.freeFMUstate(fmu_state)
    return {"rows": rows, "state": state, "time": now}
