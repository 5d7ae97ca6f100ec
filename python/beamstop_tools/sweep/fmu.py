"""What a beamstop FMU offers a sweep, read from its modelDescription.xml
alone (fmpy.read_model_description): its parameters with their declared
ranges, the forcing frequency, its stops and the outputs that count their
events, and sensible default outputs.

Names, types, ranges, variability and value references are the declared
variables'. Which variable belongs to which scene element is read from the
descriptions the FMU gives its variables, which name the element: a load's
frequency is "Circular frequency of the load 'NAME'", every output of a stop
mentions "stop 'NAME'" (src/interface.rs writes them). No naming rule is
applied here, so renamed variables (PinnedBeamStop's w_stop, impacts, ...)
are found like the default `stop.w`, `stop.impacts`.
"""
from __future__ import annotations

import math
import re
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


# What an output of a stop is, from its type and the start of its description
# (the element's name quoted in it): field -> (type, description start).
STOP_FIELDS = {
    "w": ("Real", "Displacement at stop"),
    "v": ("Real", "Velocity at stop"),
    "impacts": ("Integer", "Number of impacts"),
    "contacts": ("Integer", "Number of contact onsets"),
    "sticking": ("Boolean", "Whether the structure is stuck"),
    "sticks": ("Integer", "Number of times the structure stuck"),
    "stuck_time": ("Real", "Total time the structure has been stuck"),
}
STOP_OF = re.compile(r"\bstop '([^']*)'")
LOAD_FREQUENCY = re.compile(r"^Circular frequency of the load '([^']*)'")
SENSOR_OUTPUT = re.compile(r"^(Displacement|Velocity) at sensor '([^']*)'")
SURFACE = "surface"  # a rotating scene's contact surface: its outputs name no stop


def _stop_field(v) -> str | None:
    description = v.description or ""
    return next((f for f, (kind, start) in STOP_FIELDS.items()
                 if v.type == kind and description.startswith(start)), None)


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
    # the forcing: the first harmonic load's frequency parameter
    info.forcing = next((v.name for v in md.modelVariables if v.name in params
                         and LOAD_FREQUENCY.match(v.description or "")), None)
    # the stops, in the order their outputs are declared, and their outputs by field
    fields: dict[str, dict[str, str]] = {}
    for v in md.modelVariables:
        if v.causality != "output":
            continue
        field_ = _stop_field(v)
        if field_ is None:
            continue
        m = STOP_OF.search(v.description or "")
        fields.setdefault(m.group(1) if m else SURFACE, {}).setdefault(field_, v.name)
    for name, f in fields.items():
        rigid = "impacts" in f
        info.stops.append(Stop(name, rigid, f.get("impacts" if rigid else "contacts"), f.get("sticking"),
                               f.get("stuck_time"), f.get("sticks"), f.get("w"), f.get("v")))
    # the default output: the first stop's displacement, else a sensor's, else the first Real output
    sensors: dict[str, dict[str, str]] = {}
    for v in md.modelVariables:
        m = SENSOR_OUTPUT.match(v.description or "") if v.causality == "output" and v.type == "Real" else None
        if m:
            sensors.setdefault(m.group(2), {}).setdefault(m.group(1), v.name)
    pairs = [(s.w, s.v) for s in info.stops] + [(f.get("Displacement"), f.get("Velocity")) for f in sensors.values()]
    info.default_output, info.default_rate = next(((w, v) for w, v in pairs if w and v), (None, None))
    if info.default_output is None:
        info.default_output = next((n for n, t in outputs.items() if t == "Real"), None)
    return info
