"""Many small dicts of few layouts, held as columns (:class:`ColumnarRecords`).

A recording of thousands of revolutions has one details dict per cycle, all of the same
layout: the same keys, nested lists and dicts, and value types. As Python objects each costs
about 2.5 KiB; here a record costs its numbers at 8 bytes each, a reference per other value
and 16 bytes of bookkeeping, and every record reads back as a dict equal to the one stored,
each value of the same type (``float``, ``numpy.float64``, ``int`` or the object itself), so
that JSON written from it is the same text.
"""

from __future__ import annotations

from array import array
from collections.abc import Iterator, Sequence

import numpy as np

__all__ = ["ColumnarRecords"]

_INT64 = (-(2**63), 2**63 - 1)


def _shape(obj, floats: list, ints: list, objs: list):
    """The layout of ``obj`` (hashable), its leaves appended to the three lists."""
    t = type(obj)
    if t is dict:
        return ("d", tuple((k, _shape(v, floats, ints, objs)) for k, v in obj.items()))
    if t is list or t is tuple:
        return ("l" if t is list else "t", tuple(_shape(v, floats, ints, objs) for v in obj))
    if t is float or t is np.float64:
        floats.append(obj)
        return "f" if t is float else "F"
    if t is int and _INT64[0] <= obj <= _INT64[1]:
        ints.append(obj)
        return "i"
    objs.append(obj)
    return "o"


def _build(shape, fv: Iterator, iv: Iterator, ov: Iterator):
    """The value of layout ``shape`` from the leaves' iterators."""
    if shape == "f":
        return float(next(fv))
    if shape == "F":
        return np.float64(next(fv))
    if shape == "i":
        return int(next(iv))
    if shape == "o":
        return next(ov)
    kind, parts = shape
    if kind == "d":
        return {k: _build(s, fv, iv, ov) for k, s in parts}
    items = [_build(s, fv, iv, ov) for s in parts]
    return items if kind == "l" else tuple(items)


class _Block:
    """The records of one layout: a float64 and an int64 matrix (grown by doubling) and one
    list per other value."""

    def __init__(self, shape, nf: int, ni: int, no: int):
        self.shape, self.n = shape, 0
        self.f = np.empty((8, nf))
        self.i = np.empty((8, ni), dtype=np.int64)
        self.o: list[list] = [[] for _ in range(no)]

    def add(self, floats: list, ints: list, objs: list) -> int:
        if self.n == self.f.shape[0]:
            cap = 2 * self.n
            self.f = np.resize(self.f, (cap, self.f.shape[1]))
            self.i = np.resize(self.i, (cap, self.i.shape[1]))
        self.f[self.n] = floats
        self.i[self.n] = ints
        for col, v in zip(self.o, objs, strict=True):
            col.append(v)
        self.n += 1
        return self.n - 1

    def get(self, row: int):
        return _build(self.shape, iter(self.f[row].tolist()), iter(self.i[row].tolist()),
                      iter([col[row] for col in self.o]))


class ColumnarRecords(Sequence):
    """A read-only sequence of dicts stored by columns (module docstring).

    Records are added with :meth:`append`; indexing or iterating rebuilds each one as a new
    dict, equal to the one added, with values of the same types (floats exactly).

    Parameters
    ----------
    records : iterable of dict, optional
        Records to add first.
    """

    def __init__(self, records=()):
        self._blocks: list[_Block] = []
        self._index: dict = {}  # layout -> position in _blocks
        self._which = array("q")  # block of each record
        self._row = array("q")  # its row in the block
        for r in records:
            self.append(r)

    def append(self, record: dict) -> None:
        """Add one record (a dict; nested dicts, lists and tuples are kept as such)."""
        floats: list = []
        ints: list = []
        objs: list = []
        shape = _shape(record, floats, ints, objs)
        b = self._index.get(shape)
        if b is None:
            b = self._index[shape] = len(self._blocks)
            self._blocks.append(_Block(shape, len(floats), len(ints), len(objs)))
        self._which.append(b)
        self._row.append(self._blocks[b].add(floats, ints, objs))

    def __len__(self) -> int:
        return len(self._which)

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self[j] for j in range(*k.indices(len(self)))]
        n = len(self)
        if k < 0:
            k += n
        if not 0 <= k < n:
            raise IndexError("record index out of range")
        return self._blocks[self._which[k]].get(self._row[k])

    def __iter__(self) -> Iterator[dict]:
        for b, r in zip(self._which, self._row, strict=True):
            yield self._blocks[b].get(r)

    def __eq__(self, other) -> bool:
        if not isinstance(other, Sequence) or isinstance(other, str | bytes):
            return NotImplemented
        return len(self) == len(other) and all(a == b for a, b in zip(self, other,
                                                                      strict=True))

    __hash__ = None

    def __repr__(self) -> str:
        return f"<ColumnarRecords: {len(self)} records, {len(self._blocks)} layouts>"

    def nbytes(self) -> int:
        """Bytes held by the columns and the index (object values counted as references)."""
        return (sum(b.f.nbytes + b.i.nbytes + 8 * sum(len(c) for c in b.o)
                    for b in self._blocks) + 8 * (len(self._which) + len(self._row)))
