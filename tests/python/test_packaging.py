"""`pip install ./python` (non-editable) into a fresh venv: the package's
metadata declares every third-party module it imports, pinned as in
requirements.txt, and its console scripts (beamstop-sweep, beamstop-orbits,
beamstop-report) run from a folder outside the checkout, finding the
project by --root or $BEAMSTOP_ROOT.

Offline and quick: the wheel is built from a copy of python/ with the
pinned setuptools of the test venv, installed with --no-deps into a venv
made without pip (the test venv's pip installs it there), and the
dependencies the scripts need at run time are the test venv's, put after
the fresh venv's own site-packages by a .pth line (the editable install
there is not activated by it: the fresh venv's beamstop_tools is the
wheel's, which the test checks)."""
from __future__ import annotations

import ast
import importlib.metadata as md
import os
import re
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from conftest import ROOT

SCRIPTS = ("beamstop-sweep", "beamstop-orbits", "beamstop-report")


def canonical(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def pins() -> dict[str, str]:
    out = {}
    for line in (ROOT / "requirements.txt").read_text().splitlines():
        line = line.split("#")[0].strip()
        if "==" in line:
            name, version = line.split("==")
            out[canonical(name)] = version.strip()
    return out


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    """A venv with the wheel of python/ installed and nothing else of its own."""
    tmp = tmp_path_factory.mktemp("packaging")
    src = tmp / "src"
    shutil.copytree(ROOT / "python", src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "--quiet"]
    subprocess.run(pip + ["wheel", "--no-deps", "--no-build-isolation", "-w", str(tmp / "dist"), str(src)],
                   check=True, cwd=tmp)
    wheel = next((tmp / "dist").glob("beamstop_tools-*.whl"))
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    subprocess.run(pip + ["--python", str(python), "install", "--no-deps", str(wheel)], check=True, cwd=tmp)
    site = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    (site / "zz_test_venv.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return venv, site


def test_metadata_declares_every_import(fresh):
    venv, site = fresh
    python = venv / "bin" / "python"
    meta = subprocess.run([str(python), "-c", "import importlib.metadata as m, json; "
                           "print(json.dumps([m.requires('beamstop-tools'), m.version('beamstop-tools')]))"],
                          capture_output=True, text=True, check=True)
    import json
    requires, _ = json.loads(meta.stdout)
    runtime, test_extra = {}, {}
    for req in requires:
        m = re.match(r"([A-Za-z0-9_.-]+)\s*==\s*([^;\s]+)\s*(;.*)?$", req)
        assert m, f"not pinned with ==: {req}"
        (test_extra if m.group(3) and "extra" in m.group(3) else runtime)[canonical(m.group(1))] = m.group(2)
    assert {"pytest", "pytest-xdist"} <= set(test_extra)
    pinned = pins()
    for name, version in {**runtime, **test_extra}.items():
        assert pinned.get(name) == version, f"{name}=={version} in pyproject.toml, requirements.txt: {pinned.get(name)}"

    # every third-party module the installed package imports, and the distribution that brings it
    package = site / "beamstop_tools"
    modules = set()
    for path in package.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                modules |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                modules.add(node.module.split(".")[0])
    third_party = {m for m in modules if m not in sys.stdlib_module_names and m != "beamstop_tools"}
    assert {"fmpy", "numpy", "scipy"} <= third_party
    provided = md.packages_distributions()
    missing = {}
    for module in sorted(third_party):
        dists = {canonical(d) for d in provided.get(module, [])}
        assert dists, f"beamstop_tools imports {module}, which no installed distribution provides"
        if not dists & set(runtime):
            missing[module] = sorted(dists)
    assert not missing, f"imported but not in [project] dependencies: {missing}"


def test_console_scripts_outside_the_checkout(fresh, tmp_path):
    venv, site = fresh
    env = {k: v for k, v in os.environ.items() if k not in ("BEAMSTOP_ROOT", "VIRTUAL_ENV", "PYTHONPATH")}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    run = lambda *cmd, **kw: subprocess.run(cmd, cwd=tmp_path, env={**env, **kw.pop("extra", {})},
                                            capture_output=True, text=True, timeout=120)
    where = run(str(venv / "bin" / "python"), "-c", "import beamstop_tools; print(beamstop_tools.__file__)")
    assert where.stdout.strip().startswith(str(site)), where

    for script in SCRIPTS:
        assert (venv / "bin" / script).exists()
        p = run(script, "--help")
        assert p.returncode == 0, p.stderr
        assert "usage" in p.stdout.lower()
    p = run("beamstop-report", "generate")
    assert p.returncode != 0 and "BEAMSTOP_ROOT" in p.stderr, p

    # real runs, the project given by the environment and by --root: the
    # rigid-peer figure from the tracked CSVs, and a run of beamstop itself
    if not (ROOT / "target" / "release" / "beamstop").exists():
        pytest.skip("target/release/beamstop not built")
    p = run("beamstop-report", "rigid_peer", "--out", "rigid_peer", extra={"BEAMSTOP_ROOT": str(ROOT)})
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "rigid_peer" / "summary.md").exists()
    p = run("beamstop-report", "--root", str(ROOT), "rigid_limit", "--quick", "--out", "limit")
    assert p.returncode == 0, p.stderr
    assert "rigid limit" in (tmp_path / "limit" / "rigid_limit.md").read_text()
