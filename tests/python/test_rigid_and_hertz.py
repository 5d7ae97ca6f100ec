"""RigidAndHertzStops: a rigid restitution stop and a Hertz stop on one beam,
both active in one run (impacts, chatter and sticks at the rigid stop while
the Hertz stop pushes), through fmpy (FMI 2.0):

- one doStep over the horizon and 10,000 at the experiment's step log the
  same events, bit for bit;
- the events and both stops' displacements agree with an independent model
  of the same modes and laws (mixed_stops_reference.py: scipy DOP853 at
  rtol 1e-12 between located events) to 1e-8 of the Hertz stop's gap;
- states saved during a hold under the Hertz push, and during a chatter,
  restore and continue bit for bit.
"""

from __future__ import annotations

import json
import re

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

from conftest import FMU_DIR, ROOT
import mixed_stops_reference as reference

NAME = "RigidAndHertzStops"
SCENE = json.loads((ROOT / "scenes" / "rigid_and_hertz.json").read_text())
T_END = SCENE["experiment"]["stop"]
STEP = SCENE["experiment"]["step"]
GAP = SCENE["stops"][1]["gap"]


class Run:
    def __init__(self):
        fmu = str(FMU_DIR / f"{NAME}.fmu")
        self.md = read_model_description(fmu)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.reals = [v.valueReference for v in self.md.modelVariables if v.causality == "output" and v.type == "Real"]
        self.lines = []

        self.errors = []

        def log(env, name, status, category, message):
            if category == b"logEvents":
                self.lines.append(message.decode())
            elif status >= 3:
                self.errors.append(message.decode())
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(log)
        self.s = FMU2Slave(guid=self.md.guid, unzipDirectory=extract(fmu), modelIdentifier=self.md.coSimulation.modelIdentifier,
                           instanceName="a")
        self.s.instantiate(callbacks=self.callbacks, loggingOn=True)
        self.s.setDebugLogging(True, ["logEvents"])
        self.s.setupExperiment(startTime=0.0)
        self.s.enterInitializationMode()
        self.s.exitInitializationMode()
        self.t = 0.0

    def to(self, t):
        try:
            self.s.doStep(self.t, t - self.t)
        except Exception as e:
            raise AssertionError(f"doStep to {t}: {self.errors}") from e
        self.t = t

    def get(self, name):
        return self.s.getReal([self.vr[name]])[0]

    def bits(self):
        return [x.hex() for x in self.s.getReal(self.reals)]


def stepped():
    """At the experiment's step, with the stops' displacements on a 0.01 grid."""
    r = Run()
    samples = []
    n = round(T_END / STEP)
    for k in range(1, n + 1):
        r.to(T_END if k == n else k * STEP)
        if k % 10 == 0:
            samples.append((r.t, r.get("rigid.w"), r.get("soft.w")))
    return r, samples


def parse(line):
    t = float(re.match(r"t = (\S+):", line).group(1))
    for words, kind in [("contact starts", "contact"), ("contact ends", "separation"), ("impact", "impact"),
                        ("sticking starts", "stick"), ("release from", "release")]:
        if words in line:
            return t, kind
    return t, line


def test_one_step_and_the_experiments_step_log_the_same_events_as_an_independent_model():
    whole = Run()
    whole.to(T_END)
    fine, samples = stepped()
    assert whole.lines == fine.lines and len(fine.lines) > 20
    events = [parse(l) for l in fine.lines]
    kinds = [k for _, k in events]
    # Both stops act in one run: impacts, a chatter ending in a stick and a
    # release at the rigid stop while the Hertz stop pushes.
    assert kinds.count("impact") > 10 and kinds.count("stick") >= 2 and kinds.count("release") >= 2, kinds
    ref_events, pieces = reference.simulate(SCENE, T_END)
    assert [k for _, k, _ in ref_events] == kinds, (ref_events, events)
    worst_t = max(abs(a[0] - b[0]) for a, b in zip(ref_events, events))
    assert worst_t <= 1e-8, worst_t
    m = reference.Model(SCENE)
    worst_w = 0.0
    for t, w_rigid, w_soft in samples:
        y = reference.state_at(pieces, t)
        worst_w = max(worst_w, abs(m.w_r @ y[:m.n] - w_rigid), abs(m.w_s @ y[:m.n] - w_soft))
    assert worst_w <= 1e-8 * GAP, worst_w / GAP
    whole.s.freeInstance()
    fine.s.freeInstance()


def test_states_saved_in_a_hold_under_the_hertz_push_restore_bit_for_bit():
    r = Run()
    for t_save in (0.7597697054528, 1.5, 7.0, 7.5):  # at a chatter's end, held, chattering, held
        r.to(t_save)
        state = r.s.getFMUstate()
        blob = r.s.serializeFMUstate(state)
        r.to(t_save + 0.3)
        after = r.bits()
        r.s.setFMUstate(state)
        r.t = t_save
        r.to(t_save + 0.3)
        assert r.bits() == after, t_save
        try:
            restored = r.s.deserializeFMUState(blob)
        except Exception as e:
            raise AssertionError(f"at {t_save}: {r.errors}") from e
        r.s.setFMUstate(restored)
        r.t = t_save
        r.to(t_save + 0.3)
        assert r.bits() == after, t_save
        r.s.freeFMUState(state)
    r.s.freeInstance()
