"""The spring-stop FMUs (the RMTM paper's base-excited cantilever) against an
independent numerical integration of the same modal equations
(`python/beamstop_tools/report/springstop_reference.py`: its own mode shapes, scipy's DOP853
at rtol 1e-13 with located switches): the exact force-integration route
agrees to 1e-9 of the gap over 0.5 s from rest, contact for contact."""

import csv
import json
import subprocess

import numpy as np
import pytest
from fmpy import simulate_fmu

from beamstop_tools.report.springstop_reference import simulate
from conftest import FMU_DIR, ROOT, native_beamstop

T_END, DT, GAP = 0.5, 1e-4, 1e-3


def scene(name: str) -> dict:
    return json.loads((ROOT / "scenes" / f"{name}.json").read_text())


def native(name: str, modes: int, tmp_path) -> tuple[np.ndarray, int]:
    s = scene(name)
    s["structure"]["modes"] = modes
    s["experiment"] = {"start": 0.0, "stop": T_END, "step": DT}
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(s))
    subprocess.run(native_beamstop() + ["run", str(path), "--out", str(tmp_path)], check=True, capture_output=True)
    rows = list(csv.DictReader(open(tmp_path / f"{s['name']}.csv")))
    return np.array([float(r["tip.w"]) for r in rows]), int(rows[-1]["stop.contacts"])


@pytest.mark.parametrize("name,modes", [("spring_stop_soft", 5), ("spring_stop_soft", 20),
                                        ("spring_stop_hard", 5), ("spring_stop_hard", 20)])
def test_exact_route_matches_numerical_integration(name, modes, tmp_path):
    ref = simulate(scene(name), modes, T_END, DT)
    tip, contacts = native(name, modes, tmp_path)
    assert contacts == len(ref["onsets"]) >= 8
    assert len(tip) == len(ref["tip_w"])
    error = np.max(np.abs(tip - ref["tip_w"])) / GAP
    assert error < 1e-9, f"{name}, {modes} modes: {error:.2e} of the gap"


def test_fmu_through_fmpy_matches_numerical_integration():
    # The packaged hard-impact FMU (20 modes) stepped by fmpy every 0.1 ms.
    ref = simulate(scene("spring_stop_hard"), 20, T_END, DT)
    res = simulate_fmu(str(FMU_DIR / "SpringStopHard.fmu"), stop_time=T_END, output_interval=DT,
                       output=["tip.w", "stop.contacts", "stop.force"])
    assert len(res) == len(ref["tip_w"])
    error = np.max(np.abs(res["tip.w"] - ref["tip_w"])) / GAP
    assert error < 1e-9, f"{error:.2e} of the gap"
    assert res["stop.contacts"][-1] == len(ref["onsets"])
    assert np.max(np.abs(res["stop.force"] - ref["force"])) < 1e-9 * np.max(ref["force"]) * 1e3
