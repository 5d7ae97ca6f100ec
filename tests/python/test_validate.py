"""The FMU archive and its modelDescription.xml: fmpy's validator, the FMI
2.0 XSD, the exact variable list with its causalities, and the GUID check
of fmi2Instantiate."""

import math
import zipfile

import pytest
from lxml import etree

from fmpy.validation import validate_fmu

from conftest import (
    EXPECTED_VARIABLES,
    FMPY_SCHEMA_FMI2,
    FMU_PATH,
    Instance,
    model_description,
    variables,
)


def test_fmpy_validate_fmu_reports_no_problems():
    problems = validate_fmu(str(FMU_PATH))
    assert problems == [], "\n".join(problems)


def test_archive_layout():
    with zipfile.ZipFile(FMU_PATH) as z:
        names = set(z.namelist())
        assert z.testzip() is None
    for required in ("modelDescription.xml", "binaries/linux64/PinnedBeamStop.so", "resources/scene.json"):
        assert required in names, sorted(names)
    assert not any("\\" in n for n in names)


def test_model_description_validates_against_fmi2_xsd():
    schema = etree.XMLSchema(etree.parse(str(FMPY_SCHEMA_FMI2 / "fmi2ModelDescription.xsd")))
    with zipfile.ZipFile(FMU_PATH) as z:
        doc = etree.fromstring(z.read("modelDescription.xml"))
    ok = schema.validate(doc)
    assert ok, "\n".join(str(e) for e in schema.error_log)
    assert doc.get("fmiVersion") == "2.0"
    assert doc.find("CoSimulation").get("modelIdentifier") == "PinnedBeamStop"
    assert doc.find("ModelExchange") is None


def test_variable_names_are_exactly_the_interface():
    names = [v.name for v in model_description().modelVariables]
    assert len(names) == len(set(names)), "duplicate variable names"
    assert set(names) == EXPECTED_VARIABLES, (
        f"missing {sorted(EXPECTED_VARIABLES - set(names))}, extra {sorted(set(names) - EXPECTED_VARIABLES)}"
    )
    for ty in ("Real", "Integer", "Boolean"):
        refs = [v.valueReference for v in model_description().modelVariables if v.type == ty]
        assert len(refs) == len(set(refs)), f"two {ty} variables share a value reference"


TUNABLE = {"F", "omega", "R", "eps"}
FIXED = {"zeta", "d", "x_stop", "x_force", *(f"q0[{j}]" for j in range(1, 5)), *(f"qd0[{j}]" for j in range(1, 5))}


def test_causality_variability_and_types():
    v = variables()
    for n in TUNABLE:
        assert (v[n].causality, v[n].variability, v[n].type) == ("parameter", "tunable", "Real"), n
    for n in FIXED:
        assert (v[n].causality, v[n].variability, v[n].type) == ("parameter", "fixed", "Real"), n
    assert (v["force"].causality, v["force"].type) == ("input", "Real")
    for n in EXPECTED_VARIABLES - TUNABLE - FIXED - {"force"}:
        assert v[n].causality == "output", n
    assert v["impacts"].type == v["sticks"].type == "Integer"
    assert v["sticking"].type == "Boolean"
    for n in ("w_stop", "v_stop", "t_last_impact", "stuck_time", "lambda", "energy"):
        assert v[n].type == "Real", n


def test_start_values_are_the_papers_scene():
    v = variables()
    expected = {
        "F": 76.8, "omega": 0.1 * math.pi ** 2, "zeta": 0.05, "R": 0.7, "eps": 1e-6,
        "d": 0.0, "x_stop": 0.4, "force": 0.0,
        **{f"q0[{j}]": 0.0 for j in range(1, 5)}, **{f"qd0[{j}]": 0.0 for j in range(1, 5)},
    }
    for n, x in expected.items():
        assert math.isclose(float(v[n].start), x, rel_tol=1e-15, abs_tol=0.0), (n, v[n].start, x)
    x_force = float(v["x_force"].start)
    assert 0.0 <= x_force <= 1.0


def test_capabilities():
    cs = model_description().coSimulation
    assert cs.canGetAndSetFMUstate
    assert cs.canSerializeFMUstate
    assert cs.canHandleVariableCommunicationStepSize
    ex = model_description().defaultExperiment
    assert ex is not None and ex.stopTime is not None and ex.stepSize is not None


def test_guid_in_xml_is_the_one_the_binary_checks(unzipdir):
    guid = model_description().guid
    # The right GUID instantiates ...
    ok = Instance(unzipdir, name="right_guid")
    ok.free()
    # ... a wrong one is rejected (NULL), with a message naming the expected GUID.
    wrong = "{00000000-0000-0000-0000-000000000000}"
    assert wrong != guid
    with pytest.raises(RuntimeError) as info:
        Instance(unzipdir, name="wrong_guid", guid=wrong)
    text = str(info.value)
    assert guid in text, text
    assert wrong in text, text


def test_guid_rejected_through_plain_fmpy(unzipdir):
    """fmpy's own instantiate() raises on a wrong GUID."""
    from fmpy.fmi2 import FMU2Slave

    md = model_description()
    slave = FMU2Slave(guid="{not-the-guid}", unzipDirectory=str(unzipdir),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="x")
    try:
        with pytest.raises(Exception, match="Failed to instantiate"):
            slave.instantiate()
    finally:
        slave.freeLibrary()
