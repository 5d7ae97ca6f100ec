"""Restores continue bit for bit through the FMI calls a co-simulation
master uses to roll back, on every FMU: before each communication step the
state is taken (fmi2GetFMUstate) and set into a second instance, and
serialized (fmi2SerializeFMUstate) and deserialized into a third; the three
then take the same step and every output must have the same bits. Three
step sizes per FMU, with a tunable parameter or an input changed mid-run
where the FMU has one. (tests/integration/restores.rs checks the same on the engine's
own encoding, with longer runs through every phase each scene has.)"""

import zipfile

import pytest
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave

from conftest import FMU_DIR

# FMU: (three communication steps it accepts, steps per run, change mid-run).
RUNS = {
    "PinnedBeamStop": ((0.01, 0.1, 1.0), 30, ("omega", 9.0)),
    "WaggBishopChain": ((0.05, 0.5, 5.0), 30, ("A1.omega", 1.2)),
    "WaggBishopCantilever1": ((0.01, 0.1, 1.0), 30, ("base.amplitude", 0.05)),
    "WaggBishopCantilever4": ((0.01, 0.1, 1.0), 30, ("base.amplitude", 0.05)),
    "SteelCantileverStop": ((0.001, 0.01, 0.1), 30, ("force", 5.0)),
    "SpringStopSoft": ((1e-4, 1e-3, 1e-2), 30, ("shaker.omega", 90.0)),
    "SpringStopHard": ((1e-4, 1e-3, 1e-2), 30, ("stop.k", 2e5)),
    "SpringStopVeryHard": ((1e-4, 1e-3, 1e-2), 30, None),
    "HertzStop": ((2e-4, 5e-4, 1e-3), 120, ("stop.e", 0.6)),
    "RotatingBeamImpact": ((1e-5, 1e-4, 1e-3), 30, ("torque", 1.0)),
    "SpinUpBeam": ((0.01, 0.1, 1.0), 30, None),
    "TappingArm": ((0.01, 0.02, 0.05), 12, None),
}


class Unit:
    """One instance of an FMU, with every output's value reference by type."""

    def __init__(self, unzipdir, md, name):
        self.md = md
        self.slave = FMU2Slave(guid=md.guid, unzipDirectory=str(unzipdir),
                               modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self.slave.instantiate()
        self.time = 0.0
        outputs = [v for v in md.modelVariables if v.causality == "output"]
        self.reals = [v.valueReference for v in outputs if v.type == "Real"]
        self.integers = [v.valueReference for v in outputs if v.type == "Integer"]
        self.booleans = [v.valueReference for v in outputs if v.type == "Boolean"]

    def start(self):
        self.slave.setupExperiment(startTime=0.0)
        self.slave.enterInitializationMode()
        self.slave.exitInitializationMode()

    def outputs(self):
        reals = [x.hex() for x in self.slave.getReal(self.reals)] if self.reals else []
        integers = list(self.slave.getInteger(self.integers)) if self.integers else []
        booleans = [bool(b) for b in self.slave.getBoolean(self.booleans)] if self.booleans else []
        return reals, integers, booleans

    def step(self, h):
        self.slave.doStep(currentCommunicationPoint=self.time, communicationStepSize=h)
        self.time += h


@pytest.mark.parametrize("fmu", sorted(RUNS))
def test_restores_continue_bit_for_bit(fmu, tmp_path):
    path = FMU_DIR / f"{fmu}.fmu"
    with zipfile.ZipFile(path) as z:
        z.extractall(tmp_path)
    md = read_model_description(str(path))
    refs = {v.name: v.valueReference for v in md.modelVariables}
    steps, n, change = RUNS[fmu]
    units = []
    try:
        for h in steps:
            original, by_state, by_bytes = (Unit(tmp_path, md, f"{fmu}-{k}") for k in ("original", "state", "bytes"))
            units += [original, by_state, by_bytes]
            original.start()
            for k in range(n):
                if change and k == n // 3:
                    original.slave.setReal([refs[change[0]]], [change[1]])
                state = original.slave.getFMUstate()
                data = original.slave.serializeFMUstate(state)
                by_state.slave.setFMUstate(state)
                original.slave.freeFMUstate(state)
                restored = by_bytes.slave.deSerializeFMUstate(data)
                by_bytes.slave.setFMUstate(restored)
                by_bytes.slave.freeFMUstate(restored)
                by_state.time = by_bytes.time = original.time
                for u in (original, by_state, by_bytes):
                    u.step(h)
                expected = original.outputs()
                assert by_state.outputs() == expected, f"{fmu}, h = {h}, step {k}: fmi2SetFMUstate differs"
                assert by_bytes.outputs() == expected, f"{fmu}, h = {h}, step {k}: the deserialized state differs"
    finally:
        for u in units:
            u.slave.terminate()
            u.slave.freeInstance()
