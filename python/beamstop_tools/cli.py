"""The console scripts of `pip install ./python` (python/pyproject.toml):

  beamstop-sweep [--root DIR] FMU --param ...      = scripts/sweep (beamstop_tools.sweep)
  beamstop-orbits [--root DIR] SCENE.json ...      = scripts/orbits (beamstop_tools.orbits)
  beamstop-report [--root DIR] NAME [ARGS...]      one report of scripts/report (NAME below)

Each works on a beamstop project: --root DIR, else $BEAMSTOP_ROOT, else the
working directory or the first folder above it with Cargo.toml and
scenes/. They run what is built there (target/release, target/fmu): build
it first (scripts/test, scripts/report or `cargo build --release` and
`cargo run --release -- package`). Relative paths in ARGS are the working
directory's.
"""
from __future__ import annotations

import importlib
import os
import sys

from . import engine

#: beamstop-report NAME: the module whose main(argv) it runs.
REPORTS = {
    "generate": "beamstop_tools.report.generate",
    "springstop": "beamstop_tools.report.springstop",
    "hertz": "beamstop_tools.report.hertz",
    "rotating_peers": "beamstop_tools.report.rotating_peers",
    "rotating_plots": "beamstop_tools.report.rotating_plots",
    "rigid_peer": "beamstop_tools.report.rigid_peer",
    "rigid_limit": "beamstop_tools.report.rigid_limit",
    "scaling": "beamstop_tools.report.scaling",
    "s3_cold": "beamstop_tools.report.s3_cold",
    "binaries": "beamstop_tools.report.binaries",
    "sweeps": "beamstop_tools.sweep.figures",
    "coupling": "beamstop_tools.coupling.pd_slew",
}


def _take_root(argv: list[str], prog: str) -> list[str]:
    """Removes --root DIR (or --root=DIR) from argv, exports it as
    $BEAMSTOP_ROOT and points beamstop_tools.ROOT at the project found.
    Without a project only --help may go on."""
    rest, i = [], 0
    while i < len(argv):
        a = argv[i]
        if a == "--root" and i + 1 < len(argv):
            os.environ[engine.ROOT_VARIABLE] = os.path.abspath(argv[i + 1])
            i += 2
            continue
        if a.startswith("--root="):
            os.environ[engine.ROOT_VARIABLE] = os.path.abspath(a.split("=", 1)[1])
        else:
            rest.append(a)
        i += 1
    import beamstop_tools

    try:
        beamstop_tools.ROOT = engine.find_root()
    except engine.RootNotFound as err:
        if not any(a in ("-h", "--help") for a in rest):
            sys.exit(f"{prog}: {err}")
    return rest


def _run(module: str, argv: list[str]) -> int:
    result = importlib.import_module(module).main(argv)
    return result if isinstance(result, int) else 0


def sweep(argv: list[str] | None = None) -> int:
    return _run("beamstop_tools.sweep.cli", _take_root(sys.argv[1:] if argv is None else argv, "beamstop-sweep"))


def orbits(argv: list[str] | None = None) -> int:
    return _run("beamstop_tools.orbits", _take_root(sys.argv[1:] if argv is None else argv, "beamstop-orbits"))


def report(argv: list[str] | None = None) -> int:
    argv = _take_root(sys.argv[1:] if argv is None else argv, "beamstop-report")
    if not argv or argv[0] not in REPORTS:
        usage = (f"usage: beamstop-report [--root DIR] NAME [ARGS...] (NAME --help for its own)\n"
                 f"NAME: {', '.join(REPORTS)}")
        if argv and argv[0] in ("-h", "--help"):
            print(__doc__ + "\n" + usage)
            return 0
        print(usage, file=sys.stderr)
        return 2
    return _run(REPORTS[argv[0]], argv[1:])
