"""Bad arguments and illegal call sequences: fmi2Error (fmpy raises
FMICallException with status 3), a logged message naming the variable and
the offending value, and an instance that stays usable."""

import ctypes
import math
import re

import pytest

from conftest import (
    FMICallException,
    FREE_VIBRATION,
    fmi2Error,
    unused_value_reference,
    variables,
    vr,
)


def value_pattern(value) -> str:
    """Regex for how a number may be printed after '=' ("1", "1.0", "1e0", "NaN", "inf")."""
    if isinstance(value, float) and math.isnan(value):
        return r"(?i:nan)"
    if isinstance(value, float) and math.isinf(value):
        return ("-" if value < 0 else r"\+?") + r"(?i:inf)(?:inity)?"
    forms = {repr(value), str(value), f"{value:g}", f"{value:e}"}
    if float(value).is_integer():
        forms |= {str(int(value)), f"{int(value)}.0", f"{float(value):.1f}"}
    return "(?:" + "|".join(re.escape(f) for f in sorted(forms, key=len, reverse=True)) + r")(?![0-9.eE])"


def assert_logged(inst, *needles, value=None):
    """An error message was logged that contains every needle and, if given,
    '= <value>' (the offending value)."""
    errors = inst.log.errors()
    assert errors, f"no error message logged; log:\n{inst.log.text()}"
    for m in errors:
        if all(n in m for n in needles) and (value is None or re.search(r"=\s*" + value_pattern(value), m)):
            return m
    raise AssertionError(f"no error message contains {needles} and value {value!r}; errors: {errors}")


def expect_error(call):
    with pytest.raises(FMICallException) as info:
        call()
    assert info.value.status == fmi2Error, info.value
    return info.value


@pytest.fixture
def in_init(make_instance):
    inst = make_instance()
    inst.slave.setupExperiment(startTime=0.0)
    inst.slave.enterInitializationMode()
    inst.time = 0.0
    return inst


@pytest.fixture
def running(make_instance):
    inst = make_instance().initialize()
    inst.step(0.1)
    return inst


def finish_init_and_step(inst):
    inst.slave.exitInitializationMode()
    inst.time = 0.0
    inst.step(0.1)
    inst.step(0.1)
    assert inst.time == pytest.approx(0.2)


BAD_VALUES = [
    ("F", math.nan), ("F", math.inf), ("F", -math.inf), ("omega", math.nan), ("d", math.nan),
    ("q0[1]", math.inf), ("R", 1.5), ("R", -0.1), ("x_stop", 0.0), ("x_stop", 1.0), ("x_stop", 1.2),
    ("zeta", -0.01), ("eps", -1.0), ("omega", -1e-300), ("omega", -1.0), ("x_force", 1.5), ("x_force", -0.1),
]


@pytest.mark.parametrize("name,value", BAD_VALUES, ids=[f"{n}={v}" for n, v in BAD_VALUES])
def test_bad_parameter_value_in_initialization_mode(in_init, name, value):
    inst = in_init
    old = inst.get(name)
    expect_error(lambda: inst.set({name: value}))
    assert_logged(inst, name, value=value)
    assert inst.get(name) == old, "a rejected value must not be applied"
    finish_init_and_step(inst)
    assert inst.get(name) == old


TUNABLE_BAD = [(n, v) for n, v in BAD_VALUES if variables()[n].variability == "tunable"]


@pytest.mark.parametrize("name,value", TUNABLE_BAD, ids=[f"{n}={v}" for n, v in TUNABLE_BAD])
def test_bad_tunable_value_between_steps(running, name, value):
    inst = running
    old = inst.get(name)
    expect_error(lambda: inst.set({name: value}))
    assert_logged(inst, name, value=value)
    assert inst.get(name) == old
    inst.step(0.1)
    assert inst.get(name) == old


def test_bad_value_in_instantiated_state(make_instance):
    """Before initialization mode (fmi2GetReal is not yet allowed there)."""
    inst = make_instance()
    expect_error(lambda: inst.set({"R": 1.5}))
    assert_logged(inst, "R", value=1.5)
    inst.initialize()
    assert inst.get("R") == 0.7
    inst.step(0.1)


