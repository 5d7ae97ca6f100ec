"""examples/coupling/OspSystemStructure.xml, read for the fmpy loop: both
masters take the step, the initial values and the connections from the one
file libcosim runs."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from .. import ROOT

STRUCTURE = ROOT / "examples" / "coupling" / "OspSystemStructure.xml"
NS = {"osp": "http://opensimulationplatform.com/MSMI/OSPSystemStructure"}


@dataclass
class Simulator:
    name: str
    fmu: Path
    initial: dict = field(default_factory=dict)


@dataclass
class System:
    path: Path
    start: float
    step: float
    simulators: dict
    #: (source simulator, variable, target simulator, variable)
    connections: list

    @property
    def step_ns(self) -> int:
        """libcosim's step in integer nanoseconds (it keeps time so)."""
        ns = round(self.step * 1e9)
        if ns <= 0 or abs(ns * 1e-9 - self.step) > 1e-15 * self.step:
            raise ValueError(f"step {self.step!r} is not a whole number of nanoseconds")
        return ns

    def inputs_of(self, simulator: str) -> dict:
        """{input variable: (source simulator, output variable)}."""
        return {tv: (s, sv) for (s, sv, t, tv) in self.connections if t == simulator}


def _value(elem):
    for tag, conv in (("Real", float), ("Integer", int), ("Boolean", lambda v: v.lower() in ("true", "1"))):
        child = elem.find(f"osp:{tag}", NS)
        if child is not None:
            return conv(child.get("value"))
    raise ValueError(f"initial value of {elem.get('variable')}: no Real, Integer or Boolean")


def load(path: Path = STRUCTURE) -> System:
    path = Path(path).resolve()
    root = ET.parse(path).getroot()
    text = lambda tag, default: (root.find(f"osp:{tag}", NS).text if root.find(f"osp:{tag}", NS) is not None else default)
    algorithm = text("Algorithm", "fixedStep")
    if algorithm != "fixedStep":
        raise ValueError(f"{path}: algorithm {algorithm}: the fmpy loop mirrors libcosim's fixedStep only")
    simulators = {}
    for s in root.findall("osp:Simulators/osp:Simulator", NS):
        if s.get("stepSize") not in (None, text("BaseStepSize", None)):
            raise ValueError(f"{path}: simulator {s.get('name')} has its own stepSize: the fmpy loop steps all alike")
        initial = {iv.get("variable"): _value(iv) for iv in s.findall("osp:InitialValues/osp:InitialValue", NS)}
        simulators[s.get("name")] = Simulator(s.get("name"), (path.parent / s.get("source")).resolve(), initial)
    connections = []
    for c in root.findall("osp:Connections/osp:VariableConnection", NS):
        (a, b) = c.findall("osp:Variable", NS)
        connections.append((a.get("simulator"), a.get("name"), b.get("simulator"), b.get("name")))
    return System(path, float(text("StartTime", "0")), float(text("BaseStepSize", "nan")), simulators, connections)
