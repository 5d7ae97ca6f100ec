"""What a beamstop FMU offers a sweep, read from the FMU file alone: its
parameters with their declared ranges, the forcing frequency, its stops and
the outputs that count their events, and sensible default outputs.

The modelDescription.xml gives names, types, ranges and variability; the
scene the FMU carries (resources/scene.json) says which parameter is a
load's frequency and which outputs belong to which stop (names may be
renamed there, as in PinnedBeamStop).
"""
from __future__ import annotations

import json
import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

from fmpy import read_model_description

from .errors import SweepError


@dataclass(frozen=True)
class Parameter:
    name: str
    min: float
    max: float
    start: float
    tunable: bool
    description: str

    def check(self, value: float, field: str) -> None:
        if not (self.min <= value <= self.max):
            raise SweepError(f"{field}: {self.name} = {value!r} is outside its declared range "
                             f"[{self.min!r}, {self.max!r}]" + (f" ({self.description})" if self.description else ""))


@dataclass(frozen=True)
class Stop:
    """A stop and the names of its outputs (None where the FMU has none)."""
    name: str
    rigid: bool
    counter: str | None        # impacts (rigid) or contacts (compliant), Integer
    sticking: str | None       # Boolean flag, rigid stops
    stuck_time: str | None     # Real: total time held on the stop since the start
    sticks: str | None         # Integer: stick onsets since the start
    w: str | None
    v: str | None


@dataclass
class FmuInfo:
    path: Path
    guid: str
    model_name: str
    model_identifier: str
    generation_tool: str
    parameters: dict[str, Parameter]
    outputs: dict[str, str]               # name -> type (Real, Integer, Boolean)
    value_references: dict[str, int]
    forcing: str | None                   # the first harmonic load's frequency parameter
    stops: list[Stop] = field(default_factory=list)
    default_output: str | None = None
    default_rate: str | None = None

    def parameter(self, name: str, field: str) -> Parameter:
        if name not in self.parameters:
            raise SweepError(f"{field}: '{name}' is not a parameter of {self.model_name}; its parameters are "
                             f"{', '.join(self.parameters)}")
        return self.parameters[name]

    def output(self, name: str, field: str, types=("Real",)) -> str:
        if self.outputs.get(name) not in types:
            allowed = [n for n, t in self.outputs.items() if t in types]
            raise SweepError(f"{field}: '{name}' is not a {'/'.join(types)} output of {self.model_name}; "
                             f"its outputs are {', '.join(allowed)}")
        return name


def _float(text, default):
    try:
        return float(text)
    except (TypeError, ValueError):
        return default


def _scene(path: Path) -> dict:
    try:
        with zipfile.ZipFile(path) as z:
            return json.loads(z.read("resources/scene.json"))
    except (KeyError, ValueError):
        return {}


def read_fmu(path: str | Path) -> FmuInfo:
    path = Path(path)
    if not path.is_file():
        raise SweepError(f"FMU: '{path}' does not exist (build the FMUs with scripts/main: target/fmu/*.fmu)")
    try:
        md = read_model_description(str(path))
    except Exception as err:  # fmpy raises various types for a broken archive
        raise SweepError(f"FMU: '{path}' is not an FMU fmpy can read ({err})") from None
    if md.coSimulation is None:
        raise SweepError(f"FMU: '{path}' has no co-simulation interface")
    params, outputs, refs = {}, {}, {}
    for v in md.modelVariables:
        refs[v.name] = v.valueReference
        if v.causality == "parameter" and v.type == "Real":
            params[v.name] = Parameter(v.name, _float(v.min, -math.inf), _float(v.max, math.inf),
                                       _float(v.start, math.nan), v.variability == "tunable", v.description or "")
        elif v.causality == "output":
            outputs[v.name] = v.type
    info = FmuInfo(path=path, guid=md.guid, model_name=md.modelName, model_identifier=md.coSimulation.modelIdentifier,
                   generation_tool=md.generationTool or "", parameters=params, outputs=outputs,
                   value_references=refs, forcing=None)
    scene = _scene(path)

    def var(element: dict, fieldname: str) -> str:
        names = element.get("names", {})
        return names.get(fieldname, f"{element.get('name')}.{fieldname}")

    for load in scene.get("loads", []):
        name = var(load, "omega")
        if name in params:
            info.forcing = name
            break
    single = len(scene.get("stops", [])) == 1

    def present(element, fieldname):
        for candidate in (var(element, fieldname), fieldname if single else None):
            if candidate and candidate in outputs:
                return candidate
        return None

    for stop in scene.get("stops", []):
        rigid = stop.get("law", {}).get("type") == "restitution"
        info.stops.append(Stop(stop.get("name"), rigid, present(stop, "impacts" if rigid else "contacts"),
                               present(stop, "sticking"), present(stop, "stuck_time"), present(stop, "sticks"),
                               present(stop, "w"), present(stop, "v")))
    if not scene.get("stops") and "stop.contacts" in outputs:    # a rotating scene's surface
        info.stops.append(Stop("stop", False, "stop.contacts", None, None, None, None, None))
    # the default output: the first stop's displacement, else a sensor's, else the first Real output
    first = info.stops[0] if info.stops else None
    if first is not None and first.w and first.v:
        info.default_output, info.default_rate = first.w, first.v
    else:
        for name, kind in outputs.items():
            if kind == "Real" and name.endswith(".w") and name[:-2] + ".v" in outputs:
                info.default_output, info.default_rate = name, name[:-2] + ".v"
                break
    if info.default_output is None:
        info.default_output = next((n for n, t in outputs.items() if t == "Real"), None)
    return info
