"""JSON for result files: numpy values as Python numbers, NaN/inf as null (strict JSON)."""

from __future__ import annotations

import datetime as _dt
import json
import math
from pathlib import Path

import numpy as np


def to_jsonable(obj):
    """``obj`` with dicts, sequences, numpy arrays and scalars, paths and dates (ISO text)
    made JSON-ready;
    non-finite floats become None so that the file is valid JSON."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, bool | np.bool_):
        return bool(obj)
    if isinstance(obj, int | np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, _dt.date | _dt.time):  # TOML dates and times (e.g. [test] date)
        return obj.isoformat()
    return obj


def dump_json(obj) -> str:
    """Indented strict JSON text of :func:`to_jsonable` ``(obj)``."""
    return json.dumps(to_jsonable(obj), indent=2, allow_nan=False)


def write_json(path, obj) -> None:
    """``dump_json(obj)`` and a newline into the file ``path`` (UTF-8), written as it is
    encoded: the indented encoder makes a piece of text per key and value, which
    :func:`json.dumps` holds all at once (tens of MiB for the per-cycle details of a
    recording of thousands of revolutions)."""
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(to_jsonable(obj), fh, indent=2, allow_nan=False)
        fh.write("\n")
