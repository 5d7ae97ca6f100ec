"""The one way Python reaches beamstop's engine: where the project is, its
Rust programs (the `beamstop` binary and the examples, through cargo) and
its FMUs (an FMI 2.0 session through fmpy).

- `find_root()`: the project (a folder with Cargo.toml and scenes/): the
  BEAMSTOP_ROOT environment variable (the console scripts' --root sets it),
  else the working directory or a folder above it, else the checkout this
  package is installed editable from.
- `beamstop(args)`: target/release/beamstop (or $BEAMSTOP_BIN) in the root.
- `example(name, args)`: examples/NAME.rs, built by cargo once per process,
  then run from target/release/examples; `cargo_run(target, args)`:
  `cargo run --release --quiet TARGET -- ARGS` in the root (the coupling
  example's controller FMU).
- `Fmu(path)` / `Session(fmu, name)`: an FMU extracted and read once, and
  instances of it: instantiate (with an optional logger), start (setup,
  initialisation with parameter values), step, read by name, close.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT_VARIABLE = "BEAMSTOP_ROOT"


class RootNotFound(RuntimeError):
    pass


def is_root(path: Path) -> bool:
    return (path / "Cargo.toml").is_file() and (path / "scenes").is_dir()


def find_root(required: bool = True) -> Path | None:
    """The project: $BEAMSTOP_ROOT, else the working directory or the first
    folder above it with Cargo.toml and scenes/, else the checkout of an
    editable install. None (or RootNotFound when `required`) if none."""
    given = os.environ.get(ROOT_VARIABLE)
    if given:
        path = Path(given).expanduser().resolve()
        if not is_root(path):
            raise RootNotFound(f"{ROOT_VARIABLE}={given}: no Cargo.toml and scenes/ there")
        return path
    cwd = Path.cwd().resolve()
    for path in (cwd, *cwd.parents, Path(__file__).resolve().parents[2]):
        if is_root(path):
            return path
    if required:
        raise RootNotFound(f"no beamstop project found: give --root DIR or {ROOT_VARIABLE}=DIR, or run inside "
                           "a checkout (a folder with Cargo.toml and scenes/)")
    return None


def root() -> Path:
    from . import ROOT
    return ROOT


# ---------------------------------------------------------------- the Rust programs

def binary() -> Path:
    """The beamstop executable: $BEAMSTOP_BIN, else target/release/beamstop."""
    return Path(os.environ.get("BEAMSTOP_BIN") or root() / "target" / "release" / "beamstop")


def _run(cmd, *, tee=False, capture=False, stdout=None, check=True, echo=False, timeout=None):
    """Runs `cmd` in the root. `tee`: stdout captured and echoed; `capture`:
    stdout and stderr captured, silently; `echo`: the command printed first.
    A failure raises CalledProcessError when `check`."""
    if echo:
        print("$ " + " ".join(map(str, cmd)), flush=True)
    if capture:
        p = subprocess.run(cmd, cwd=root(), capture_output=True, text=True, timeout=timeout)
    else:
        p = subprocess.run(cmd, cwd=root(), stdout=subprocess.PIPE if tee else stdout, text=True, timeout=timeout)
    if tee:
        sys.stdout.write(p.stdout)
        sys.stdout.flush()
    if check and p.returncode != 0:
        raise subprocess.CalledProcessError(p.returncode, cmd, p.stdout, p.stderr)
    return p


def beamstop(args, exe=None, **kw) -> subprocess.CompletedProcess:
    """`beamstop ARGS`, the executable as built (scripts/* build it), or
    `exe`; keywords as `_run`'s, output captured by default, not checked."""
    exe = Path(exe) if exe else binary()
    if not exe.exists():
        raise FileNotFoundError(f"{exe} is missing: cargo build --release first")
    kw.setdefault("capture", True)
    kw.setdefault("check", False)
    return _run([str(exe), *map(str, args)], **kw)


def cargo_run(target, args=(), **kw) -> subprocess.CompletedProcess:
    """`cargo run --release --quiet TARGET... -- ARGS` in the root (built
    first if out of date); keywords as `_run`'s."""
    return _run([_cargo(), "run", "--release", "--quiet", *target, "--", *map(str, args)], **kw)


_BUILT: set = set()


def example(name: str, args=(), **kw) -> subprocess.CompletedProcess:
    """examples/NAME.rs run with ARGS: built by `cargo build --release
    --example NAME` once per process (a no-op when up to date), then run
    as target/release/examples/NAME; keywords as `_run`'s."""
    if name not in _BUILT:
        subprocess.run([_cargo(), "build", "--release", "--quiet", "--example", name], cwd=root(), check=True)
        _BUILT.add(name)
    return _run([str(root() / "target" / "release" / "examples" / name), *map(str, args)], **kw)


def _cargo() -> str:
    cargo = shutil.which("cargo")
    if cargo is None:
        raise RuntimeError("cargo not found: beamstop's Rust programs are built and run with cargo")
    return cargo


# ---------------------------------------------------------------- FMUs through fmpy

class Fmu:
    """An FMU (FMI 2.0 co-simulation) read and extracted once: `md` its
    model description, `vars` and `vr` its variables and value references
    by name; `Session(fmu, ...)` makes instances. `path` may be the .fmu or
    a folder it was extracted to."""

    def __init__(self, path, unzipdir=None):
        from fmpy import extract, read_model_description

        self.path = Path(path)
        self.dir = str(self.path) if self.path.is_dir() else extract(str(self.path), unzipdir=unzipdir)
        self.md = read_model_description(self.dir)
        if self.md.coSimulation is None:
            raise ValueError(f"{self.path}: not a co-simulation FMU")
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.vr = {n: v.valueReference for n, v in self.vars.items()}

    def refs(self, names) -> list[int]:
        return [self.vr[n] for n in names]


class Session:
    """One instance of an `Fmu` (fmpy's FMU2Slave, as `slave`, for what is
    not wrapped here). `logger(status, category, message)` receives the
    FMU's messages as text; `categories` are switched on with logging."""

    def __init__(self, fmu: Fmu, name: str = "beamstop", *, logger=None, logging_on=None, categories=None,
                 instantiate=True):
        from fmpy.fmi2 import FMU2Slave

        self.fmu = fmu
        self.slave = FMU2Slave(guid=fmu.md.guid, unzipDirectory=fmu.dir,
                               modelIdentifier=fmu.md.coSimulation.modelIdentifier, instanceName=name)
        self._logger, self._categories = logger, categories
        self._logging_on = bool(logger) if logging_on is None else logging_on
        if instantiate:
            self.instantiate()

    def instantiate(self) -> None:
        kw = {}
        if self._logger is not None:
            from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

            def log(env, instance, status, category, message):
                self._logger(status, (category or b"").decode("utf-8", "replace"),
                             (message or b"").decode("utf-8", "replace"))

            self._callbacks = fmi2CallbackFunctions()
            self._callbacks.logger = self._log_type = fmi2CallbackLoggerTYPE(log)
            kw["callbacks"] = self._callbacks
        self.slave.instantiate(loggingOn=self._logging_on, **kw)
        if self._categories:
            self.slave.setDebugLogging(True, list(self._categories))

    def start(self, values: dict | None = None, t0: float = 0.0) -> "Session":
        """Setup at t0, initialisation with these Real values (by name)."""
        self.slave.setupExperiment(startTime=t0)
        self.slave.enterInitializationMode()
        if values:
            self.set(values)
        self.slave.exitInitializationMode()
        return self

    def set(self, values: dict) -> None:
        names = list(values)
        self.slave.setReal(self.fmu.refs(names), [float(values[n]) for n in names])

    def step(self, t: float, h: float) -> None:
        self.slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)

    def real(self, names) -> list[float]:
        return self.slave.getReal(self.fmu.refs(names))

    def read(self, names) -> list:
        """Values of Real, Integer and Boolean variables by name, in the order given."""
        by_type = {}
        for n in names:
            by_type.setdefault(self.fmu.vars[n].type, []).append(n)
        get = {"Real": self.slave.getReal, "Integer": self.slave.getInteger, "Boolean": self.slave.getBoolean}
        got = {}
        for t, ns in by_type.items():
            got.update(zip(ns, get[t](self.fmu.refs(ns))))
        return [got[n] for n in names]

    def close(self) -> None:
        self.slave.terminate()
        self.slave.freeInstance()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if exc[0] is None:
            self.close()
        else:
            try:
                self.slave.freeInstance()
            except Exception:
                pass
