"""The Python side of beamstop, driving its FMUs through fmpy:

- `beamstop_tools.report`: the reports of scripts/report (report/);
- `beamstop_tools.sweep`: parameter sweeps on Dask (scripts/sweep,
  scripts/sweep-figures);
- `beamstop_tools.coupling`: the controller-coupling example (scripts/coupling).

and `beamstop_tools.engine`, the one gateway to the engine they all use:
the project's root, its Rust programs and its FMUs.

Installed editable into the project's venv by scripts/venv.sh, or as a
package (`pip install ./python`: the console scripts beamstop-sweep,
beamstop-orbits and beamstop-report). `ROOT` is the project it works on: its
FMUs (target/fmu), scenes and report/; found by `engine.find_root()`
($BEAMSTOP_ROOT, the working directory or one above it, the editable
checkout), else the working directory.
"""
from pathlib import Path

from .engine import find_root

ROOT = find_root(required=False) or Path.cwd()
