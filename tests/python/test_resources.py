"""fmuResourceLocation: every common spelling of a local file URI works,
also for a directory whose name needs percent-encoding; URIs that do not
point at the resources fail cleanly (NULL and a logged reason)."""

import shutil
from pathlib import Path
from urllib.parse import quote

import pytest

from conftest import Instance, model_description


def reference_outputs(unzipdir):
    inst = Instance(unzipdir, name="ref")
    try:
        inst.initialize()
        inst.step_to(1.0, 0.1)
        return inst.outputs()
    finally:
        inst.free()


def spellings(resources: Path):
    p = resources.resolve().as_posix()
    return {
        "file:///abs": "file://" + quote(p),
        "file:///abs/": "file://" + quote(p) + "/",
        "file:/abs": "file:" + quote(p),
        "file://localhost/abs": "file://localhost" + quote(p),
        "Path.as_uri": resources.resolve().as_uri(),
    }


def check_instantiates(unzipdir, uri, expected):
    so = Path(unzipdir, "binaries", "linux64", model_description().coSimulation.modelIdentifier + ".so")
    inst = Instance(unzipdir, name="res", resource_location=uri, library_path=str(so))
    try:
        assert not inst.log.errors(), inst.log.text()
        inst.initialize()
        inst.step_to(1.0, 0.1)
        assert inst.outputs() == expected
    finally:
        inst.free()


@pytest.mark.parametrize("form", ["file:///abs", "file:///abs/", "file:/abs", "file://localhost/abs", "Path.as_uri"])
def test_uri_forms(unzipdir, form):
    uri = spellings(Path(unzipdir, "resources"))[form]
    check_instantiates(unzipdir, uri, reference_outputs(unzipdir))


@pytest.fixture(scope="module")
def spaced_copy(unzipdir, tmp_path_factory):
    base = tmp_path_factory.mktemp("res") / "my fmu dir" / "Pinned Beam Stop"
    shutil.copytree(unzipdir, base)
    return base


@pytest.mark.parametrize("form", ["file:///abs", "file:///abs/", "file:/abs", "file://localhost/abs", "Path.as_uri"])
def test_percent_encoded_directory_with_space(unzipdir, spaced_copy, form):
    uri = spellings(spaced_copy / "resources")[form]
    assert "%20" in uri and " " not in uri
    check_instantiates(spaced_copy, uri, reference_outputs(unzipdir))


@pytest.mark.parametrize("uri_of", [
    lambda r: "file:///nonexistent/beamstop/resources",
    lambda r: "file://some-server" + r.as_posix(),
    lambda r: "http://localhost" + r.as_posix(),
    lambda r: "file://" + quote((r.parent / "no_such_dir").as_posix()),
    lambda r: "file:///a%2",
], ids=["missing dir", "remote host", "not a file URI", "missing subdir", "bad escape"])
def test_bad_resource_locations_fail_cleanly(unzipdir, uri_of):
    uri = uri_of(Path(unzipdir, "resources").resolve())
    with pytest.raises(RuntimeError, match="NULL") as info:
        Instance(unzipdir, name="bad_res", resource_location=uri)
    assert "fmi2Instantiate" in str(info.value), str(info.value)
