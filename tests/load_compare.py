"""The comparison shared by the tests of streamed, split and whole-file processing."""

from __future__ import annotations

import dataclasses

import numpy as np


def same_items(got, ref) -> None:
    """Two results of ``pipeline._load_and_process`` (or of merged revolution groups), equal
    in everything but the timings: digest, NaN actions, notes, and every cycle's number,
    index range, signals and traces, bit for bit (NaN equal to NaN)."""
    assert got[2:5] == ref[2:5]  # digest, NaN actions, notes
    assert len(got[5]) == len(ref[5])
    for (c1, s1, i1, r1), (c2, s2, i2, r2) in zip(got[5], ref[5], strict=True):
        assert c1 == c2 and i1 == i2
        assert r1.keys() == r2.keys() and all(np.array_equal(r1[k], r2[k]) for k in r1)
        for f in dataclasses.fields(s1):
            a, b = getattr(s1, f.name), getattr(s2, f.name)
            if isinstance(a, np.ndarray):
                assert np.array_equal(a, b, equal_nan=True), f.name
            else:
                assert repr(a) == repr(b), f.name  # dicts of floats, NaN-safe
