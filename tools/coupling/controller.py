"""PDController.fmu's law in Python, and the FMU's build.

`Controller` performs the floating-point operations of
examples/coupling/pd_controller/src/lib.rs in the same order, so a loop that
steps it gives the same torques as the FMU bit for bit: the fmpy loop uses
it, libcosim the FMU, and their agreement checks both.
"""
from __future__ import annotations

import os
import platform
import shutil
import subprocess
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
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
    at t, returns the torque to hold, and integrates the error over h.

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
        s = self.law(t, theta, theta_dot)
        if not s.frozen:
            self.integral += s.error * h
        return s


def _library_name() -> tuple[str, str]:
    """(cargo's output file, the FMU's binaries/<platform>/ file)."""
    machine = platform.machine().lower()
    bits = "64" if machine in ("x86_64", "amd64", "aarch64", "arm64") or sys.maxsize > 2**32 else "32"
    if sys.platform.startswith("linux"):
        return "libpd_controller_fmu.so", f"linux{bits}/PDController.so"
    if sys.platform == "darwin":
        return "libpd_controller_fmu.dylib", f"darwin{bits}/PDController.dylib"
    if sys.platform == "win32":
        return "pd_controller_fmu.dll", f"win{bits}/PDController.dll"
    raise RuntimeError(f"no FMI 2.0 platform name for {sys.platform}")


def build_fmu(out: Path = FMU_PATH, quiet: bool = True) -> Path:
    """`cargo build --release` of examples/coupling/pd_controller (its own
    workspace) and the FMU archive: the crate's
    modelDescription.xml and binaries/<platform>/PDController.<ext>."""
    cargo = shutil.which("cargo")
    if cargo is None:
        raise RuntimeError("cargo not found: PDController.fmu is built from examples/coupling/pd_controller")
    # CARGO_TARGET_DIR if set (relative to the crate: cargo runs there),
    # else target/pd_controller under the repository.
    target = Path(os.environ.get("CARGO_TARGET_DIR") or ROOT / "target" / "pd_controller")
    if not target.is_absolute():
        target = CRATE / target
    cmd = [cargo, "build", "--release", "--target-dir", str(target)]
    if quiet:
        cmd.append("--quiet")
    subprocess.run(cmd, check=True, cwd=CRATE)
    built, inside = _library_name()
    library = target / "release" / built
    if not library.is_file():
        raise RuntimeError(f"cargo built no {library}")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".fmu.tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        z.write(CRATE / "modelDescription.xml", "modelDescription.xml")
        z.write(library, f"binaries/{inside}")
    tmp.replace(out)
    return out


if __name__ == "__main__":
    print(build_fmu())
