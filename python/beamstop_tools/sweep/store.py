"""Finished work on disk, so that a run can be interrupted and resumed:
DIR/sweep.json holds the settings; every finished task is one Parquet file
in DIR/parts/ (a chain's part also keeps the serialized FMU state after its
last point); DIR/points.parquet is assembled from the parts at the end,
with the run's metadata (FMU GUID, settings, package versions)."""
from __future__ import annotations

import base64
import json
import os
import shutil
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from .errors import SweepError

METADATA_KEY = b"beamstop.sweep"
#: Measured columns, after the point's identity and parameters.
MEASURED = [
    ("t_record", pa.float64()), ("impacts", pa.int64()), ("impacts_per_period", pa.float64()),
    ("sticking", pa.bool_()), ("stuck_fraction", pa.float64()), ("period", pa.int32()), ("peak", pa.float64()),
    ("poincare", pa.list_(pa.float64())), ("poincare_rate", pa.list_(pa.float64())),
    ("maxima", pa.list_(pa.float64())), ("seconds", pa.float64()), ("error", pa.string()),
]
IDENTITY = [("point", pa.int32()), ("direction", pa.string()), ("chain", pa.int32()), ("forcing_period", pa.float64())]


def schema(parameters: list[str]) -> pa.Schema:
    reserved = {n for n, _ in IDENTITY + MEASURED}
    for p in parameters:
        if p in reserved:
            raise SweepError(f"--param/--set: the parameter '{p}' has the name of a result column; "
                             f"the table cannot hold both")
    return pa.schema(IDENTITY + [(p, pa.float64()) for p in parameters] + MEASURED)


class Store:
    def __init__(self, out: Path, settings: dict, parameters: list[str], restart: bool = False):
        self.out = Path(out)
        self.parts = self.out / "parts"
        self.schema = schema(parameters)
        self.settings = settings
        spec_file = self.out / "sweep.json"
        if restart and self.parts.exists():
            shutil.rmtree(self.parts)
        if spec_file.exists() and self.parts.exists() and any(self.parts.iterdir()):
            old = json.loads(spec_file.read_text())
            diff = [k for k in sorted(set(old) | set(settings)) if old.get(k) != settings.get(k)]
            if diff:
                shown = "; ".join(f"{k}: {old.get(k)!r} there, {settings.get(k)!r} now" for k in diff)
                raise SweepError(f"--out {self.out}: holds a sweep with other settings ({shown}); "
                                 f"choose another --out or add --restart to discard it")
        self.parts.mkdir(parents=True, exist_ok=True)
        spec_file.write_text(json.dumps(settings, indent=1) + "\n")

    # ------------------------------------------------------------ reading
    def _tables(self):
        for f in sorted(self.parts.glob("*.parquet")):
            try:
                yield f, pq.read_table(f)
            except Exception:          # a part cut short by an interruption: computed again
                f.unlink()

    def done(self) -> dict:
        """(direction or None, point) -> (part file, position of the row)."""
        out = {}
        for f, t in self._tables():
            for i, (d, p) in enumerate(zip(t.column("direction").to_pylist(), t.column("point").to_pylist())):
                out[(d, p)] = (f, i)
        return out

    def chain_state(self, direction: str, order: list[int], done: dict) -> tuple[int, dict | None]:
        """How many points of the chain (in its order) are done, and the
        state the last of them left (None: start from rest)."""
        k = 0
        while k < len(order) and (direction, order[k]) in done:
            k += 1
        if k == 0:
            return 0, None
        f, _ = done[(direction, order[k - 1])]
        meta = pq.read_schema(f).metadata or {}
        last = pq.read_table(f).column("point").to_pylist()[-1]
        if last != order[k - 1] or b"state" not in meta:
            return k, None        # (cannot happen with parts written here) restart the rest from rest
        state = meta[b"state"]
        return k, {"state": base64.b64decode(state) if state else None, "time": float(meta[b"time"])}

    # ------------------------------------------------------------ writing
    def write_part(self, name: str, rows: list[dict], state: bytes | None = None, time: float | None = None,
                   chained: bool = False) -> None:
        table = pa.Table.from_pylist(rows, schema=self.schema)
        if chained:
            table = table.replace_schema_metadata({
                b"state": base64.b64encode(state) if state else b"",
                b"time": repr(time if time is not None else 0.0).encode()})
        tmp = self.parts / f".{name}.tmp"
        pq.write_table(table, tmp)
        os.replace(tmp, self.parts / f"{name}.parquet")

    def finish(self, metadata: dict) -> Path:
        tables = [t.replace_schema_metadata(None) for _, t in self._tables()]
        table = pa.concat_tables(tables) if tables else self.schema.empty_table()
        order = sorted(range(table.num_rows), key=lambda i: (table.column("direction")[i].as_py() or "",
                                                                 table.column("chain")[i].as_py() or 0,
                                                                 table.column("point")[i].as_py()))
        table = table.take(order)
        table = table.replace_schema_metadata({METADATA_KEY: json.dumps(metadata).encode()})
        path = self.out / "points.parquet"
        tmp = self.out / ".points.parquet.tmp"
        pq.write_table(table, tmp)
        os.replace(tmp, path)
        return path


def read_points(path: Path) -> tuple[pa.Table, dict]:
    """A sweep's table and its metadata."""
    table = pq.read_table(path)
    meta = json.loads((table.schema.metadata or {}).get(METADATA_KEY, b"{}"))
    return table, meta