@pytest.mark.parametrize("value", [math.nan, math.inf])
def test_bad_input_value(running, value):
    inst = running
    expect_error(lambda: inst.set({"force": value}))
    assert_logged(inst, "force", value=value)
    assert inst.get("force") == 0.0
    inst.step(0.1)


def test_rejected_call_changes_nothing(in_init):
    """One bad value among several: none is applied."""
    inst = in_init
    vrs = [vr("R"), vr("F"), vr("x_stop")]
    expect_error(lambda: inst.slave.setReal(vrs, [0.5, 1.0, 2.0]))
    assert_logged(inst, "x_stop", value=2.0)
    assert (inst.get("R"), inst.get("F"), inst.get("x_stop")) == (0.7, 76.8, 0.4)
    finish_init_and_step(inst)


def test_initial_state_through_the_stop(in_init):
    inst = in_init
    inst.set({"q0[1]": 1.0, "d": 0.0})
    inst.log.clear()
    expect_error(inst.slave.exitInitializationMode)
    m = assert_logged(inst, "fmi2ExitInitializationMode")
    assert "stop" in m, m
    # still in initialization mode: fix the state and go on
    inst.set({"q0[1]": 0.0})
    finish_init_and_step(inst)


def test_preload_without_initial_deflection_is_rejected(in_init):
    inst = in_init
    inst.set({"d": -0.1})
    expect_error(inst.slave.exitInitializationMode)
    assert "stop" in assert_logged(inst, "fmi2ExitInitializationMode")
    inst.set({"q0[1]": -1.0})  # w_stop = -sqrt2 sin(0.4 pi) < -0.1
    finish_init_and_step(inst)


@pytest.mark.parametrize("phase", ["init", "running"])
def test_unknown_value_reference(make_instance, phase):
    inst = make_instance()
    if phase == "init":
        inst.slave.setupExperiment(startTime=0.0)
        inst.slave.enterInitializationMode()
    else:
        inst.initialize()
    bad = unused_value_reference()
    expect_error(lambda: inst.slave.getReal([bad]))
    assert_logged(inst, str(bad))
    inst.log.clear()
    expect_error(lambda: inst.slave.setReal([bad], [1.0]))
    assert_logged(inst, str(bad))
    assert inst.get("R") == 0.7
    if phase == "init":
        finish_init_and_step(inst)
    else:
        inst.step(0.1)


def test_wrong_type_and_output_writes(running):
    inst = running
    expect_error(lambda: inst.slave.getReal([vr("impacts")]))
    assert_logged(inst, "impacts")
    inst.log.clear()
    expect_error(lambda: inst.slave.setReal([vr("w_stop")], [0.0]))
    assert_logged(inst, "w_stop")
    inst.log.clear()
    expect_error(lambda: inst.slave.setInteger([vr("impacts")], [3]))
    assert_logged(inst, "impacts")
    inst.step(0.1)


FIXED = ["d", "x_stop", "zeta", "q0[1]"]


@pytest.mark.parametrize("name", FIXED)
def test_fixed_parameter_after_initialization(running, name):
    inst = running
    old = inst.get(name)
    new = 0.3 if name != "zeta" else 0.1
    before = inst.outputs()
    expect_error(lambda: inst.set({name: new}))
    assert_logged(inst, name)
    assert inst.get(name) == old
    assert inst.outputs() == before
    inst.step(0.1)


def test_fixed_parameter_message_names_the_value(running):
    """Interface contract: every error message names the variable AND the
    offending value (here: the value the importer tried to set)."""
    inst = running
    missing = []
    for name in FIXED:
        new = 0.3 if name != "zeta" else 0.1
        inst.log.clear()
        expect_error(lambda: inst.set({name: new}))
        try:
            assert_logged(inst, name, value=new)
        except AssertionError:
            missing.append((name, new, inst.log.errors()))
    assert not missing, "messages without the offending value:\n" + "\n".join(map(str, missing))


def test_tunable_parameter_between_steps_is_applied(running):
    inst = running
    inst.set({"R": 0.5, "eps": 1e-4, "F": 50.0, "omega": 2.0})
    assert (inst.get("R"), inst.get("eps"), inst.get("F"), inst.get("omega")) == (0.5, 1e-4, 50.0, 2.0)
    assert not inst.log.errors()
    inst.step(0.1)


def clean_trajectory(make_instance, times):
    ref = make_instance(name="clean").initialize(FREE_VIBRATION)
    out = []
    for t in times:
        ref.advance_to(t)
        out.append(ref.outputs())
    return out


