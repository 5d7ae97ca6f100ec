"""The settings of a sweep, checked against the FMU, and its points.

Every bad value is refused with a SweepError naming the option, the value
and what is allowed; the grid's parameter values are checked against the
FMU's declared ranges at every point before anything runs.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from .errors import SweepError
from .expr import Expression
from .fmu import FmuInfo

CONTINUATION = ("none", "up", "down", "both")


@dataclass(frozen=True)
class Axis:
    name: str
    start: float
    stop: float
    points: int

    def values(self) -> np.ndarray:
        return np.linspace(self.start, self.stop, self.points)


@dataclass(frozen=True)
class Point:
    """One grid point: its index in the grid, the chain it belongs to
    (direction and number; none for independent points) and every
    parameter value set on the FMU."""
    index: int
    values: dict
    period: float


@dataclass
class SweepSpec:
    info: FmuInfo
    axes: list[Axis]
    sets: list[tuple[str, Expression]]
    discard: float
    record: int
    samples_per_period: int
    forcing: str
    output: str
    rate: str | None
    continuation: str = "none"
    period_tol: float = 1e-4
    max_period: int = 16
    points: list[Point] = field(default_factory=list)

    # ------------------------------------------------------------ identity
    def settings(self) -> dict:
        """What fixes the results (not how they are computed): written to
        DIR/sweep.json and the table's metadata, compared on resume."""
        return {
            "fmu": self.info.model_name, "guid": self.info.guid,
            "param": [{"name": a.name, "from": a.start, "to": a.stop, "points": a.points} for a in self.axes],
            "set": [f"{n}={e.text}" for n, e in self.sets],
            "discard_periods": self.discard, "record_periods": self.record,
            "samples_per_period": self.samples_per_period, "forcing": self.forcing,
            "output": self.output, "rate": self.rate, "continuation": self.continuation,
            "period_tol": self.period_tol, "max_period": self.max_period,
        }

    # -------------------------------------------------------------- chains
    def chains(self) -> list[tuple[str, int, list[int]]]:
        """(direction, chain number, point indices in order): one chain per
        value of the second axis and direction; 'up' runs the first axis's
        values in increasing order."""
        if self.continuation == "none":
            return []
        n1 = self.axes[0].points
        n2 = self.axes[1].points if len(self.axes) > 1 else 1
        v1 = self.axes[0].values()
        order = list(np.argsort(v1, kind="stable"))
        dirs = ["up", "down"] if self.continuation == "both" else [self.continuation]
        out = []
        for d in dirs:
            seq = order if d == "up" else order[::-1]
            for j in range(n2):
                out.append((d, j, [int(i) + n1 * j for i in seq]))
        return out


def parse_axis(text: str, info: FmuInfo) -> Axis:
    field_ = f"--param {text}"
    m = re.fullmatch(r"\s*([^=\s]+)\s*=(.+)", text)
    if not m:
        raise SweepError(f"{field_}: expected NAME=FROM:TO:POINTS (e.g. d=0:1.8:181)")
    name, rng = m.group(1), m.group(2)
    info.parameter(name, "--param")
    parts = rng.split(":")
    if len(parts) != 3:
        raise SweepError(f"{field_}: '{rng}' is not FROM:TO:POINTS (three fields separated by ':', e.g. 0:1.8:181)")
    from .expr import number
    start, stop = number(parts[0], f"{field_} FROM"), number(parts[1], f"{field_} TO")
    try:
        points = int(parts[2])
    except ValueError:
        raise SweepError(f"{field_}: POINTS = '{parts[2]}' is not a whole number (allowed: 1 or more)") from None
    if points < 1:
        raise SweepError(f"{field_}: POINTS = {points}; allowed: 1 or more")
    if points == 1 and start != stop:
        raise SweepError(f"{field_}: POINTS = 1 needs FROM = TO (got {start!r} and {stop!r})")
    return Axis(name, start, stop, points)


def parse_set(text: str, info: FmuInfo) -> tuple[str, Expression]:
    m = re.fullmatch(r"\s*([^=\s]+)\s*=(.+)", text)
    if not m:
        raise SweepError(f"--set {text}: expected NAME=VALUE (VALUE a number or an expression such as 0.7*pi**2)")
    name = m.group(1)
    info.parameter(name, "--set")
    return name, Expression(m.group(2), f"--set {name}", set(info.parameters))


