"""FMU state: get/set and serialization round trips continue bit for bit,
also in another process; reset; several instances; threads; many
instantiate/free and reset cycles."""

import ctypes
import json
import subprocess
import sys
import textwrap
import threading

import pytest

from conftest import ALL_OUTPUTS, FREE_VIBRATION, Instance, python_env


def bits(outputs: dict) -> dict:
    """Outputs with floats as their exact bit patterns (float.hex keeps -0.0 apart from 0.0)."""
    return {k: (v.hex() if isinstance(v, float) else v) for k, v in outputs.items()}


def trajectory(inst, t_end, h=0.01):
    rec = []
    inst.step_to(t_end, h, rec)
    return [(t, bits(o)) for t, o in rec]


def test_get_set_state_round_trip_is_bit_identical(make_instance):
    inst = make_instance().initialize(stop_time=20.0)
    inst.step_to(5.0, 0.01)
    state = inst.slave.getFMUstate()
    first = trajectory(inst, 10.0)
    assert first[-1][1]["impacts"] > 0, "the stretch 5..10 should contain impacts and sticking"
    inst.slave.setFMUstate(state)
    inst.time = 5.0
    assert inst.slave.getRealStatus(2) == 5.0  # fmi2LastSuccessfulTime
    second = trajectory(inst, 10.0)
    assert second == first
    # the state object can be reused (fmi2GetFMUstate into an existing state)
    inst.slave.fmi2GetFMUstate(inst.slave.component, ctypes.byref(state))
    inst.slave.setFMUstate(state)
    inst.time = 10.0
    third = trajectory(inst, 12.0)
    inst.slave.setFMUstate(state)
    inst.time = 10.0
    assert trajectory(inst, 12.0) == third
    inst.slave.freeFMUstate(state)


def test_state_restores_tunable_parameters(make_instance):
    inst = make_instance().initialize(stop_time=20.0)
    inst.step_to(5.0, 0.01)
    state = inst.slave.getFMUstate()
    first = trajectory(inst, 9.0)
    inst.slave.setFMUstate(state)
    inst.time = 5.0
    inst.set({"R": 0.2, "F": 10.0})
    inst.step_to(6.0, 0.01)
    inst.slave.setFMUstate(state)
    inst.time = 5.0
    assert inst.get("R") == 0.7 and inst.get("F") == 76.8
    assert trajectory(inst, 9.0) == first
    inst.slave.freeFMUstate(state)


SUBPROCESS_SCRIPT = textwrap.dedent(
    """
    import json, sys
    from conftest import Instance
    unzipdir, state_file, t0, t_end = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
    inst = Instance(unzipdir, name="restored")
    data = open(state_file, "rb").read()
    state = inst.slave.deSerializeFMUstate(data)
    inst.slave.setFMUstate(state)
    inst.slave.freeFMUstate(state)
    inst.time = t0
    out = {"R": inst.get("R").hex(), "rows": []}
    rec = []
    inst.step_to(t_end, 0.01, rec)
    for t, o in rec:
        out["rows"].append([t, {k: (v.hex() if isinstance(v, float) else v) for k, v in o.items()}])
    inst.free()
    print(json.dumps(out))
    """
)


def test_serialized_state_restores_in_another_process(make_instance, unzipdir, tmp_path):
    inst = make_instance().initialize(stop_time=20.0)
    inst.step_to(2.0, 0.01)
    inst.set({"R": 0.55})  # a tunable parameter that must travel with the state
    inst.step_to(5.0, 0.01)
    state = inst.slave.getFMUstate()
    data = inst.slave.serializeFMUstate(state)
    inst.slave.freeFMUstate(state)
    assert isinstance(data, bytes) and len(data) > 0
    (tmp_path / "state.bin").write_bytes(data)
    here = trajectory(inst, 10.0)

    # in this process first: deserialize, set, continue
    state2 = inst.slave.deSerializeFMUstate(data)
    inst.slave.setFMUstate(state2)
    inst.slave.freeFMUstate(state2)
    inst.time = 5.0
    assert trajectory(inst, 10.0) == here

    script = tmp_path / "restore.py"
    script.write_text(SUBPROCESS_SCRIPT)
    proc = subprocess.run([sys.executable, str(script), str(unzipdir), str(tmp_path / "state.bin"), "5.0", "10.0"],
                          capture_output=True, text=True, env=python_env(), timeout=120)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["R"] == (0.55).hex()
    there = [(t, o) for t, o in out["rows"]]
    assert len(there) == len(here)
    assert there == [(t, o) for t, o in here]