BAD_STEPS = [
    ("t != time", 1.0, 0.1, "currentCommunicationPoint", 1.0),
    ("t slightly != time", 0.1 + 1e-6, 0.1, "currentCommunicationPoint", 0.1 + 1e-6),
    ("h = 0", None, 0.0, "communicationStepSize", 0.0),
    ("h < 0", None, -0.1, "communicationStepSize", -0.1),
    ("h = nan", None, math.nan, "communicationStepSize", math.nan),
]


@pytest.mark.parametrize("label,t,h,needle,value", BAD_STEPS, ids=[b[0] for b in BAD_STEPS])
def test_bad_do_step(make_instance, label, t, h, needle, value):
    inst = make_instance().initialize(FREE_VIBRATION)
    inst.step(0.1)
    current = inst.time if t is None else t
    expect_error(lambda: inst.slave.doStep(currentCommunicationPoint=current, communicationStepSize=h))
    assert_logged(inst, "fmi2DoStep", needle, value=value)
    # nothing happened: the FMU's time and state are those of t = 0.1
    assert inst.slave.getRealStatus(2) == pytest.approx(0.1, abs=1e-15)
    inst.advance_to(0.2)
    inst.advance_to(0.3)
    ref = clean_trajectory(make_instance, [0.1, 0.2, 0.3])
    assert inst.outputs() == ref[-1]


def test_do_step_before_initialization(make_instance):
    inst = make_instance()
    expect_error(lambda: inst.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.1))
    assert_logged(inst, "fmi2DoStep")
    inst.slave.setupExperiment(startTime=0.0)
    inst.slave.enterInitializationMode()
    inst.log.clear()
    expect_error(lambda: inst.slave.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.1))
    assert_logged(inst, "fmi2DoStep")
    finish_init_and_step(inst)


def test_calls_after_terminate(running):
    inst = running
    inst.slave.terminate()
    expect_error(lambda: inst.slave.doStep(currentCommunicationPoint=inst.time, communicationStepSize=0.1))
    assert_logged(inst, "fmi2DoStep")
    assert inst.get("R") == 0.7  # outputs and parameters can still be read
    inst.slave.reset()
    inst.initialize()
    inst.step(0.1)


def test_do_step_past_stop_time(make_instance):
    inst = make_instance().initialize(stop_time=1.0)
    inst.step(0.5)
    expect_error(lambda: inst.slave.doStep(currentCommunicationPoint=0.5, communicationStepSize=1.0))
    assert_logged(inst, "fmi2DoStep")
    inst.advance_to(1.0)


ME_FUNCTIONS = {
    "fmi2EnterEventMode": ([], []),
    "fmi2EnterContinuousTimeMode": ([], []),
    "fmi2SetTime": ([ctypes.c_double], [0.5]),
    "fmi2GetContinuousStates": ([ctypes.c_void_p, ctypes.c_size_t], [None, 0]),
    "fmi2GetDerivatives": ([ctypes.c_void_p, ctypes.c_size_t], [None, 0]),
    "fmi2GetEventIndicators": ([ctypes.c_void_p, ctypes.c_size_t], [None, 0]),
}


@pytest.mark.parametrize("fname", sorted(ME_FUNCTIONS))
def test_model_exchange_functions_return_error(running, fname):
    inst = running
    argtypes, args = ME_FUNCTIONS[fname]
    f = getattr(inst.slave.dll, fname)
    f.argtypes = [ctypes.c_void_p] + argtypes
    f.restype = ctypes.c_int
    assert f(inst.slave.component, *args) == fmi2Error
    assert_logged(inst, fname)
    inst.step(0.1)


def test_unknown_log_category_is_an_error(running):
    inst = running
    expect_error(lambda: inst.slave.setDebugLogging(True, ["logNoSuchCategory"]))
    assert_logged(inst, "logNoSuchCategory")
    inst.step(0.1)


def test_null_component_is_an_error(unzipdir):
    from conftest import Instance

    inst = Instance(unzipdir, name="null")
    try:
        f = inst.slave.dll.fmi2DoStep
        f.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
        f.restype = ctypes.c_int
        assert f(None, 0.0, 0.1, 1) == fmi2Error
    finally:
        inst.free()
