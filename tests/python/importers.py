"""Step one FMU through one importer and write its outputs as JSON.

    python tests/python/importers.py IMPORTER FMU STEP N_STEPS OUT.json

IMPORTER is one of
  fmpy           fmpy's FMU2Slave on fmpy's (and ecos's) time grid: t += h;
  fmpy-libcosim  fmpy's FMU2Slave on libcosim's time grid (see below);
  libcosim       OSP libcosim through libcosimpy: an execution with one local
                 slave and a last-value observer;
  ecos           ecos through ecospy: a simulation structure with one model.

Each importer runs the FMU from its start values (start time 0) with the
fixed communication step STEP and records, after each of N_STEPS steps, the
time it reached and every Real, Integer and Boolean output, by name. The JSON
is {"time": [t_1, ..., t_n], "rows": [{name: value}, ...]}; floats survive the
round trip through JSON exactly.

Run it in a subprocess (tests/python/test_importers.py does): ecos's library
needs the tbb wheel's lib directory on LD_LIBRARY_PATH before it is loaded,
and a crash of an importer then fails one test instead of the session.
Nothing is printed unless an importer or the FMU complains: libcosim logs at
WARNING and above, ecos at its default level, and fmpy's logger prints every
message whose status is not fmi2OK, all to stderr.

libcosim's time grid: libcosim keeps time in integer nanoseconds and hands
the FMU t_k = to_double_time_point(k h_ns) = (k h_ns) / 1e9 (a correctly
rounded division, std::chrono::duration_cast) and the step size
h_k = t_(k+1) - t_k (cosim::to_double_duration), see libcosim's
include/cosim/time.hpp. That is not the grid t += h: for h = 0.01 almost every
point differs from it by an ulp or so.
"""

from __future__ import annotations

import json
import sys


def outputs_of(fmu):
    from fmpy import read_model_description

    md = read_model_description(fmu)
    outs = [v for v in md.modelVariables if v.causality == "output"]
    unknown = [f"{v.name}: {v.type}" for v in outs if v.type not in ("Real", "Integer", "Boolean")]
    assert not unknown, f"outputs of a type this comparison does not read: {unknown}"
    return md, outs


def step_ns(step: float) -> int:
    ns = int(round(step * 1e9))
    assert ns > 0 and abs(ns * 1e-9 - step) <= 1e-15 * step, f"step {step!r} is not a whole number of nanoseconds"
    return ns


def run_fmpy(fmu, step, n, grid="sum"):
    from fmpy import calloc, extract, free
    from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2OK)

    md, outs = outputs_of(fmu)

    def logger(env, instance, status, category, message):
        # The FMU passes no printf arguments and escapes '%' as '%%'.
        if status != fmi2OK:
            text = (message or b"").decode("utf-8", "replace").replace("%%", "%")
            print(f"[fmpy] FMU status {status} [{(category or b'').decode()}] {text}", file=sys.stderr)

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(fmu), modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="beam")
    slave.instantiate(callbacks=callbacks, loggingOn=True)
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    real = [v.valueReference for v in outs if v.type == "Real"]
    integer = [v.valueReference for v in outs if v.type == "Integer"]
    boolean = [v.valueReference for v in outs if v.type == "Boolean"]
    ns = step_ns(step)
    times, rows = [], []
    t = 0.0
    for k in range(n):
        if grid == "libcosim":
            t, h = k * ns / 1e9, (k + 1) * ns / 1e9 - k * ns / 1e9
        else:
            h = step
        slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        t = (k + 1) * ns / 1e9 if grid == "libcosim" else t + step
        times.append(t)
        rows.append(by_name(outs, slave.getReal(real) if real else [], slave.getInteger(integer) if integer else [],
                            slave.getBoolean(boolean) if boolean else []))
    slave.terminate()
    slave.freeInstance()
    return times, rows


def by_name(outs, reals, integers, booleans):
    """One row {name: value} from the values read in the order of `outs`."""
    values = {"Real": iter(reals), "Integer": iter(integers), "Boolean": iter(booleans)}
    row = {}
    for v in outs:
        x = next(values[v.type])
        row[v.name] = float(x) if v.type == "Real" else int(x) if v.type == "Integer" else bool(x)
    return row


def run_libcosim(fmu, step, n):
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    md, outs = outputs_of(fmu)
    ns = step_ns(step)
    execution = CosimExecution.from_step_size(step_size=ns)
    index = execution.add_local_slave(local_slave=CosimLocalSlave(fmu_path=str(fmu), instance_name="beam"))
    assert index >= 0, "libcosim refused the FMU"
    observer = CosimObserver.create_last_value()
    assert execution.add_observer(observer=observer), "libcosim: add_observer failed"
    real = [v.valueReference for v in outs if v.type == "Real"]
    integer = [v.valueReference for v in outs if v.type == "Integer"]
    boolean = [v.valueReference for v in outs if v.type == "Boolean"]
    times, rows = [], []
    for k in range(n):
        assert execution.step(step_count=1), f"libcosim: step {k + 1} failed: {execution.status()}"
        now = execution.status().current_time
        assert now == (k + 1) * ns, f"libcosim at {now} ns after {k + 1} steps of {ns} ns"
        times.append(now / 1e9)
        rows.append(by_name(
            outs,
            observer.last_real_values(slave_index=index, variable_references=real) if real else [],
            observer.last_integer_values(slave_index=index, variable_references=integer) if integer else [],
            observer.last_boolean_values(slave_index=index, variable_references=boolean) if boolean else [],
        ))
    return times, rows


def run_ecos(fmu, step, n):
    from ecospy import EcosSimulation, EcosSimulationStructure

    md, outs = outputs_of(fmu)
    structure = EcosSimulationStructure()
    structure.add_model("beam", str(fmu))
    getter = {"Real": "get_real", "Integer": "get_integer", "Boolean": "get_bool"}
    times, rows = [], []
    with EcosSimulation(structure=structure, step_size=step) as sim:
        sim.init()
        for _ in range(n):
            times.append(sim.step())
            row = {}
            for v in outs:
                x = getattr(sim, getter[v.type])(f"beam::{v.name}")
                row[v.name] = float(x) if v.type == "Real" else int(x) if v.type == "Integer" else bool(x)
            rows.append(row)
        sim.terminate()
    return times, rows


RUNNERS = {
    "fmpy": run_fmpy,
    "fmpy-libcosim": lambda fmu, step, n: run_fmpy(fmu, step, n, grid="libcosim"),
    "libcosim": run_libcosim,
    "ecos": run_ecos,
}

if __name__ == "__main__":
    importer, fmu, step, n, out = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
    times, rows = RUNNERS[importer](fmu, step, n)
    with open(out, "w") as f:
        json.dump({"time": times, "rows": rows}, f)
