"""Helpers every report shares: where they write (report/, or
target/report-quick/ with --quick), progress lines, CSV files, Markdown
tables and number formats. What the reports against the compiled DOP853
peer have in common is in peers.py."""
from __future__ import annotations

import csv
import math
import numbers
from pathlib import Path

from .. import ROOT

REPORT = ROOT / "report"                      # the tracked report: scripts/report
QUICK = ROOT / "target" / "report-quick"      # smoke runs (--quick): git-ignored
QUICK_NOTE = "**Quick smoke run (--quick): few settings, short runs; these are not the report's figures.**\n"


def out_dir(out, name: str, quick: bool) -> Path:
    """Where a report writes: `out` if given, else report/NAME, or with
    --quick target/report-quick/NAME (never the tracked report/)."""
    if out is not None:
        return Path(out)
    return (QUICK if quick else REPORT) / name


def log(msg: str) -> None:
    print(msg, flush=True)


def cell(x):
    """A CSV cell: '' for None, a float as its shortest round-trip repr
    (numpy's too), a list or tuple space-separated, anything else as is."""
    if x is None:
        return ""
    if isinstance(x, numbers.Real) and not isinstance(x, numbers.Integral):
        return repr(float(x))
    if isinstance(x, (list, tuple)):
        return " ".join(str(cell(v)) for v in x)
    return x


def write_csv(path, columns, rows, fmt=cell) -> None:
    """A CSV: the header `columns`, then each row (a dict, read by column
    with '' where a key is missing, or a sequence in column order) with
    its cells through `fmt`: one function, or one per column."""
    fmts = list(fmt) if isinstance(fmt, (list, tuple)) else [fmt] * len(columns)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for r in rows:
            cells = [r.get(c, "") for c in columns] if isinstance(r, dict) else r
            w.writerow([f(x) for f, x in zip(fmts, cells)])


def md_table(header, rows) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def fnum(x, d=2) -> str:
    """A measured number in a table: `d` digits in e-notation, '-' for none or NaN."""
    if x is None:
        return "-"
    x = float(x)
    if math.isnan(x):
        return "-"
    if math.isinf(x):
        return "inf"
    if x == 0:
        return "0"
    return f"{x:.{d}e}"
