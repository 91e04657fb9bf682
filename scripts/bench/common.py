"""Paths and the small formatting helpers every part of the benchmark uses."""
import math
import os
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent
DATA = Path(os.environ.get("SPARSELOOP_DATA", ROOT.parent / "shared" / "data"))
RESULTS = ROOT / "bench" / "results"  # long runs recorded by scripts/soak


def fmt(v, digits=2):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "n/a"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return str(v)


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(c) if not isinstance(c, str) else c for c in row) + " |"
              for row in rows]
    return "\n".join(lines)


def num(v):
    return float("nan") if v is None else v


def status(value, ok):
    """Target status: n/a when the value could not be measured."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "not measured"
    return "met" if ok else "**missed**"
