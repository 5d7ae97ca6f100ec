"""S3 (VSM12 Figure 4: 177 impacts, 7 sticks in 20 time units) as a user's
one-off simulation pays it: a fresh PinnedBeamStop.fmu instance through
fmpy, timed around fmi2Instantiate, initialisation (setup, enter and exit
initialisation mode) and the first fmi2DoStep over the whole horizon,
against the compiled DOP853 peer's fastest run at the same error level
(`examples/rigid_peer.rs --scene S3`, run here, side by side).

The FMU computes S3 at its default event_tolerance 0: event times to about
3e-14 (report/rigid_peer), so any level of 1e-6 or looser compares it with
the peer's fastest run at that level.

    python -m beamstop_tools.report.s3_cold [--instances 30] [--level 1e-6]
"""

import argparse
import csv
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

from .. import ROOT, engine


def fmu_phases(fmu: Path, instances: int, t_end: float) -> dict:
    """Seconds per phase of fresh instances (the binary loaded once)."""
    unzipped = engine.Fmu(fmu)
    phases = {"instantiate": [], "initialise": [], "first doStep": []}
    for k in range(instances):
        f = engine.Session(unzipped, f"s3_{k}", instantiate=False)
        t0 = time.perf_counter()
        f.instantiate()
        t1 = time.perf_counter()
        f.start()
        t2 = time.perf_counter()
        f.step(0.0, t_end)  # fmpy raises on a bad status
        t3 = time.perf_counter()
        f.close()
        phases["instantiate"].append(t1 - t0)
        phases["initialise"].append(t2 - t1)
        phases["first doStep"].append(t3 - t2)
    return phases


def peer_at(level: float) -> dict:
    with tempfile.TemporaryDirectory() as td:
        levels = Path(td) / "levels.csv"
        engine.example("rigid_peer", ["--scene", "S3", "--quick", "--csv", Path(td) / "runs.csv",
                                      "--levels-csv", levels], stdout=subprocess.DEVNULL)
        rows = list(csv.DictReader(open(levels)))
    row = min((r for r in rows if float(r["level"]) >= level * (1 - 1e-9)), key=lambda r: float(r["level"]))
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--instances", type=int, default=30)
    ap.add_argument("--level", type=float, default=1e-6)
    ap.add_argument("--fmu", type=Path, default=ROOT / "target/fmu/PinnedBeamStop.fmu")
    args = ap.parse_args(argv)
    phases = fmu_phases(args.fmu, args.instances, 20.0)
    peer = peer_at(args.level)
    print(f"PinnedBeamStop.fmu (S3, 0..20), fresh instances through fmpy, {args.instances} of them: "
          "fastest and median [ms]")
    for name, values in phases.items():
        print(f"  {name:<13} {1e3 * min(values):8.3f} {1e3 * statistics.median(values):8.3f}")
    first = min(phases["first doStep"])
    peer_ms = float(peer["peer_ms"])
    print(f"peer at error <= {args.level:g}: {peer['peer_setting']}, {peer_ms:.3f} ms (error {float(peer['peer_error']):.2e})")
    print(f"peer time / first doStep: {peer_ms / (1e3 * first):.2f}; "
          f"peer time / (initialise + first doStep): {peer_ms / (1e3 * (first + min(phases['initialise']))):.2f}")


if __name__ == "__main__":
    main()
