"""JSON for result files: numpy values as Python numbers, NaN/inf as null (strict JSON)."""

from __future__ import annotations

import datetime as _dt
import json
import math
from pathlib import Path

import numpy as np

from torquemod._util.records import ColumnarRecords


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


#: the encoder of json.dumps(..., indent=2, allow_nan=False), for its pieces
_ENCODER = json.JSONEncoder(indent=2, allow_nan=False)


def dump_json(obj) -> str:
    """Indented strict JSON text of :func:`to_jsonable` ``(obj)``."""
    return json.dumps(to_jsonable(obj), indent=2, allow_nan=False)


def iter_json_list(items, *, indent: int, level: int, **dumps_kw):
    """The text of ``json.dumps(list(items), indent=indent, **dumps_kw)`` as it stands at
    nesting ``level`` of an indented document, in pieces: one per item, each encoded alone
    (``json`` escapes newlines inside strings, so re-indenting an item's lines is exact)."""
    outer, inner = " " * (indent * level), " " * (indent * (level + 1))
    first = True
    for item in items:
        text = json.dumps(item, indent=indent, **dumps_kw).replace("\n", "\n" + inner)
        yield ("[\n" if first else ",\n") + inner + text
        first = False
    yield "[]" if first else "\n" + outer + "]"


def iter_json(obj):
    """The text of :func:`dump_json` ``(obj)`` in pieces: the values of a top-level dict
    that are :class:`~torquemod._util.records.ColumnarRecords` are encoded one record at a
    time, so that no JSON-ready copy of them all is made."""
    streamed = ({k: v for k, v in obj.items() if isinstance(v, ColumnarRecords)}
                if isinstance(obj, dict) else {})
    if not streamed:  # the indented encoder's pieces, as json.dump writes them
        yield from _ENCODER.iterencode(to_jsonable(obj))
        return
    marks = {k: f"\x00torquemod-records-{id(v):x}-{n}\x00"
             for n, (k, v) in enumerate(streamed.items())}
    text = dump_json({k: marks.get(k, v) for k, v in obj.items()})
    for k, records in streamed.items():
        head, text = text.split(json.dumps(marks[k]), 1)
        yield head
        yield from iter_json_list((to_jsonable(r) for r in records), indent=2, level=1,
                                  allow_nan=False)
    yield text


def write_json(path, obj) -> None:
    """``dump_json(obj)`` and a newline into the file ``path`` (UTF-8), written as it is
    encoded (:func:`iter_json`): the per-cycle details of a recording of thousands of
    revolutions are never all held as text or as JSON-ready objects."""
    with open(path, "w", encoding="utf-8") as fh:
        for piece in iter_json(obj):
            fh.write(piece)
        fh.write("\n")