def test_corrupt_serialized_state_is_rejected(make_instance):
    from conftest import FMICallException

    inst = make_instance().initialize()
    inst.step(0.5)
    state = inst.slave.getFMUstate()
    data = inst.slave.serializeFMUstate(state)
    inst.slave.freeFMUstate(state)
    for bad in (data[:-3], b"X" + data[1:], data + b"\0"):
        inst.log.clear()
        with pytest.raises(FMICallException):
            inst.slave.deSerializeFMUstate(bad)
        assert inst.log.errors(), "a rejected state must be explained in the log"
    inst.step(0.5)  # still usable


def header_fields(data: bytes) -> dict:
    """Offsets of a serialized state's times (src/fmi/serialize.rs, and the
    modal simulation's first fields, src/kinds/modal/sim/codec.rs)."""
    import struct

    o = 8 + 4  # magic, format version
    (guid_len,) = struct.unpack_from("<I", data, o)
    o += 4 + guid_len + 4  # GUID, instance state
    fields = {"start": o, "stop flag": o + 8, "stop": o + 9, "last successful": o + 17}
    o += 17 + 8 + 3  # ... last successful, terminated, pending, choices
    for _ in range(2):  # parameters, inputs
        (n,) = struct.unpack_from("<I", data, o)
        o += 4 + 8 * n
    assert data[o] == 1, "a state with a simulation"
    o += 1 + 3 * 4  # has_sim, the simulation's version, modes, stops
    fields.update({"time": o, "anchor time": o + 8})
    return fields


def test_serialized_times_a_run_cannot_have_are_refused(make_instance):
    """A state whose anchor lies before its start, whose last successful
    step ends after its time, or whose time is past its stop time is
    refused with a message (accepted, the first gave NaN outputs under
    fmi2OK, the others refused every later step)."""
    import struct

    from conftest import FMICallException

    inst = make_instance().initialize(stop_time=10.0)
    inst.step(0.5)
    state = inst.slave.getFMUstate()
    data = inst.slave.serializeFMUstate(state)
    inst.slave.freeFMUstate(state)
    at = header_fields(data)
    assert struct.unpack_from("<d", data, at["time"])[0] == 0.5
    forgeries = {
        "anchor": [("anchor time", -5.5e303)],
        "last successful time": [("last successful", 1e6)],
        "stop time": [("stop", 0.25)],
    }
    for expect, changes in forgeries.items():
        bad = bytearray(data)
        for field, value in changes:
            struct.pack_into("<d", bad, at[field], value)
        inst.log.clear()
        with pytest.raises(FMICallException):
            inst.slave.deSerializeFMUstate(bytes(bad))
        assert any(expect in m for m in inst.log.errors()), (expect, inst.log.errors())
    s = inst.slave.deSerializeFMUstate(data)  # the true state restores
    inst.slave.setFMUstate(s)
    inst.slave.freeFMUstate(s)
    inst.step(0.5)


def test_a_state_not_live_in_this_fmu_is_refused(make_instance, unzipdir, tmp_path):
    """A state pointer is looked up before it is read: one freed with the
    instance that made it, or one made by another copy of the library (as
    another FMU's would be), is refused with a message, not read (they
    crashed the process or restored another model's state)."""
    import shutil

    from conftest import FMICallException

    a = make_instance(name="a").initialize()
    a.step(0.5)
    b = make_instance(name="b").initialize()
    state = a.slave.getFMUstate()
    b.slave.setFMUstate(state)  # another instance of the same FMU: fine
    b.time = 0.5
    a.free()
    for call in (lambda: b.slave.setFMUstate(state), lambda: b.slave.serializeFMUstate(state), lambda: b.slave.freeFMUstate(state)):
        b.log.clear()
        with pytest.raises(FMICallException):
            call()
        assert any("not one this FMU handed out" in m for m in b.log.errors()), b.log.errors()

    other = tmp_path / "copy"
    shutil.copytree(unzipdir, other)
    c = make_instance(name="c", unzipdir=other).initialize()
    assert c.slave.dll._handle != b.slave.dll._handle, "two copies of the library"
    foreign = c.slave.getFMUstate()
    b.log.clear()
    with pytest.raises(FMICallException):
        b.slave.setFMUstate(foreign)
    assert any("not one this FMU handed out" in m for m in b.log.errors()), b.log.errors()
    c.slave.freeFMUstate(foreign)
    b.step(0.5)


