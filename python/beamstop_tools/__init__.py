"""The Python side of beamstop, driving its FMUs through fmpy:

- `beamstop_tools.report`: the reports of scripts/report (report/);
- `beamstop_tools.sweep`: parameter sweeps on Dask (scripts/sweep,
  scripts/sweep-figures);
- `beamstop_tools.coupling`: the controller-coupling example (scripts/coupling).

Installed editable into the project's venv by scripts/venv.sh
(`pip install -e python`). `ROOT` is the repository this package lives in:
its FMUs (target/fmu), scenes and report/.
"""
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
