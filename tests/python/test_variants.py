"""Each FMU carries only what its scene needs (issue 45).

Every packaged FMU (FMI 2.0 in target/fmu, 3.0 in target/fmu3) holds the
prebuilt variant `beamstop describe --contents` names for its scene
(scripts/build-variants, target/variants/<name>): byte for byte its
stripped binary. The variant's unstripped build has no symbol of a kind,
contact law, solver or FMI standard the variant does not carry, and
exports exactly its standard's entry points. And the lean FMU computes
what the full binary (every kind, law and standard: target/release) does,
bit for bit: outputs on the grids of the experiment's step, ten times it
and the whole horizon, and the event log, through both standards.
"""
from __future__ import annotations

import hashlib
import json
import re
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from conftest import ROOT, SO_PATH

BEAMSTOP = ROOT / "target" / "release" / "beamstop"
VARIANTS = ROOT / "target" / "variants"
FMU_DIRS = {"fmi2": ROOT / "target" / "fmu", "fmi3": ROOT / "target" / "fmu3"}
SCENES = sorted((ROOT / "scenes").glob("*.json"))

# What each part's code is called in the symbols (demangled Rust paths).
PARTS = {
    ("kinds", "modal"): "beamstop::kinds::modal::",
    ("kinds", "rotating"): "beamstop::kinds::rotating::",
    ("contact laws", "restitution"): "beamstop::contact::restitution::",
    ("contact laws", "spring_dashpot"): "beamstop::contact::spring_dashpot::",
    ("contact laws", "hertz"): "beamstop::contact::hertz::",
    ("contact laws", "power_law"): "beamstop::contact::power_law::",
    ("solvers", "collocation"): "beamstop_numerics::solve::collocation::",
    ("solvers", "dop853"): "beamstop_numerics::solve::dop853::",
    ("solvers", "radau"): "beamstop_numerics::solve::radau::",
    ("solvers", "exponential"): "beamstop_numerics::solve::exponential::",
    ("FMI standard", "2.0"): "beamstop::fmi2::api::",
    ("FMI standard", "3.0"): "beamstop::fmi3::api::",
}


def test_every_part_is_named_as_the_full_binary_names_it():
    """The symbol test below only proves an absence: each part's prefix must
    name code in the full binary, or a renamed module would pass it."""
    symbols = subprocess.run(["nm", "-C", "--defined-only", str(SO_PATH)], check=True, capture_output=True, text=True).stdout
    missing = [f"{part} {name}: {prefix}" for (part, name), prefix in PARTS.items() if prefix not in symbols]
    assert not missing, f"no symbol of the full binary {SO_PATH} starts so: {missing}"


def contents(scene: Path, standard: str) -> dict[str, list[str]]:
    args = [str(BEAMSTOP), "describe"] + (["--fmi3"] if standard == "fmi3" else []) + ["--contents", str(scene)]
    out = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    return {k: [x.strip() for x in v.split(",")] for k, v in (line.split(": ", 1) for line in out.splitlines())}


def carried(c: dict[str, list[str]]) -> set[tuple[str, str]]:
    """The (part, name) keys of PARTS the contents say the binary carries."""
    have = {("kinds", k) for k in c["kinds"]} | {("contact laws", law) for law in c["contact laws"]}
    have |= {("FMI standard", s) for s in c["FMI standard"]}
    solvers = " ".join(c["solvers"])
    if "collocation" in solvers:
        have.add(("solvers", "collocation"))
    if "DOP853" in solvers:
        have |= {("solvers", "dop853"), ("solvers", "radau"), ("solvers", "exponential")}
    return have


def scene_name(scene: Path) -> str:
    return json.loads(scene.read_text())["name"]


def binary_in(fmu: Path) -> bytes:
    with zipfile.ZipFile(fmu) as z:
        (name,) = [n for n in z.namelist() if n.startswith("binaries/")]
        return z.read(name)


@pytest.mark.parametrize("standard", ["fmi2", "fmi3"])
@pytest.mark.parametrize("scene", SCENES, ids=lambda p: p.stem)
def test_the_fmu_packs_its_variant_which_carries_nothing_its_scene_does_not_use(scene, standard):
    c = contents(scene, standard)
    build = VARIANTS / f"{c['variant'][0]}-{standard}"
    fmu = FMU_DIRS[standard] / f"{scene_name(scene)}.fmu"
    assert binary_in(fmu) == (build / "libbeamstop_fmu.so").read_bytes()
    assert json.loads((build / "manifest.json").read_text())["variant"] == build.name
    unstripped = build / "libbeamstop_fmu.unstripped.so"
    symbols = subprocess.run(["nm", "-C", "--defined-only", str(unstripped)], check=True, capture_output=True, text=True).stdout
    # Identical functions are folded into one under several names (serde's
    # field visitors of every law, say): code belongs to a part only when
    # every name at its address is that part's. Drop glue is named after
    # the first type it was made for but is the same code for any type of
    # the same shape (a `RefCell` borrow's release, say): not a part's code.
    at: dict[str, list[str]] = {}
    for line in symbols.splitlines():
        address, _, name = line.split(" ", 2)
        if not name.startswith("core::ptr::drop_in_place<"):
            at.setdefault(address, []).append(name)
    have = carried(c)
    for key, prefix in PARTS.items():
        if key not in have:
            found = [names[0] for names in at.values() if all(prefix in n for n in names)]
            assert not found, f"{build.name} carries {key} (not in its contents {c}): {found[:3]}"
    # The kind's own code is there, and the exports are exactly the standard's.
    assert any(PARTS[("kinds", k)] in symbols for k in c["kinds"])
    exported = subprocess.run(["nm", "-D", "--defined-only", str(build / "libbeamstop_fmu.so")], check=True, capture_output=True, text=True).stdout
    names = set(re.findall(r"\b(fmi[23]\w+)", exported))
    own, other = ("fmi2", "fmi3") if standard == "fmi2" else ("fmi3", "fmi2")
    assert f"{own}Instantiate" in names or f"{own}InstantiateCoSimulation" in names
    assert not [n for n in names if n.startswith(other)], names


