"""Binary size, load time and first step of the FMUs.

`python -m beamstop_tools.report.binaries [--set LABEL=DIR[,DIR...]]... [--repeats 5] [--quick] [--out DIR]`
writes report/binaries/summary.md and report/binaries/binaries.csv (and
prints the Markdown). For every FMU of each set (a folder of .fmu files, or
several: FMI 2.0 and FMI 3.0 ones are told apart by their
modelDescription.xml; default one set, `after` = target/fmu and target/fmu3
of the project):

- the bytes of its shared object (binaries/linux64/ID.so for FMI 2.0,
  binaries/x86_64-linux/ID.so for FMI 3.0, uncompressed) and of the .fmu;
- load: dlopen of the .so (ctypes, RTLD_NOW) and the instantiation call,
  fmi2Instantiate (fmi2CoSimulation, the GUID, the file URI of the
  extracted resources/ folder, logging off) or fmi3InstantiateCoSimulation
  (the instantiationToken, the resources/ path with a trailing slash,
  logging, eventModeUsed and earlyReturnAllowed off), under one
  time.perf_counter pair;
- first step: after fmi2SetupExperiment (FMI 2.0) and entering and leaving
  initialisation mode, the wall time of the first doStep from the default
  experiment's start time (0 if none) over its stepSize (initialisation is
  not included).

Each FMU is extracted once (not timed); each measurement is a fresh Python
process (this module's --worker, ctypes only, nothing but the FMU loaded
in it), repeated --repeats times (default 5), the minimum reported; the
repeats go round all FMUs of all sets in turn, so a change in the
machine's load hits every set alike. The .so is in the page cache (the
process is cold, not the disk). With two or more sets, a ratio table:
.so bytes and load time of each set over `before` (else the first set).
`--quick`: 1 repeat of 2 FMUs per set (one of each folder in turn), to
target/report-quick/binaries/.

    --set before=/tmp/fmu-before/fmu2,/tmp/fmu-before/fmu3 --set after=target/fmu,target/fmu3
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from .. import ROOT
from .common import QUICK_NOTE, log, md_table, out_dir, write_csv

REPEATS = 5
QUICK_FMUS = 2
WORKER_TIMEOUT_S = 300
MARK = "BINARIES-RESULT "
SO_DIR = {2: "binaries/linux64", 3: "binaries/x86_64-linux"}
STANDARD = {2: "FMI 2.0", 3: "FMI 3.0"}
COLUMNS = ["set", "standard", "fmu", "so_bytes", "fmu_bytes", "load_ms", "first_step_ms",
           "so_compressed_bytes", "so_path", "start_time", "step_size", "init_ms", "repeats",
           "load_ms_all", "first_step_ms_all", "error"]


# ---------------------------------------------------------------- the worker (a fresh process per measurement)

def _worker(spec: dict) -> dict:
    """One cold measurement in this process: dlopen + instantiate, then
    initialisation (not timed) and the first doStep (timed). Only ctypes:
    nothing else is loaded before the FMU."""
    import ctypes
    from ctypes import POINTER, byref, c_bool, c_char_p, c_double, c_int, c_size_t, c_uint32, c_void_p

    std, so = spec["standard"], spec["so"]
    start, h = float(spec["start"]), float(spec["step"])
    name = b"binaries"
    token = spec["token"].encode()
    messages = []
    out = {}

    def check(what, status, ok=(0, 1)):
        if status not in ok:
            raise RuntimeError(f"{what} returned status {status}" + (f": {messages[-3:]}" if messages else ""))

    if std == 2:
        LOGGER = ctypes.CFUNCTYPE(None, c_void_p, c_char_p, c_int, c_char_p, c_char_p)
        ALLOC = ctypes.CFUNCTYPE(c_void_p, c_size_t, c_size_t)
        FREE = ctypes.CFUNCTYPE(None, c_void_p)

        class Callbacks(ctypes.Structure):
            _fields_ = [("logger", LOGGER), ("allocateMemory", ALLOC), ("freeMemory", FREE),
                        ("stepFinished", c_void_p), ("componentEnvironment", c_void_p)]

        def logger(env, instance, status, category, message):
            messages.append(f"[{status}] {(category or b'').decode(errors='replace')}: "
                            f"{(message or b'').decode(errors='replace')}")

        libc = ctypes.CDLL(None)
        callbacks = Callbacks(LOGGER(logger), ALLOC(ctypes.cast(libc.calloc, c_void_p).value),
                              FREE(ctypes.cast(libc.free, c_void_p).value), None, None)
        resources = Path(spec["resources"]).as_uri().encode()

        t0 = time.perf_counter()
        lib = ctypes.CDLL(so)
        instantiate = lib.fmi2Instantiate
        instantiate.restype = c_void_p
        instantiate.argtypes = [c_char_p, c_int, c_char_p, c_char_p, POINTER(Callbacks), c_int, c_int]
        comp = instantiate(name, 1, token, resources, byref(callbacks), 0, 0)  # 1: fmi2CoSimulation
        t1 = time.perf_counter()
        if not comp:
            raise RuntimeError(f"fmi2Instantiate returned NULL: {messages[-3:]}")
        c = c_void_p(comp)
        for fn, args in (("fmi2SetupExperiment", [c_void_p, c_int, c_double, c_double, c_int, c_double]),
                         ("fmi2EnterInitializationMode", [c_void_p]), ("fmi2ExitInitializationMode", [c_void_p]),
                         ("fmi2DoStep", [c_void_p, c_double, c_double, c_int]),
                         ("fmi2Terminate", [c_void_p])):
            getattr(lib, fn).argtypes, getattr(lib, fn).restype = args, c_int
        lib.fmi2FreeInstance.argtypes, lib.fmi2FreeInstance.restype = [c_void_p], None
        t2 = time.perf_counter()
        check("fmi2SetupExperiment", lib.fmi2SetupExperiment(c, 0, 0.0, start, 0, 0.0))
        check("fmi2EnterInitializationMode", lib.fmi2EnterInitializationMode(c))
        check("fmi2ExitInitializationMode", lib.fmi2ExitInitializationMode(c))
        t3 = time.perf_counter()
        status = lib.fmi2DoStep(c, start, h, 1)
        t4 = time.perf_counter()
        check("fmi2DoStep", status)
        lib.fmi2Terminate(c)
        lib.fmi2FreeInstance(c)
    else:
        LOG = ctypes.CFUNCTYPE(None, c_void_p, c_int, c_char_p, c_char_p)

        def log_message(env, status, category, message):
            messages.append(f"[{status}] {(category or b'').decode(errors='replace')}: "
                            f"{(message or b'').decode(errors='replace')}")

        log_cb = LOG(log_message)
        resources = (str(Path(spec["resources"])) + os.sep).encode()

        t0 = time.perf_counter()
        lib = ctypes.CDLL(so)
        instantiate = lib.fmi3InstantiateCoSimulation
        instantiate.restype = c_void_p
        instantiate.argtypes = [c_char_p, c_char_p, c_char_p, c_bool, c_bool, c_bool, c_bool,
                                POINTER(c_uint32), c_size_t, c_void_p, LOG, c_void_p]
        comp = instantiate(name, token, resources, False, False, False, False, None, 0, None, log_cb, None)
        t1 = time.perf_counter()
        if not comp:
            raise RuntimeError(f"fmi3InstantiateCoSimulation returned NULL: {messages[-3:]}")
        c = c_void_p(comp)
        for fn, args in (("fmi3EnterInitializationMode", [c_void_p, c_bool, c_double, c_double, c_bool, c_double]),
                         ("fmi3ExitInitializationMode", [c_void_p]),
                         ("fmi3DoStep", [c_void_p, c_double, c_double, c_bool, POINTER(c_bool), POINTER(c_bool),
                                         POINTER(c_bool), POINTER(c_double)]),
                         ("fmi3Terminate", [c_void_p])):
            getattr(lib, fn).argtypes, getattr(lib, fn).restype = args, c_int
        lib.fmi3FreeInstance.argtypes, lib.fmi3FreeInstance.restype = [c_void_p], None
        event, terminate, early, last = c_bool(), c_bool(), c_bool(), c_double()
        t2 = time.perf_counter()
        check("fmi3EnterInitializationMode", lib.fmi3EnterInitializationMode(c, False, 0.0, start, False, 0.0))
        check("fmi3ExitInitializationMode", lib.fmi3ExitInitializationMode(c))
        t3 = time.perf_counter()
        status = lib.fmi3DoStep(c, start, h, True, byref(event), byref(terminate), byref(early), byref(last))
        t4 = time.perf_counter()
        check("fmi3DoStep", status)
        if terminate.value or early.value:
            out["note"] = f"terminateSimulation={terminate.value} earlyReturn={early.value} " \
                          f"lastSuccessfulTime={last.value!r}"
        lib.fmi3Terminate(c)
        lib.fmi3FreeInstance(c)
    out.update(load_s=t1 - t0, init_s=t3 - t2, step_s=t4 - t3, status=status)
    return out


def _worker_main(arg: str) -> int:
    try:
        result = _worker(json.loads(arg))
    except Exception as err:  # reported to the parent, which records it
        result = {"error": f"{type(err).__name__}: {err}"}
    print(MARK + json.dumps(result), flush=True)
    return 0


# ---------------------------------------------------------------- the FMUs and their measurements

@dataclass
class Entry:
    set: str
    standard: int
    fmu: Path
    model: str
    token: str
    so_member: str
    so_bytes: int
    so_compressed: int
    fmu_bytes: int
    start: float
    step: float
    step_note: str = ""
    dir: Path | None = None
    load: list = field(default_factory=list)
    init: list = field(default_factory=list)
    first: list = field(default_factory=list)
    errors: list = field(default_factory=list)

    @property
    def key(self):
        return self.standard, self.fmu.name


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def read_fmu(label: str, path: Path) -> Entry:
    """Sizes and what the worker needs, from the archive (not extracted)."""
    with zipfile.ZipFile(path) as z:
        md = ET.fromstring(z.read("modelDescription.xml"))
        version = md.get("fmiVersion", "")
        if version.startswith("2."):
            std, token = 2, md.get("guid")
        elif version.startswith("3."):
            std, token = 3, md.get("instantiationToken")
        else:
            raise ValueError(f"{path}: fmiVersion {version!r} is neither 2.0 nor 3.0")
        cs = next((e for e in md if _local(e.tag) == "CoSimulation"), None)
        if cs is None:
            raise ValueError(f"{path}: no CoSimulation")
        model = cs.get("modelIdentifier")
        infos = {i.filename: i for i in z.infolist()}
        member = f"{SO_DIR[std]}/{model}.so"
        if member not in infos:
            found = sorted(n for n in infos if n.startswith(SO_DIR[std] + "/") and n.endswith(".so"))
            if not found:
                raise ValueError(f"{path}: no {member}")
            member = found[0]
        de = next((e for e in md if _local(e.tag) == "DefaultExperiment"), None)
        de = de.attrib if de is not None else {}
        start = float(de.get("startTime", 0.0))
        note = ""
        if "stepSize" in de:
            step = float(de["stepSize"])
        else:  # as fmpy: 1/500 of the default experiment (stopTime 1 when none)
            step = (float(de.get("stopTime", start + 1.0)) - start) / 500
            note = "no DefaultExperiment stepSize: (stopTime - startTime) / 500"
    return Entry(label, std, path, model, token, member, infos[member].file_size, infos[member].compress_size,
                 path.stat().st_size, start, step, note)


def parse_set(text: str) -> tuple[str, list[Path]]:
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"--set {text!r}: expected LABEL=DIR[,DIR...]")
    label, dirs = text.split("=", 1)
    paths = [Path(d).expanduser() for d in dirs.split(",") if d]
    if not label or not paths:
        raise argparse.ArgumentTypeError(f"--set {text!r}: expected LABEL=DIR[,DIR...]")
    return label, paths


def collect(label: str, dirs: list[Path], quick: bool) -> list[Entry]:
    per_dir = []
    for d in dirs:
        if d.is_file() and d.suffix == ".fmu":
            per_dir.append([d])
        elif d.is_dir():
            fmus = sorted(d.glob("*.fmu"))
            if not fmus:
                raise SystemExit(f"--set {label}: no .fmu in {d}")
            per_dir.append(fmus)
        else:
            raise SystemExit(f"--set {label}: {d} is neither a folder nor an .fmu (target/fmu: "
                             "`cargo run --release -- package`, target/fmu3: `... package --fmi3`)")
    if quick:  # one of each folder in turn: both standards with the default sets
        chosen, i = [], 0
        while len(chosen) < QUICK_FMUS and any(i < len(f) for f in per_dir):
            chosen += [f[i] for f in per_dir if i < len(f)]
            i += 1
        paths = chosen[:QUICK_FMUS]
    else:
        paths = [p for f in per_dir for p in f]
    return [read_fmu(label, p) for p in paths]


def measure(e: Entry) -> None:
    spec = {"standard": e.standard, "so": str(e.dir / e.so_member), "token": e.token,
            "resources": str(e.dir / "resources"), "start": e.start, "step": e.step}
    cmd = [sys.executable, "-m", "beamstop_tools.report.binaries", "--worker", json.dumps(spec)]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=WORKER_TIMEOUT_S, cwd=e.dir)
    except subprocess.TimeoutExpired:
        e.errors.append(f"worker timed out after {WORKER_TIMEOUT_S} s")
        return
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith(MARK)]
    if p.returncode or not lines:
        tail = (p.stderr or p.stdout).strip().splitlines()[-3:]
        e.errors.append(f"worker exit {p.returncode}: {' / '.join(tail)}")
        return
    r = json.loads(lines[-1][len(MARK):])
    if "error" in r:
        e.errors.append(r["error"])
        return
    if r.get("note"):
        e.errors.append(r["note"])
    e.load.append(r["load_s"])
    e.init.append(r["init_s"])
    e.first.append(r["step_s"])


# ---------------------------------------------------------------- the tables

def ms(values, d=3):
    return f"{1e3 * min(values):.{d}f}" if values else "failed"


def nbytes(n: int) -> str:
    return f"{n:,}"


def ratio(a, b, d=3):
    return f"{a / b:.{d}f}" if a is not None and b else "-"


def system_line() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} logical CPUs, Linux {platform.release()}, Python {platform.python_version()}"


def load_average() -> str:
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "-"


def tables(entries: list[Entry], labels: list[str]) -> list[str]:
    lines = ["## Per FMU", "",
             "Load: dlopen + instantiate; first step: the first doStep over one default step; "
             "both the minimum over the repeats, in fresh processes.", ""]
    rows = [[e.set, STANDARD[e.standard], e.fmu.stem, nbytes(e.so_bytes), nbytes(e.fmu_bytes),
             ms(e.load, 2), ms(e.first, 4)] for e in entries]
    lines += [md_table(["set", "standard", "FMU", ".so bytes", ".fmu bytes", "load ms", "first step ms"], rows), ""]

    lines += ["## Per set and standard", ""]
    rows = []
    for label in labels:
        for std in (2, 3):
            es = [e for e in entries if e.set == label and e.standard == std]
            if not es:
                continue
            big = max(es, key=lambda e: e.so_bytes)
            loads = [min(e.load) for e in es if e.load]
            rows.append([label, STANDARD[std], len(es), f"{nbytes(big.so_bytes)} ({big.fmu.stem})",
                         nbytes(sum(e.fmu_bytes for e in es)),
                         f"{1e3 * min(loads):.2f} .. {1e3 * max(loads):.2f}" if loads else "failed"])
    lines += [md_table(["set", "standard", "FMUs", "largest .so bytes", "total .fmu bytes", "load ms (range)"],
                       rows), ""]

    if len(labels) >= 2:
        base = "before" if "before" in labels else labels[0]
        by = {(e.set, *e.key): e for e in entries}
        for other in (x for x in labels if x != base):
            lines += [f"## {other} / {base}", "",
                      f".so bytes and load time of `{other}` over `{base}`, FMU by FMU (same standard and file name).",
                      ""]
            rows = []
            for e in (e for e in entries if e.set == other):
                b = by.get((base, *e.key))
                if b is None:
                    rows.append([STANDARD[e.standard], e.fmu.stem, f"not in {base}", "-", "-"])
                    continue
                la = min(e.load) if e.load else None
                lb = min(b.load) if b.load else None
                rows.append([STANDARD[e.standard], e.fmu.stem, ratio(e.so_bytes, b.so_bytes),
                             ratio(la, lb, 2), ratio(min(e.first) if e.first else None,
                                                     min(b.first) if b.first else None, 2)])
            lines += [md_table(["standard", "FMU", ".so bytes ratio", "load ratio", "first step ratio"], rows), ""]
            for std in (2, 3):
                a_ = [e for e in entries if e.set == other and e.standard == std]
                b_ = [e for e in entries if e.set == base and e.standard == std]
                if a_ and b_:
                    lines.append(f"- {STANDARD[std]}: total .fmu bytes {other}/{base} "
                                 f"{ratio(sum(e.fmu_bytes for e in a_), sum(e.fmu_bytes for e in b_))}, "
                                 f"largest .so {ratio(max(e.so_bytes for e in a_), max(e.so_bytes for e in b_))}")
            lines.append("")
    failed = [e for e in entries if e.errors]
    if failed:
        lines += ["## Failures and notes", ""]
        lines += [f"- {e.set} {STANDARD[e.standard]} {e.fmu.stem}: {'; '.join(sorted(set(e.errors)))}"
                  for e in failed]
        lines.append("")
    return lines


def csv_rows(entries: list[Entry]) -> list[dict]:
    return [{"set": e.set, "standard": STANDARD[e.standard], "fmu": e.fmu.stem, "so_bytes": e.so_bytes,
             "fmu_bytes": e.fmu_bytes, "load_ms": 1e3 * min(e.load) if e.load else None,
             "first_step_ms": 1e3 * min(e.first) if e.first else None, "so_compressed_bytes": e.so_compressed,
             "so_path": e.so_member, "start_time": e.start, "step_size": e.step,
             "init_ms": 1e3 * min(e.init) if e.init else None, "repeats": len(e.load),
             "load_ms_all": [1e3 * x for x in e.load], "first_step_ms_all": [1e3 * x for x in e.first],
             "error": "; ".join(sorted(set(e.errors + ([e.step_note] if e.step_note else []))))}
            for e in entries]


# ---------------------------------------------------------------- main

def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["--worker"]:
        return _worker_main(argv[1])
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--set", dest="sets", action="append", type=parse_set, metavar="LABEL=DIR[,DIR...]",
                    help="a labelled set of FMU folders (repeatable; default after=target/fmu,target/fmu3)")
    ap.add_argument("--repeats", type=int, help=f"fresh processes per FMU (default {REPEATS}, 1 with --quick)")
    ap.add_argument("--quick", action="store_true",
                    help=f"1 repeat of {QUICK_FMUS} FMUs per set, to target/report-quick/binaries")
    ap.add_argument("--out", type=Path, help="output folder (default report/binaries)")
    args = ap.parse_args(argv)
    sets = args.sets or [("after", [ROOT / "target" / "fmu", ROOT / "target" / "fmu3"])]
    labels = [label for label, _ in sets]
    if len(set(labels)) != len(labels):
        ap.error("--set: each label once")
    repeats = args.repeats or (1 if args.quick else REPEATS)
    out = out_dir(args.out, "binaries", args.quick)

    started = time.perf_counter()
    load_before = load_average()
    entries = [e for label, dirs in sets for e in collect(label, dirs, args.quick)]
    with tempfile.TemporaryDirectory(prefix="beamstop-binaries-") as tmp:
        for i, e in enumerate(entries):  # extracted once per FMU, not timed
            e.dir = Path(tmp) / f"{i:03d}-{e.fmu.stem}"
            with zipfile.ZipFile(e.fmu) as z:
                z.extractall(e.dir)
        for rep in range(repeats):  # every FMU once per round: the machine's drift hits all alike
            for e in entries:
                measure(e)
                got = f"load {1e3 * e.load[-1]:.2f} ms, first step {1e3 * e.first[-1]:.3f} ms" \
                    if len(e.load) > rep else f"FAILED: {e.errors[-1]}"
                log(f"[{rep + 1}/{repeats}] {e.set} {STANDARD[e.standard]} {e.fmu.stem}: {got}")
    elapsed = time.perf_counter() - started

    command = "python -m beamstop_tools.report.binaries" + (" " + shlex.join(argv) if argv else "")
    lines = ["# Binary size, load time and first step of the FMUs", ""]
    if args.quick:
        lines += [QUICK_NOTE.rstrip(), ""]
    lines += [f"Generated by `{command}` on {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC in {elapsed:.1f} s "
              f"({len(entries)} FMUs, {repeats} fresh process{'es' if repeats > 1 else ''} each); {system_line()}; "
              f"load average {load_before} before, {load_average()} after.", "",
              "Sizes: the shared object uncompressed (as extracted) and the .fmu archive. Load: "
              "`ctypes.CDLL` (dlopen, RTLD_NOW) of the extracted .so and the instantiation call "
              "(fmi2Instantiate as co-simulation with the GUID and the file URI of resources/, logging off; "
              "fmi3InstantiateCoSimulation with the instantiationToken, the resources/ path with a trailing "
              "slash, eventModeUsed and earlyReturnAllowed false), one `time.perf_counter` pair. First step: "
              "after fmi2SetupExperiment (FMI 2.0) and entering and leaving initialisation mode (not timed), "
              "the first doStep from the default experiment's start over its stepSize. Each measurement in a "
              "fresh Python process that loads nothing but the FMU (the .so in the page cache: cold process, "
              "warm disk); the minimum over the repeats, taken round all FMUs in turn.", "",
              "Sets:", ""]
    lines += [f"- `{label}`: " + ", ".join(f"`{d}`" for d in dirs) for label, dirs in sets]
    lines += [""] + tables(entries, labels)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "binaries.csv", COLUMNS, csv_rows(entries))
    (out / "summary.md").write_text("\n".join(lines))
    print("\n".join(lines))
    print(f"wrote {out / 'summary.md'} and {out / 'binaries.csv'}; {elapsed:.1f} s")
    return 1 if any(not e.load for e in entries) else 0


if __name__ == "__main__":
    sys.exit(main())
