"""The coupled run, by two masters, on one time grid.

Both masters keep libcosim's clock: t_k = (k h_ns) / 1e9 in integer
nanoseconds, steps h_k = t_(k+1) - t_k (tests/python/importers.py explains
why: t += h drifts from that grid by ulps).

Orderings (what the plant's torque over [t_k, t_(k+1)] is):
- "jacobi", libcosim's fixed-step algorithm: every unit steps from the
  values exchanged after the previous step, then outputs are copied to
  inputs. The controller samples theta(t_k) during its step k and its output
  reaches the plant one step later: torque over step k = law(theta_(k-1)),
  one sample of computational delay (the first two steps both use the law at
  t_0, which libcosim's initialisation hands the plant).
- "gauss-seidel", the usual hand-written loop: read theta(t_k), compute the
  law, set the torque, step the plant: torque over step k = law(theta_k).

The fmpy loop steps RotatingBeamImpact.fmu through fmpy and the controller
as `beamstop_tools.coupling.controller.Controller` (the FMU's law in Python, the same
floating-point operations); libcosim runs both FMUs from the OSP system
structure. With the same ordering the two give the same trajectory bit for
bit; the comparison in `pd_slew` says how close they are.
"""
from __future__ import annotations

import re
import time as _time

import numpy as np

from .. import engine
from .controller import Controller
from .system import System

#: The beam's outputs recorded after each step.
BEAM_OUTPUTS = ("theta", "theta_dot", "tip.w", "tip.x", "tip.y", "root.M", "energy",
                "stop.force", "stop.penetration", "stop.impulse", "stop.contacts", "stop.contact")
#: A contact's peak force in the FMU's logEvents message for a separation.
PEAK = re.compile(r"peak force ([-+0-9.eE]+) N")
#: Columns of a run: the time t_(k+1), the torque applied over [t_k, t_(k+1)]
#: and the reference the controller computed it with, then the beam's outputs.
COLUMNS = ("time", "torque", "theta_r") + BEAM_OUTPUTS


def _grid(system: System, n: int):
    ns = system.step_ns
    t0 = system.start
    if t0 != 0.0:
        raise ValueError("the example starts at t = 0 (libcosim's clock in nanoseconds from the start)")
    return [k * ns / 1e9 for k in range(n + 1)]


def steps_for(system: System, t_end: float) -> int:
    return int(round(t_end / system.step))


def _result(rows, wall, extra=None):
    out = {c: np.array([r[i] for r in rows], dtype=float) for i, c in enumerate(COLUMNS)}
    out["wall"] = wall
    if extra:
        out.update(extra)
    return out


def run_fmpy(system: System, t_end: float, ordering: str = "jacobi") -> dict:
    """RotatingBeamImpact.fmu through fmpy's FMU2Slave, the controller in Python."""
    if ordering not in ("jacobi", "gauss-seidel"):
        raise ValueError(ordering)
    beam_sim, ctrl_sim = system.simulators["beam"], system.simulators["controller"]
    fmu = engine.Fmu(beam_sim.fmu)
    var = fmu.vars
    missing = [n for n in BEAM_OUTPUTS + ("torque",) if n not in var]
    if missing:
        raise KeyError(f"{beam_sim.fmu.name} has no {missing}")
    # The connections of the system structure, checked against what this loop wires.
    wired = {("beam", "theta", "controller", "theta"), ("beam", "theta_dot", "controller", "theta_dot"),
             ("controller", "torque", "beam", "torque")}
    if set(system.connections) != wired:
        raise ValueError(f"the fmpy loop wires {sorted(wired)}, the structure {sorted(system.connections)}")
    # The FMU's event log gives each contact's exact peak force (the outputs
    # are samples at communication points); anything not fmi2OK is an error.
    peaks, problems = [], []

    def logger(status, category, message):
        text = message.replace("%%", "%")
        if status != 0:  # fmi2OK
            problems.append(f"[{category}] {text}")
        m = PEAK.search(text)
        if m:
            peaks.append(float(m.group(1)))

    categories = [getattr(c, "name", c) for c in getattr(fmu.md, "logCategories", []) or []]
    session = engine.Session(fmu, "beam", logger=logger, logging_on=True,
                             categories=["logEvents"] if "logEvents" in categories else None)
    session.start(beam_sim.initial, t0=system.start)
    beam = session.slave

    ctrl = Controller.from_values(ctrl_sim.initial, t_start=system.start)
    real_vr = [var[n].valueReference for n in BEAM_OUTPUTS if var[n].type == "Real"]
    int_vr = [var[n].valueReference for n in BEAM_OUTPUTS if var[n].type == "Integer"]
    bool_vr = [var[n].valueReference for n in BEAM_OUTPUTS if var[n].type == "Boolean"]
    order = [n for n in BEAM_OUTPUTS if var[n].type == "Real"] + \
            [n for n in BEAM_OUTPUTS if var[n].type == "Integer"] + [n for n in BEAM_OUTPUTS if var[n].type == "Boolean"]
    index = [order.index(n) for n in BEAM_OUTPUTS]
    torque_vr = [var["torque"].valueReference]
    theta_vr = [var["theta"].valueReference, var["theta_dot"].valueReference]

    def read():
        vals = list(beam.getReal(real_vr)) + list(beam.getInteger(int_vr)) + [float(b) for b in beam.getBoolean(bool_vr)]
        return [vals[i] for i in index]

    n = steps_for(system, t_end)
    grid = _grid(system, n)
    theta, theta_dot = beam.getReal(theta_vr)
    # Jacobi: what libcosim's initialisation hands the plant (the law at t_0).
    held = ctrl.law(grid[0], theta, theta_dot)
    rows = []
    clock = _time.perf_counter()
    for k in range(n):
        t, h = grid[k], grid[k + 1] - grid[k]
        if ordering == "jacobi":
            applied = held
            beam.setReal(torque_vr, [applied.torque])
            beam.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            held = ctrl.step(t, h, theta, theta_dot)   # samples theta(t_k): the plant gets it next step
        else:
            applied = ctrl.step(t, h, theta, theta_dot)
            beam.setReal(torque_vr, [applied.torque])
            beam.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        outs = read()
        theta, theta_dot = outs[0], outs[1]
        rows.append([grid[k + 1], applied.torque, applied.reference] + outs)
    wall = _time.perf_counter() - clock
    session.close()
    if problems:
        raise RuntimeError("RotatingBeamImpact.fmu complained:\n" + "\n".join(problems[:20]))
    return _result(rows, wall, {"master": f"fmpy ({ordering})", "peaks": peaks})


