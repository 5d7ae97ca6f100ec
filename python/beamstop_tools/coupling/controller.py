"""PDController.fmu's law in Python, and the FMU's build.

`Controller` performs the floating-point operations of
examples/coupling/pd_controller/src/lib.rs in the same order, so a loop that
steps it gives the same torques as the FMU bit for bit: the fmpy loop uses
it, libcosim the FMU, and their agreement checks both.
"""
from __future__ import annotations

import subprocess
from dataclasses import dataclass
from pathlib import Path

from .. import ROOT, engine

CRATE = ROOT / "examples" / "coupling" / "pd_controller"
FMU_PATH = ROOT / "target" / "coupling" / "PDController.fmu"

PARAMETERS = ("Kp", "Kd", "Ki", "theta_ref", "theta_start", "T_slew", "torque_max")


@dataclass
class Sample:
    torque: float
    reference: float
    error: float
    frozen: bool


class Controller:
    """A sampled PD/PID law: `step(t, h, theta, theta_dot)` samples the inputs
    at the controller's own time (where its last step ended, as the FMU
    keeps it), returns the torque to hold, and integrates the error up to
    the step's end t + h.

    torque = clamp(Kp e + Kd (r'(t) - theta_dot) + Ki I, -torque_max, torque_max),
    e = r(t) - theta; I += e h unless the output saturates with e pushing it
    further (clamping anti-windup). r slews from theta_start to theta_ref over
    T_slew along 10 s^3 - 15 s^4 + 6 s^5 (a step when T_slew = 0).
    """

    def __init__(self, Kp, Kd, Ki, theta_ref, theta_start, T_slew, torque_max, t_start=0.0):
        self.Kp, self.Kd, self.Ki = float(Kp), float(Kd), float(Ki)
        self.theta_ref, self.theta_start = float(theta_ref), float(theta_start)
        self.T_slew, self.torque_max = float(T_slew), float(torque_max)
        self.t_start = float(t_start)
        self.time = float(t_start)
        self.integral = 0.0

    @classmethod
    def from_values(cls, values: dict, t_start=0.0) -> "Controller":
        return cls(*(values[name] for name in PARAMETERS), t_start=t_start)

    def reference(self, t: float) -> tuple[float, float]:
        if not self.T_slew > 0.0:
            return self.theta_ref, 0.0
        s = min(max((t - self.t_start) / self.T_slew, 0.0), 1.0)
        if s == 1.0:
            return self.theta_ref, 0.0
        d = self.theta_ref - self.theta_start
        shape = s * s * s * (10.0 + s * (-15.0 + s * 6.0))
        rate = 30.0 * s * s * (1.0 - s) * (1.0 - s) / self.T_slew
        return self.theta_start + d * shape, d * rate

    def law(self, t: float, theta: float, theta_dot: float) -> Sample:
        r, r_dot = self.reference(t)
        e = r - theta
        v = self.Kp * e + self.Kd * (r_dot - theta_dot) + self.Ki * self.integral
        torque = min(max(v, -self.torque_max), self.torque_max)
        return Sample(torque, r, e, torque != v and e * v > 0.0)

    def step(self, t: float, h: float, theta: float, theta_dot: float) -> Sample:
        end = max(t + h, self.time)
        s = self.law(self.time, theta, theta_dot)
        if not s.frozen:
            self.integral += s.error * (end - self.time)
        self.time = end
        return s


def build_fmu(out: Path = FMU_PATH, quiet: bool = True) -> Path:
    """PDController.fmu at `out` (its folder; the name is the scene's): the
    controller's crate, a kind of simulation of its own, built by cargo in
    beamstop's workspace and packed by its command, which uses beamstop's
    FMI layer and packager.

    `cargo run -p pd_controller_fmu --bin package-pd-controller` (a no-op
    after scripts/test): beamstop is linked without its own kinds, so the
    FMU carries only the controller."""
    engine.cargo_run(["-p", "pd_controller_fmu", "--bin", "package-pd-controller"], [out.parent],
                     stdout=subprocess.DEVNULL if quiet else None)
    built = out.parent / "PDController.fmu"
    if built != out:
        built.replace(out)
    return out


if __name__ == "__main__":
    print(build_fmu())
