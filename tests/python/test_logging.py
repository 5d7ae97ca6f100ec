"""Log messages through the logger callback: logEvents carries every impact
with its exact time, categories are the declared ones, fmi2SetDebugLogging
switches them, and nothing but errors is logged when logging is off."""

import re

import pytest

from conftest import FMICallException, FREE_VIBRATION, fmi2Error, fmi2OK, model_description

EVENT = re.compile(r"t = ([-+0-9.eE]+): (impact|sticking starts|release|grazing)")


def events(inst, kind=None):
    out = []
    for m in inst.log.messages("logEvents"):
        g = EVENT.match(m)
        assert g, f"logEvents message without a leading time: {m!r}"
        if kind is None or g.group(2) == kind:
            out.append((float(g.group(1)), g.group(2)))
    return out


def logging_instance(make_instance, categories=("logEvents",), **kw):
    inst = make_instance(logging_on=True, **kw)
    inst.slave.setDebugLogging(True, list(categories))
    return inst


def test_impact_messages_carry_t_last_impact(make_instance):
    inst = logging_instance(make_instance)
    inst.initialize(FREE_VIBRATION)
    seen = 0
    t_prev = 0.0
    for _ in range(500):
        inst.step(0.01)
        impacts = inst.get("impacts")
        new = events(inst, "impact")[seen:]
        assert len(new) == impacts - seen, (inst.time, new, impacts, seen)
        for t, _ in new:
            assert t_prev < t <= inst.time + 1e-15
        if new:
            t_last = inst.get("t_last_impact")
            # printed with 17 decimals: equal up to the printing
            assert abs(new[-1][0] - t_last) <= 1e-16 * max(1.0, t_last), (new[-1][0], t_last)
            seen = impacts
        t_prev = inst.time
    assert seen > 20
    first = events(inst, "impact")[0][0]
    assert abs(first - 1.0 / (2.0 * 3.141592653589793)) <= 1e-12


def test_event_messages_are_ok_status_in_log_events(make_instance):
    inst = logging_instance(make_instance, name="named_instance")
    inst.initialize()
    inst.step_to(7.0, 0.05)
    ev = [r for r in inst.log.records if r[2] == "logEvents"]
    assert ev
    assert all(s == fmi2OK for _, s, _, _ in ev)
    assert all(name == "named_instance" for name, _, _, _ in ev)
    declared = {c.name for c in model_description().logCategories}
    assert {c for _, _, c, _ in inst.log.records} <= declared


def test_stick_and_release_messages_follow_the_sticking_output(make_instance):
    inst = logging_instance(make_instance)
    inst.initialize(stop_time=10.0)
    assert inst.get("sticking")
    stick0 = events(inst, "sticking starts")
    assert stick0 and stick0[0][0] == 0.0, inst.log.text()
    was = True
    for _ in range(1000):
        inst.step(0.01)
        now = inst.get("sticking")
        if now != was:
            kind = "release" if was else "sticking starts"
            times = [t for t, _ in events(inst, kind)]
            assert any(inst.time - 0.01 - 1e-12 < t <= inst.time + 1e-12 for t in times), (inst.time, kind)
        was = now
    releases = [t for t, _ in events(inst, "release")]
    assert 3.18 < releases[0] < 3.19


def test_unknown_category_is_an_error(make_instance):
    inst = make_instance(logging_on=True)
    with pytest.raises(FMICallException) as info:
        inst.slave.setDebugLogging(True, ["logEvents", "noSuchCategory"])
    assert info.value.status == fmi2Error
    assert any("noSuchCategory" in m for m in inst.log.errors()), inst.log.text()
    inst.initialize()
    inst.step(0.1)


def test_importer_text_in_a_message_has_its_hash_signs_escaped(make_instance):
    """FMI 2.0.4 section 2.1.5: the logger reads `#r1#` as variable 1's
    name and `##` as one `#`; text echoed from the importer is escaped."""
    inst = make_instance(logging_on=True)
    with pytest.raises(FMICallException):
        inst.slave.setDebugLogging(True, ["#r1#"])
    assert any('"##r1##"' in m for m in inst.log.errors()), inst.log.text()


def test_no_event_messages_when_logging_is_off(make_instance):
    inst = make_instance(logging_on=False)
    inst.initialize(FREE_VIBRATION)
    inst.step_to(3.0, 0.01)
    assert inst.get("impacts") > 5
    assert inst.log.messages("logEvents") == []
    assert inst.log.records == [], inst.log.text()


def test_switching_logging_off_silences_events(make_instance):
    inst = logging_instance(make_instance)
    inst.initialize(FREE_VIBRATION)
    inst.step_to(1.0, 0.01)
    assert events(inst, "impact")
    inst.slave.setDebugLogging(False, [])
    inst.log.clear()
    inst.step_to(3.0, 0.01)
    assert inst.log.records == [], inst.log.text()
    # and back on
    inst.slave.setDebugLogging(True, ["logEvents"])
    n = inst.get("impacts")
    inst.step_to(5.0, 0.01)
    assert len(events(inst, "impact")) == inst.get("impacts") - n > 0


def test_enabling_a_category_on_an_instance_created_without_logging(make_instance):
    inst = make_instance(logging_on=False)
    inst.slave.setDebugLogging(True, ["logEvents"])
    inst.initialize(FREE_VIBRATION)
    inst.step_to(1.0, 0.01)
    assert len(events(inst, "impact")) == inst.get("impacts") > 0
    assert {c for _, _, c, _ in inst.log.records} == {"logEvents"}


def test_errors_are_logged_even_with_logging_off(make_instance):
    inst = make_instance(logging_on=False)
    inst.initialize()
    with pytest.raises(FMICallException):
        inst.set({"R": 2.0})
    assert len(inst.log.errors()) == 1