def build(info: FmuInfo, params: list[str], sets: list[str], discard: float, record: int,
          samples_per_period: int = 16, forcing: str | None = None, output: str | None = None,
          rate: str | None = None, continuation: str = "none", period_tol: float = 1e-4,
          max_period: int = 16) -> SweepSpec:
    if not params:
        raise SweepError("--param: at least one NAME=FROM:TO:POINTS is needed")
    if len(params) > 2:
        raise SweepError(f"--param: at most two parameters (a grid over one or two), got {len(params)}")
    axes = [parse_axis(p, info) for p in params]
    if len(axes) == 2 and axes[0].name == axes[1].name:
        raise SweepError(f"--param: '{axes[0].name}' is swept twice")
    set_list = [parse_set(s, info) for s in sets]
    swept = {a.name for a in axes}
    for name, _ in set_list:
        if name in swept:
            raise SweepError(f"--set {name}: '{name}' is also swept by --param")
    names = [n for n, _ in set_list]
    for name in names:
        if names.count(name) > 1:
            raise SweepError(f"--set {name}: set twice")
    if not (math.isfinite(discard) and discard >= 0):
        raise SweepError(f"--discard: {discard!r} periods; allowed: a finite number >= 0")
    if record < 3:
        raise SweepError(f"--record: {record} periods; allowed: 3 or more (the period test needs repeats)")
    if samples_per_period < 1:
        raise SweepError(f"--samples-per-period: {samples_per_period}; allowed: 1 or more")
    if continuation not in CONTINUATION:
        raise SweepError(f"--continuation: '{continuation}'; allowed: {', '.join(CONTINUATION)}")
    if not (0 < period_tol < 1):
        raise SweepError(f"--period-tol: {period_tol!r}; allowed: between 0 and 1 (relative to the signal's range)")
    if max_period < 1:
        raise SweepError(f"--max-period: {max_period}; allowed: 1 or more")
    forcing = forcing or info.forcing
    if forcing is None:
        raise SweepError(f"--forcing: {info.model_name} has no harmonic load; name the parameter that holds the "
                         f"forcing frequency (rad per time unit) with --forcing; parameters: {', '.join(info.parameters)}")
    info.parameter(forcing, "--forcing")
    output = output or info.default_output
    if output is None:
        raise SweepError(f"--output: {info.model_name} has no Real output")
    info.output(output, "--output")
    if rate is None and output == info.default_output:
        rate = info.default_rate
    if rate is not None and rate != "none":
        info.output(rate, "--rate")
    else:
        rate = None
    spec = SweepSpec(info, axes, set_list, float(discard), int(record), int(samples_per_period), forcing, output, rate,
                     continuation, float(period_tol), int(max_period))
    if continuation != "none":
        first = info.parameters[axes[0].name]
        if not first.tunable:
            tunable = [n for n, p in info.parameters.items() if p.tunable]
            raise SweepError(f"--continuation: the continued parameter is the first --param, '{first.name}', "
                             f"which is fixed (set before initialisation only); continuation needs a tunable one: "
                             f"{', '.join(tunable)} (a fixed parameter can be the second --param)")
        for name, e in set_list:
            if not info.parameters[name].tunable and _depends_on(name, e, set_list, first.name):
                raise SweepError(f"--set {name}={e.text}: follows the continued parameter '{first.name}' but "
                                 f"'{name}' is fixed; with --continuation only tunable parameters can change along a chain")
    spec.points = _points(spec)
    return spec


def _depends_on(name, e, set_list, target, depth=0) -> bool:
    if target in e.names:
        return True
    if depth > len(set_list):
        return False
    return any(_depends_on(n, x, set_list, target, depth + 1) for n, x in set_list if n in e.names and n != name)


def _points(spec: SweepSpec) -> list[Point]:
    info = spec.info
    grids = [a.values() for a in spec.axes]
    n1 = len(grids[0])
    n2 = len(grids[1]) if len(grids) > 1 else 1
    points = []
    for j in range(n2):
        for i in range(n1):
            values = {spec.axes[0].name: float(grids[0][i])}
            if n2 > 1 or len(grids) > 1:
                values[spec.axes[1].name] = float(grids[1][j])
            env = {n: p.start for n, p in info.parameters.items()}
            env.update(values)
            for name, e in spec.sets:
                env[name] = values[name] = e.value(env)
            for name, v in values.items():
                where = ", ".join(f"{a.name} = {env[a.name]!r}" for a in spec.axes)
                info.parameters[name].check(v, f"point {i + n1 * j} ({where})")
            omega = env[spec.forcing]
            if not omega > 0:
                raise SweepError(f"--forcing: {spec.forcing} = {omega!r} at point {i + n1 * j}; the forcing "
                                 f"frequency must be > 0 to define the period 2 pi / {spec.forcing}")
            points.append(Point(i + n1 * j, values, 2 * math.pi / omega))
    return points