def run_libcosim(system: System, t_end: float) -> dict:
    """Both FMUs in OSP libcosim (libcosimpy), from the OSP system structure;
    a last-value observer read after every step."""
    from fmpy import read_model_description
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)
    for s in system.simulators.values():
        if not s.fmu.is_file():
            raise FileNotFoundError(s.fmu)
    execution = CosimExecution.from_osp_config_file(str(system.path))
    observer = CosimObserver.create_last_value()
    if not execution.add_observer(observer=observer):
        raise RuntimeError("libcosim: add_observer failed")
    beam = execution.slave_index_from_instance_name("beam")
    ctrl = execution.slave_index_from_instance_name("controller")
    bvar = {v.name: v for v in read_model_description(str(system.simulators["beam"].fmu)).modelVariables}
    cvar = {v.name: v for v in read_model_description(str(system.simulators["controller"].fmu)).modelVariables}
    real = [n for n in BEAM_OUTPUTS if bvar[n].type == "Real"]
    integer = [n for n in BEAM_OUTPUTS if bvar[n].type == "Integer"]
    boolean = [n for n in BEAM_OUTPUTS if bvar[n].type == "Boolean"]
    real_vr = [bvar[n].valueReference for n in real] + [bvar["torque"].valueReference]
    int_vr = [bvar[n].valueReference for n in integer]
    bool_vr = [bvar[n].valueReference for n in boolean]
    ctrl_vr = [cvar["torque"].valueReference, cvar["theta_r"].valueReference]
    ns = system.step_ns
    n = steps_for(system, t_end)
    rows = []
    reference = None
    clock = _time.perf_counter()
    for k in range(n):
        if not execution.step(step_count=1):
            raise RuntimeError(f"libcosim: step {k + 1} failed: {execution.status()}")
        now = execution.status().current_time
        if now != (k + 1) * ns:
            raise RuntimeError(f"libcosim at {now} ns after {k + 1} steps of {ns} ns")
        r = observer.last_real_values(slave_index=beam, variable_references=real_vr)
        i = observer.last_integer_values(slave_index=beam, variable_references=int_vr) if int_vr else []
        b = observer.last_boolean_values(slave_index=beam, variable_references=bool_vr) if bool_vr else []
        vals = dict(zip(real, r[:-1])) | dict(zip(integer, i)) | {name: float(x) for name, x in zip(boolean, b)}
        # The torque the beam held over this step: its input as the beam reports it.
        applied = r[-1]
        c_torque, c_ref = observer.last_real_values(slave_index=ctrl, variable_references=ctrl_vr)
        # The controller's sample after step k is the beam's torque over step k + 1.
        if reference is None:
            reference = c_ref   # steps 0 and 1 both use the law at t_0
        rows.append([now / 1e9, applied, reference] + [vals[name] for name in BEAM_OUTPUTS])
        reference = c_ref
    wall = _time.perf_counter() - clock
    return _result(rows, wall, {"master": "libcosim (fixedStep)"})
