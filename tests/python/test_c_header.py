"""The C interface: the cbindgen headers agree with the standard
fmi2Functions.h and fmi3Functions.h (gcc -std=c99 -Wall -Werror), every
standard function of both links against the cdylib with its standard type,
and the shared objects export the fmi2 and fmi3 functions and nothing else."""

import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest

from conftest import C_TESTS, FMPY_C_CODE, HEADER_PATH, ROOT, SO_PATH, Instance, model_description, vr

C_FILE = C_TESTS / "check_header.c"
C3_FILE = C_TESTS / "check_header3.c"
HEADER3_PATH = HEADER_PATH.parent / "beamstop_fmi3.h"
FMU3_PATH = ROOT / "target" / "fmu3" / "PinnedBeamStop.fmu"


def standard_functions(version: int = 2) -> set[str]:
    """The functions fmi<v>Functions.h declares (FMI<v>_Export fmi<v>XTYPE fmi<v>X;)."""
    text = (FMPY_C_CODE / f"fmi{version}Functions.h").read_text()
    names = re.findall(rf"FMI{version}_Export\s+(fmi{version}\w+)TYPE\s+(fmi{version}\w+)\s*;", text)
    assert names, f"could not parse fmi{version}Functions.h"
    assert all(t == n for t, n in names)
    return {n for _, n in names}


def test_standard_header_declares_the_44_functions():
    assert len(standard_functions()) == 44


def test_standard_header_declares_the_75_fmi3_functions():
    assert len(standard_functions(3)) == 75


@pytest.mark.parametrize("version", [2, 3])
def test_check_file_assigns_every_standard_function(version):
    src = (C_FILE if version == 2 else C3_FILE).read_text()
    for name in standard_functions(version):
        short = name[len(f"fmi{version}"):]
        assert re.search(rf"\b{name}TYPE\s*\*\s*p_{short}\s*=\s*{name}\s*;", src), name


@pytest.mark.parametrize("version", [2, 3])
def test_cbindgen_header_declares_the_same_functions(version):
    text = (HEADER_PATH if version == 2 else HEADER3_PATH).read_text()
    declared = set(re.findall(rf"\b(fmi{version}\w+)\s*\(", text))
    standard = standard_functions(version)
    assert declared == standard, (sorted(declared - standard), sorted(standard - declared))
    assert f'#include "fmi{version}FunctionTypes.h"' in text
    other = 5 - version
    assert f"fmi{other}" not in text, f"the FMI {version}.0 header mentions fmi{other}"


def compile_check(tmp_path_factory, c_file: Path, name: str) -> Path:
    gcc = shutil.which("gcc") or shutil.which("cc")
    if gcc is None:
        pytest.skip("no C compiler")
    assert SO_PATH.is_file(), SO_PATH
    out = tmp_path_factory.mktemp("c") / name
    cmd = [gcc, "-std=c99", "-Wall", "-Wextra", "-Werror",
           f"-I{FMPY_C_CODE}", f"-I{HEADER_PATH.parent}",
           str(c_file), "-o", str(out),
           f"-L{SO_PATH.parent}", "-lbeamstop_fmu", f"-Wl,-rpath,{SO_PATH.parent}"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="module")
def check_binary(tmp_path_factory):
    return compile_check(tmp_path_factory, C_FILE, "check_header")


@pytest.fixture(scope="module")
def check3_binary(tmp_path_factory):
    return compile_check(tmp_path_factory, C3_FILE, "check_header3")


@pytest.fixture(scope="module")
def unzipdir3(tmp_path_factory):
    """The FMI 3.0 PinnedBeamStop.fmu extracted once for the module."""
    assert FMU3_PATH.is_file(), f"{FMU3_PATH} missing: run `cargo run --release -- package --fmi3` first"
    d = tmp_path_factory.mktemp("fmu3")
    with zipfile.ZipFile(FMU3_PATH) as z:
        z.extractall(d)
    return d


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


def test_fmi3_compiles_links_and_runs(check3_binary):
    proc = subprocess.run([str(check3_binary)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = dict(l.split("=", 1) for l in proc.stdout.split())
    assert lines["version"] == "3.0"
    assert int(lines["functions"]) == len(standard_functions(3))


def test_fmi3_c_importer_runs_the_default_scene(check3_binary, unzipdir3, unzipdir):
    """From C through FMI 3.0 (no event mode, no early return) the same
    numbers as through FMI 2.0 from Python; time is the last value reference."""
    from fmpy import read_model_description

    md3 = read_model_description(str(FMU3_PATH))
    vrs3 = {v.name: v.valueReference for v in md3.modelVariables}
    assert vrs3["w_stop"] == vr("w_stop") and vrs3["lambda"] == vr("lambda")
    assert vrs3["time"] == max(vrs3.values())
    proc = subprocess.run([str(check3_binary), str(Path(unzipdir3, "resources")), md3.instantiationToken,
                           str(vrs3["w_stop"]), str(vrs3["lambda"]), str(vrs3["time"])],
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
    assert float(values["time"]) == 1.0


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


@pytest.mark.parametrize("which", ["cdylib", "fmu binary", "fmi3 fmu binary"])
def test_exports_only_fmi2_and_fmi3_functions(which, unzipdir, unzipdir3):
    """Exactly the functions of fmi2Functions.h and of fmi3Functions.h: both
    from the full binary, one standard's from an FMU's (its variant)."""
    path = {"cdylib": SO_PATH,
            "fmu binary": Path(unzipdir, "binaries", "linux64", "PinnedBeamStop.so"),
            "fmi3 fmu binary": Path(unzipdir3, "binaries", "x86_64-linux", "PinnedBeamStop.so")}[which]
    symbols = exported(path)
    others = [(t, s) for t, s in symbols if not (t == "T" and s.startswith(("fmi2", "fmi3")))]
    assert not others, f"symbols other than fmi2*/fmi3* functions exported: {others[:20]}"
    names = {s for _, s in symbols}
    expected = {"cdylib": standard_functions(2) | standard_functions(3),
                "fmu binary": standard_functions(2),
                "fmi3 fmu binary": standard_functions(3)}[which]
    assert names == expected, (sorted(names - expected), sorted(expected - names))
    assert len(symbols) == len(expected), "a symbol is exported twice"


@pytest.mark.parametrize("version", [2, 3])
def test_fmu_binary_is_the_built_cdylib(version, unzipdir, unzipdir3):
    if version == 2:
        so, where = Path(unzipdir, "binaries", "linux64", "PinnedBeamStop.so"), "target/fmu"
    else:
        so, where = Path(unzipdir3, "binaries", "x86_64-linux", "PinnedBeamStop.so"), "target/fmu3"
    # The rigid-stop variant of the FMU binary (tests/python/test_variants.py
    # checks every FMU's).
    variant = ROOT / "target" / "variants" / f"rigid-fmi{version}" / "libbeamstop_fmu.so"
    assert so.read_bytes() == variant.read_bytes(), f"{where} is stale: build the variants and package again"