def test_a_scene_the_binary_was_not_built_for_is_refused_naming_what_is_missing(tmp_path):
    """The rigid-stop binary (PinnedBeamStop.fmu's) given the Hertz scene
    (HertzStop.fmu unzipped, its binary replaced): the GUID matches the
    scene, and fmi2Instantiate returns NULL with an error that names the
    law the binary lacks and the laws it has."""
    from conftest import Instance

    unzipped = tmp_path / "HertzStop"
    with zipfile.ZipFile(FMU_DIRS["fmi2"] / "HertzStop.fmu") as z:
        z.extractall(unzipped)
    (binary,) = (unzipped / "binaries").glob("*/*.so")
    binary.write_bytes(binary_in(FMU_DIRS["fmi2"] / "PinnedBeamStop.fmu"))
    guid = read_model_description(str(unzipped)).guid
    with pytest.raises(RuntimeError) as refused:
        Instance(unzipped, guid=guid, library_path=str(binary))
    message = str(refused.value)
    assert 'stops[0].law.type = "hertz"' in message and "built without the hertz law (it has: restitution)" in message, message


def test_a_scene_of_a_kind_the_binary_lacks_is_refused_naming_the_kind(tmp_path):
    """The rotating beam's binary given the pinned beam's scene."""
    from conftest import Instance

    unzipped = tmp_path / "PinnedBeamStop"
    with zipfile.ZipFile(FMU_DIRS["fmi2"] / "PinnedBeamStop.fmu") as z:
        z.extractall(unzipped)
    (binary,) = (unzipped / "binaries").glob("*/*.so")
    binary.write_bytes(binary_in(FMU_DIRS["fmi2"] / "RotatingBeamImpact.fmu"))
    with pytest.raises(RuntimeError) as refused:
        Instance(unzipped, library_path=str(binary))
    message = str(refused.value)
    assert "a modal scene (it has the key 'structure'), and this binary was built without the modal kind (it has: rotating)" in message, message


def lean_and_full(fmu: Path, tmp: Path) -> Path:
    """A copy of `fmu` with the full binary in place of its variant."""
    full = tmp / fmu.name
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(full, "w", zipfile.ZIP_DEFLATED) as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename.startswith("binaries/"):
                data = SO_PATH.read_bytes()
            dst.writestr(item, data)
    return full


def run_digest(fmu: Path, interval: float, stop: float, standard: str) -> tuple[str, int]:
    log = []

    def logger(*args):
        # FMI 2.0: (env, instance, status, category, message); 3.0: (env, status, category, message).
        log.append(b"|".join(a if isinstance(a, bytes) else str(a).encode() for a in args[-3:]))

    extra = {"early_return_allowed": True, "use_event_mode": True} if standard == "fmi3" else {}
    result = simulate_fmu(str(fmu), stop_time=stop, output_interval=interval, debug_logging=True, logger=logger,
                          **extra)
    h = hashlib.sha256(np.ascontiguousarray(result).tobytes())
    for line in log:
        h.update(line)
    return h.hexdigest(), len(log)


@pytest.mark.parametrize("standard", ["fmi2", "fmi3"])
@pytest.mark.parametrize("scene", SCENES, ids=lambda p: p.stem)
def test_the_lean_fmu_computes_what_the_full_binary_does_bit_for_bit(scene, standard, tmp_path):
    fmu = FMU_DIRS[standard] / f"{scene_name(scene)}.fmu"
    full = lean_and_full(fmu, tmp_path)
    experiment = read_model_description(str(fmu)).defaultExperiment
    stop, step = float(experiment.stopTime), float(experiment.stepSize)
    for interval in (step, 10 * step, stop):
        lean_digest, n_log = run_digest(fmu, interval, stop, standard)
        full_digest, _ = run_digest(full, interval, stop, standard)
        assert lean_digest == full_digest, f"{fmu.name} at output interval {interval}"
        assert n_log > 0
