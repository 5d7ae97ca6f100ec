"""Step one FMU through one importer and print its outputs as JSON.

    python tests/python/importers.py {fmpy|fmpy-ns|libcosim|ecos} FMU STEP N_STEPS OUT.json

Each importer runs the FMU from its start values with a fixed
communication step and records every Real, Integer and Boolean output after
each step, by name. Run in a subprocess: ecos needs the tbb wheel's lib
directory on LD_LIBRARY_PATH before its library is loaded.
"""

from __future__ import annotations

import json
import sys


def outputs_of(fmu):
    from fmpy import read_model_description

    md = read_model_description(fmu)
    return md, [v for v in md.modelVariables if v.causality == "output"]


def run_fmpy(fmu, step, n, clock="sum"):
    """clock "sum": t += step, as fmpy and ecos keep time; "ns": the time in
    integer nanoseconds, as libcosim keeps it (t = k step_ns 1e-9, h =
    step_ns 1e-9), so that the FMU sees the same communication points."""
    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave

    md, outs = outputs_of(fmu)
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(fmu), modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="fmpy")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    rows = []
    t = 0.0
    step_ns = int(round(step * 1e9))
    for k in range(1, n + 1):
        if clock == "ns":
            slave.doStep(currentCommunicationPoint=(k - 1) * step_ns * 1e-9, communicationStepSize=step_ns * 1e-9)
        else:
            slave.doStep(currentCommunicationPoint=t, communicationStepSize=step)
            t += step
        row = {}
        for v in outs:
            if v.type == "Real":
                row[v.name] = slave.getReal([v.valueReference])[0]
            elif v.type == "Integer":
                row[v.name] = slave.getInteger([v.valueReference])[0]
            else:
                row[v.name] = bool(slave.getBoolean([v.valueReference])[0])
        rows.append(row)
    slave.terminate()
    slave.freeInstance()
    return rows


def run_libcosim(fmu, step, n):
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level

    log_output_level(CosimLogLevel.WARNING)
    md, outs = outputs_of(fmu)
    execution = CosimExecution.from_step_size(step_size=int(round(step * 1e9)))
    slave = CosimLocalSlave(fmu_path=fmu, instance_name="beam")
    index = execution.add_local_slave(local_slave=slave)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer=observer)
    rows = []
    for _ in range(n):
        assert execution.step(step_count=1), "libcosim step failed"
        row = {}
        for v in outs:
            if v.type == "Real":
                row[v.name] = observer.last_real_values(slave_index=index, variable_references=[v.valueReference])[0]
            elif v.type == "Integer":
                row[v.name] = observer.last_integer_values(slave_index=index, variable_references=[v.valueReference])[0]
            else:
                row[v.name] = bool(observer.last_boolean_values(slave_index=index, variable_references=[v.valueReference])[0])
        rows.append(row)
    return rows


def run_ecos(fmu, step, n):
    from ecospy import EcosSimulation, EcosSimulationStructure

    md, outs = outputs_of(fmu)
    structure = EcosSimulationStructure()
    structure.add_model("beam", fmu)
    rows = []
    with EcosSimulation(structure=structure, step_size=step) as sim:
        sim.init()
        for _ in range(n):
            sim.step()
            row = {}
            for v in outs:
                ident = f"beam::{v.name}"
                if v.type == "Real":
                    row[v.name] = sim.get_real(ident)
                elif v.type == "Integer":
                    row[v.name] = sim.get_integer(ident)
                else:
                    row[v.name] = bool(sim.get_bool(ident))
            rows.append(row)
        sim.terminate()
    return rows


if __name__ == "__main__":
    importer, fmu, step, n, out = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
    runners = {
        "fmpy": run_fmpy,
        "fmpy-ns": lambda f, h, k: run_fmpy(f, h, k, clock="ns"),
        "libcosim": run_libcosim,
        "ecos": run_ecos,
    }
    rows = runners[importer](fmu, step, n)
    with open(out, "w") as f:
        json.dump(rows, f)
