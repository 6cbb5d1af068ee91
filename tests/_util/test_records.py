"""ColumnarRecords gives back what was stored, and JSON streamed from it is dump_json's text."""

import json

import numpy as np
import pytest

from torquemod._util.jsonutil import dump_json, iter_json, iter_json_list, write_json
from torquemod._util.records import ColumnarRecords


def _records():
    out = []
    for k in range(40):
        d = {"step": 1 + k % 3, "cycle": k, "source": "a.h5", "t0_s": k / 3,
             "mean": np.float64(k) / 7, "lag": np.int64(k - 20), "slip": None if k % 5 else
             "creepage jump", "window": [k * 0.1, k * 0.1 + 5.0], "flag": bool(k % 2),
             "notches": {"wheel": [4.5, 9.0 + k], "platform": (0.15,)},
             "drift": float("nan") if k == 3 else -0.0 if k == 4 else 1e-300 * k,
             "big": 2**70 if k == 6 else 5}
        if k % 4 == 0:  # a second layout, interleaved
            d["extra"] = [1, 2.5]
        out.append(d)
    return out


def _same(a, b):
    """Equal, with NaN equal to NaN, and each value of the same type."""
    assert type(a) is type(b)
    if isinstance(a, dict):
        assert list(a) == list(b)
        for k in a:
            _same(a[k], b[k])
    elif isinstance(a, list | tuple):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            _same(x, y)
    elif isinstance(a, float) and np.isnan(a):
        assert np.isnan(b)
    else:
        assert a == b
        if isinstance(a, float):
            assert np.signbit(a) == np.signbit(b)


def test_records_read_back_equal_with_their_types():
    recs = _records()
    col = ColumnarRecords(recs)
    assert len(col) == len(recs)
    for a, b in zip(recs, col, strict=True):
        _same(a, b)
    _same(col[-1], recs[-1])
    _same(col[1:3], recs[1:3])
    with pytest.raises(IndexError):
        col[len(recs)]
    assert col[0] is not col[0]  # rebuilt on each read: changing it changes nothing stored
    d = col[2]
    d["slip"] = "x"
    assert col[2]["slip"] is None
    assert col.nbytes() < 400 * len(recs)


@pytest.mark.parametrize("n", [0, 1, 40])
def test_streamed_json_is_dump_json_text(n, tmp_path):
    recs = _records()[:n]
    doc = {"a": 1, "details": ColumnarRecords(recs), "b": [1.5, float("inf")],
           "cycles": ColumnarRecords(recs[::-1]), "z": {"q": None}}
    plain = {**doc, "details": recs, "cycles": recs[::-1]}
    assert "".join(iter_json(doc)) == dump_json(plain)
    write_json(tmp_path / "x.json", doc)
    assert (tmp_path / "x.json").read_text(encoding="utf-8") == dump_json(plain) + "\n"
    # without record columns: the indented encoder's pieces, the same text
    pieces = list(iter_json(plain))
    assert "".join(pieces) == dump_json(plain)
    assert n == 0 or len(pieces) > 1


@pytest.mark.parametrize("n", [0, 1, 3])
def test_json_list_pieces_are_json_dumps(n):
    recs = _records()[:n]
    for level in (0, 2):
        got = "".join(iter_json_list(ColumnarRecords(recs), indent=1, level=level,
                                     default=str))
        want = json.dumps({"k": {"k": recs}} if level == 2 else recs, indent=1, default=str)
        assert got in want
        assert got.startswith("[") and got.endswith("]")