def test_reset_reproduces_the_first_run(make_instance):
    inst = make_instance()
    inst.initialize(stop_time=10.0)
    first = trajectory(inst, 10.0)
    inst.slave.terminate()
    inst.slave.reset()
    inst.initialize(stop_time=10.0)
    assert trajectory(inst, 10.0) == first
    # reset also brings back the start values changed before the first run
    inst.slave.reset()
    inst.initialize(FREE_VIBRATION, stop_time=10.0)
    free = trajectory(inst, 2.0)
    inst.slave.reset()
    inst.slave.setupExperiment(startTime=0.0, stopTime=10.0)
    inst.slave.enterInitializationMode()
    assert inst.get("R") == 0.7 and inst.get("q0[1]") == 0.0 and inst.get("zeta") == 0.05
    inst.slave.exitInitializationMode()
    inst.time = 0.0
    assert trajectory(inst, 10.0) == first
    assert free != first[:len(free)]


def test_two_instances_interleaved_match_separate_runs(make_instance):
    params_a = {"R": 0.7}
    params_b = {"R": 0.3, "F": 60.0}
    sep_a = trajectory(make_instance(name="a0").initialize(params_a, stop_time=10.0), 10.0)
    sep_b = trajectory(make_instance(name="b0").initialize(params_b, stop_time=10.0), 10.0)
    assert sep_a != sep_b
    a = make_instance(name="a1").initialize(params_a, stop_time=10.0)
    b = make_instance(name="b1").initialize(params_b, stop_time=10.0)
    rec_a, rec_b = [], []
    for n in range(1, 1001):
        t = 10.0 if n == 1000 else n * 0.01  # the grid of Instance.step_to
        a.advance_to(t)
        b.advance_to(t)
        rec_a.append((a.time, bits(a.outputs())))
        rec_b.append((b.time, bits(b.outputs())))
    assert [o for _, o in rec_a] == [o for _, o in sep_a]
    assert [o for _, o in rec_b] == [o for _, o in sep_b]


def test_instance_created_on_one_thread_stepped_on_another(make_instance):
    ref = trajectory(make_instance(name="main").initialize(stop_time=8.0), 8.0)
    inst = make_instance(name="threaded").initialize(stop_time=8.0)
    result, errors = {}, []

    def worker():
        try:
            result["traj"] = trajectory(inst, 8.0)
        except BaseException as e:  # reported below
            errors.append(e)

    th = threading.Thread(target=worker)
    th.start()
    th.join(60)
    assert not th.is_alive()
    assert not errors, errors
    assert result["traj"] == ref


def test_instances_on_parallel_threads(make_instance):
    ref = trajectory(make_instance(name="ref").initialize({"R": 0.5}, stop_time=8.0), 8.0)
    insts = [make_instance(name=f"p{k}").initialize({"R": 0.5}, stop_time=8.0) for k in range(4)]
    results, errors = {}, []

    def worker(k):
        try:
            results[k] = trajectory(insts[k], 8.0)
        except BaseException as e:
            errors.append(e)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(60)
    assert not errors, errors
    for k in range(4):
        assert results[k] == ref


def test_many_instantiate_free_cycles(unzipdir):
    for k in range(200):
        inst = Instance(unzipdir, name=f"cycle{k}")
        if k % 50 == 0:
            inst.initialize()
            inst.step(0.1)
        inst.free()
    # and the FMU still works afterwards
    inst = Instance(unzipdir, name="after")
    inst.initialize(FREE_VIBRATION)
    inst.step_to(0.2, 0.01)
    assert inst.get("impacts") >= 1
    inst.free()


def test_many_reset_cycles(make_instance):
    inst = make_instance()
    for k in range(1000):
        if k % 100 == 0:
            inst.initialize()
            inst.step(0.05)
        inst.slave.reset()
    inst.initialize(FREE_VIBRATION)
    inst.step_to(0.2, 0.01)
    assert inst.get("impacts") >= 1
    assert inst.outputs()["energy"] > 0
    assert set(ALL_OUTPUTS) <= set(inst.outputs())


def test_state_moves_between_instances(make_instance):
    """A state taken from one instance continues bit for bit in another."""
    a = make_instance(name="a").initialize({"R": 0.6}, stop_time=20.0)
    a.step_to(5.0, 0.01)
    state = a.slave.getFMUstate()
    data = a.slave.serializeFMUstate(state)
    a.slave.freeFMUstate(state)
    ref = trajectory(a, 9.0)
    b = make_instance(name="b")  # fresh, still Instantiated, default parameters
    s = b.slave.deSerializeFMUstate(data)
    b.slave.setFMUstate(s)
    b.slave.freeFMUstate(s)
    b.time = 5.0
    assert b.get("R") == 0.6
    assert trajectory(b, 9.0) == ref
