"""The C interface: the cbindgen header agrees with the standard
fmi2Functions.h (gcc -std=c99 -Wall -Werror), every standard function links
against the cdylib with its standard type, and the shared objects export the
fmi2 functions and nothing else."""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import C_TESTS, FMPY_C_CODE, HEADER_PATH, SO_PATH, Instance, model_description, vr

C_FILE = C_TESTS / "check_header.c"


def standard_functions() -> set[str]:
    """The functions fmi2Functions.h declares (FMI2_Export fmi2XTYPE fmi2X;)."""
    text = (FMPY_C_CODE / "fmi2Functions.h").read_text()
    names = re.findall(r"FMI2_Export\s+(fmi2\w+)TYPE\s+(fmi2\w+)\s*;", text)
    assert names, "could not parse fmi2Functions.h"
    assert all(t == n for t, n in names)
    return {n for _, n in names}


def test_standard_header_declares_the_44_functions():
    assert len(standard_functions()) == 44


def test_check_file_assigns_every_standard_function():
    src = C_FILE.read_text()
    for name in standard_functions():
        short = name[len("fmi2"):]
        assert re.search(rf"\b{name}TYPE\s*\*\s*p_{short}\s*=\s*{name}\s*;", src), name


def test_cbindgen_header_declares_the_same_functions():
    text = HEADER_PATH.read_text()
    declared = set(re.findall(r"\b(fmi2\w+)\s*\(", text))
    assert declared == standard_functions(), (sorted(declared - standard_functions()),
                                              sorted(standard_functions() - declared))
    assert '#include "fmi2FunctionTypes.h"' in text


@pytest.fixture(scope="module")
def check_binary(tmp_path_factory):
    gcc = shutil.which("gcc") or shutil.which("cc")
    if gcc is None:
        pytest.skip("no C compiler")
    assert SO_PATH.is_file(), SO_PATH
    out = tmp_path_factory.mktemp("c") / "check_header"
    cmd = [gcc, "-std=c99", "-Wall", "-Wextra", "-Werror",
           f"-I{FMPY_C_CODE}", f"-I{HEADER_PATH.parent}",
           str(C_FILE), "-o", str(out),
           f"-L{SO_PATH.parent}", "-lbeamstop_fmu", f"-Wl,-rpath,{SO_PATH.parent}"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return out


def test_compiles_links_and_runs(check_binary):
    proc = subprocess.run([str(check_binary)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = dict(l.split("=", 1) for l in proc.stdout.split())
    assert lines["version"] == "2.0"
    assert lines["typesPlatform"] == "default"
    assert int(lines["functions"]) == len(standard_functions())


def test_c_importer_runs_the_default_scene(check_binary, unzipdir):
    """The same numbers from C as from Python through fmpy."""
    uri = Path(unzipdir, "resources").as_uri()
    proc = subprocess.run([str(check_binary), uri, model_description().guid, str(vr("w_stop")), str(vr("lambda"))],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    values = dict(l.split("=", 1) for l in proc.stdout.split())
    inst = Instance(unzipdir, library_path=str(SO_PATH))
    try:
        inst.initialize()
        for k in range(1, 11):
            inst.advance_to(k * 0.1)
        assert float(values["w_stop"]) == inst.get("w_stop")
        assert float(values["lambda"]) == inst.get("lambda")
    finally:
        inst.free()
    assert float(values["w_stop"]) <= 1e-12
    assert float(values["lambda"]) < 0.0


def exported(path: Path):
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("nm not available")
    proc = subprocess.run([nm, "-D", "--defined-only", str(path)], capture_output=True, text=True, check=True)
    out = []
    for line in proc.stdout.splitlines():
        parts = line.split()
        if len(parts) >= 2:
            out.append((parts[-2], parts[-1]))
    return out


@pytest.mark.parametrize("which", ["cdylib", "fmu binary"])
def test_exports_only_fmi2_functions(which, unzipdir):
    path = SO_PATH if which == "cdylib" else Path(unzipdir, "binaries", "linux64", "PinnedBeamStop.so")
    symbols = exported(path)
    others = [(t, s) for t, s in symbols if not (t == "T" and s.startswith("fmi2"))]
    assert not others, f"symbols other than fmi2* functions exported: {others[:20]}"
    assert {s for _, s in symbols} == standard_functions()


def test_fmu_binary_is_the_built_cdylib(unzipdir):
    packaged = Path(unzipdir, "binaries", "linux64", "PinnedBeamStop.so").read_bytes()
    assert packaged == SO_PATH.read_bytes(), "target/fmu is stale: package again after building"
