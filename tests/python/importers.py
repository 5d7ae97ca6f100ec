"""Step one FMU through one importer and write its outputs as JSON.

    python tests/python/importers.py IMPORTER FMU STEP N_STEPS OUT.json

IMPORTER is one of
  fmpy           fmpy's FMU2Slave (FMU3Slave for an FMI 3.0 FMU) on fmpy's
                 (and ecos's) time grid: t += h;
  fmpy-libcosim  fmpy's FMU2Slave on libcosim's time grid (see below);
  libcosim       OSP libcosim through libcosimpy: an execution with one local
                 slave and a last-value observer (FMI 2.0 only);
  ecos           ecos through ecospy: a simulation structure with one model
                 (FMI 2.0 and 3.0).

Each importer runs the FMU from its start values (start time 0) with the
fixed communication step STEP and records, after each of N_STEPS steps, the
time it reached and every Real, Integer and Boolean output (FMI 3.0: Float64,
Int32 and Boolean), by name. The JSON is
{"time": [t_1, ..., t_n], "rows": [{name: value}, ...]}; floats survive the
round trip through JSON exactly.

An FMI 3.0 FMU is stepped as ecos steps it: co-simulation without event mode
and without early return, fmi3DoStep with noSetFMUStatePriorToCurrentPoint.

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


# The variable types this comparison reads, FMI 2.0's and FMI 3.0's, by the
# kind of value they hold.
KIND = {"Real": "Real", "Float64": "Real", "Integer": "Integer", "Int32": "Integer", "Boolean": "Boolean"}


def outputs_of(fmu):
    from fmpy import read_model_description

    md = read_model_description(fmu)
    outs = [v for v in md.modelVariables if v.causality == "output"]
    unknown = [f"{v.name}: {v.type}" for v in outs if v.type not in KIND]
    assert not unknown, f"outputs of a type this comparison does not read: {unknown}"
    return md, outs


def of_kind(outs, kind):
    """The value references of the outputs of one kind, in the order of `outs`."""
    return [v.valueReference for v in outs if KIND[v.type] == kind]


def step_ns(step: float) -> int:
    ns = int(round(step * 1e9))
    assert ns > 0 and abs(ns * 1e-9 - step) <= 1e-15 * step, f"step {step!r} is not a whole number of nanoseconds"
    return ns


def run_fmpy(fmu, step, n, grid="sum"):
    from fmpy import calloc, extract, free
    from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2OK)

    md, outs = outputs_of(fmu)
    if md.fmiVersion == "3.0":
        assert grid == "sum", "FMI 3.0 is compared on fmpy's (and ecos's) grid only"
        return run_fmpy3(fmu, md, outs, step, n)

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
    real, integer, boolean = of_kind(outs, "Real"), of_kind(outs, "Integer"), of_kind(outs, "Boolean")
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


def run_fmpy3(fmu, md, outs, step, n):
    """fmpy's FMU3Slave as ecos drives an FMI 3.0 FMU: no event mode, no
    early return; t += h."""
    from fmpy import extract
    from fmpy.fmi3 import FMU3Slave, fmi3OK

    def logger(env, status, category, message):
        if status != fmi3OK:
            text = (message or b"").decode("utf-8", "replace")
            print(f"[fmpy] FMU status {status} [{(category or b'').decode()}] {text}", file=sys.stderr)

    slave = FMU3Slave(guid=md.guid, unzipDirectory=extract(fmu), modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="beam")
    slave.instantiate(loggingOn=True, logMessage=logger)
    slave.enterInitializationMode(startTime=0.0)
    slave.exitInitializationMode()
    real, integer, boolean = of_kind(outs, "Real"), of_kind(outs, "Integer"), of_kind(outs, "Boolean")
    times, rows = [], []
    t = 0.0
    for _ in range(n):
        _, terminate, early, _ = slave.doStep(currentCommunicationPoint=t, communicationStepSize=step)
        assert not terminate and not early, f"fmi3DoStep at t = {t!r}: terminate {terminate}, early return {early}"
        t += step
        times.append(t)
        rows.append(by_name(outs, slave.getFloat64(real) if real else [], slave.getInt32(integer) if integer else [],
                            slave.getBoolean(boolean) if boolean else []))
    slave.terminate()
    slave.freeInstance()
    return times, rows


def by_name(outs, reals, integers, booleans):
    """One row {name: value} from the values read in the order of `outs`."""
    values = {"Real": iter(reals), "Integer": iter(integers), "Boolean": iter(booleans)}
    row = {}
    for v in outs:
        kind = KIND[v.type]
        x = next(values[kind])
        row[v.name] = float(x) if kind == "Real" else int(x) if kind == "Integer" else bool(x)
    return row


def run_libcosim(fmu, step, n):
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    md, outs = outputs_of(fmu)
    assert md.fmiVersion == "2.0", "the libcosim runner reads FMI 2.0 FMUs only"
    ns = step_ns(step)
    execution = CosimExecution.from_step_size(step_size=ns)
    index = execution.add_local_slave(local_slave=CosimLocalSlave(fmu_path=str(fmu), instance_name="beam"))
    assert index >= 0, "libcosim refused the FMU"
    observer = CosimObserver.create_last_value()
    assert execution.add_observer(observer=observer), "libcosim: add_observer failed"
    real, integer, boolean = of_kind(outs, "Real"), of_kind(outs, "Integer"), of_kind(outs, "Boolean")
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
    convert = {"Real": float, "Integer": int, "Boolean": bool}
    times, rows = [], []
    with EcosSimulation(structure=structure, step_size=step) as sim:
        sim.init()
        # (name, reader, identifier, conversion) of every output, looked up once.
        readers = [(v.name, getattr(sim, getter[KIND[v.type]]), f"beam::{v.name}", convert[KIND[v.type]]) for v in outs]
        for _ in range(n):
            times.append(sim.step())
            rows.append({name: conv(read(ident)) for name, read, ident, conv in readers})
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
    # json.dumps, not json.dump: dump streams through the pure-Python
    # encoder, several times slower than the whole run on 20000 rows.
    with open(out, "w") as f:
        f.write(json.dumps({"time": times, "rows": rows}))
