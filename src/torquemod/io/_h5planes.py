"""Large deflate-compressed HDF5 chunks read in order, a block of rows at a time, without
holding a decompressed chunk (:meth:`torquemod.io._stream_tables._H5Table.blocks`).

HDF5 decompresses a filtered chunk whole, into buffers of its own, and a stream that reads
the chunk a block of rows at a time must keep it (a chunk cache of one chunk a dataset) or
decompress it again for every block. With chunks of 2**22 float64 samples, the rig's six
channels kept 6 x 32 MiB, and each new chunk took HDF5's filter buffers on top (the deflate
output grown by doubling, the shuffle output, the compressed chunk): ``torquemod process``
peaked at 600-670 MiB instead of ~330-380 MiB (docs/performance.md).

Two filters are simple enough to undo as the rows are wanted. Deflate (HDF5 filter 1) stores
each chunk as one zlib stream (RFC 1950/1951), which :mod:`zlib` decompresses in order and
whose state can be copied. The byte shuffle (filter 2) stores a chunk of n elements of s
bytes as s planes of n bytes: byte j of every element, in order, at offset j*n. Rows a..b of
the chunk are therefore bytes j*n+a .. j*n+b of plane j, for each j. One pass through the
stream finds where each plane starts (the decompressor's state copied there); each plane's
decompressor then moves forward with the rows read. Each chunk is decompressed about twice
(the pass to the last plane, then the planes), and a dataset holds s decompressors (a
32 KiB window each) and compressed input of at most ``PIECE_BYTES`` each.

Only datasets whose pipeline is exactly deflate, or shuffle then deflate, whose chunks are
all stored and filtered (filter mask 0), of a numeric type, one-dimensional, in a file HDF5
opened with its default driver (chunk addresses are file offsets) and with chunks of at least
``MIN_CHUNK_BYTES`` take this path; any other dataset is read through HDF5.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

#: Decoded chunk size from which a compressed chunk is read by planes [bytes]; smaller
#: chunks are held whole by HDF5's chunk cache (one chunk a dataset). Reading the rig's six
#: channels of a 10-min recording (gzip + shuffle) by planes took 1.73 CPU-s for chunks of
#: 2**22 float64 samples (HDF5: 1.80-1.95 s and +290 MiB), 1.15 s for 2**22 float32
#: samples (HDF5: 0.87 s, +150-180 MiB) and 1.64 s for 2**20 float64 samples (HDF5: 1.21 s,
#: +100 MiB): chunks of 8 MiB stay with HDF5.
MIN_CHUNK_BYTES = 1 << 24
#: Compressed bytes read from the file at a time by one decompressor [bytes].
PIECE_BYTES = 1 << 16
#: Output a skip decompresses at a time [bytes].
_SKIP_BYTES = 1 << 20
_DEFLATE, _SHUFFLE = 1, 2


class DamagedChunk(Exception):
    """A compressed chunk ends before its rows or does not decompress."""


@dataclass(frozen=True)
class PlaneLayout:
    """Where a dataset's compressed chunks are and how they are decoded.

    Attributes
    ----------
    n_rows : int
        Elements in the dataset [-].
    chunk_rows : int
        Elements in a chunk [-].
    dtype : numpy.dtype
        The stored type (h5py's ``Dataset.dtype``).
    shuffled : bool
        Whether the shuffle filter ran before deflate.
    chunks : tuple
        ``(file offset [bytes], compressed size [bytes])`` of each chunk, in row order.
    """

    n_rows: int
    chunk_rows: int
    dtype: np.dtype
    shuffled: bool
    chunks: tuple[tuple[int, int], ...]


def plane_layout(ds) -> PlaneLayout | None:
    """The :class:`PlaneLayout` of the h5py dataset ``ds``, or None when it is read through
    HDF5 (see the module doc)."""
    import h5py
    try:
        if ds.ndim != 1 or not ds.chunks or ds.dtype.kind not in "biuf":
            return None
        chunk_rows, dtype = int(ds.chunks[0]), np.dtype(ds.dtype)
        if chunk_rows * dtype.itemsize < MIN_CHUNK_BYTES:
            return None
        if ds.file.id.get_access_plist().get_driver() != h5py.h5fd.SEC2:
            return None
        dcpl = ds.id.get_create_plist()
        filters = [dcpl.get_filter(i)[:3] for i in range(dcpl.get_nfilters())]
        codes = [f[0] for f in filters]
        if codes == [_SHUFFLE, _DEFLATE]:
            cd = filters[0][2]
            if cd and cd[0] != dtype.itemsize:
                return None
        elif codes != [_DEFLATE]:
            return None
        n_rows = int(ds.shape[0])
        n_chunks = -(-n_rows // chunk_rows)
        if ds.id.get_num_chunks() != n_chunks:  # a chunk never written: HDF5's fill value
            return None
        where = {}
        for i in range(n_chunks):
            info = ds.id.get_chunk_info(i)
            if info.filter_mask != 0 or info.size <= 0 or info.byte_offset is None:
                return None
            where[int(info.chunk_offset[0])] = (int(info.byte_offset), int(info.size))
        if sorted(where) != [k * chunk_rows for k in range(n_chunks)]:
            return None
        return PlaneLayout(n_rows, chunk_rows, dtype, codes[0] == _SHUFFLE,
                           tuple(where[k] for k in sorted(where)))
    except Exception:  # an h5py or HDF5 without chunk queries: read through HDF5
        return None


class _Cursor:
    """A zlib stream in the file decompressed forward from some point."""

    __slots__ = ("end", "fh", "pos", "tail", "z")

    def __init__(self, fh, z, tail: bytes, pos: int, end: int) -> None:
        self.fh, self.z, self.tail, self.pos, self.end = fh, z, tail, pos, end

    def copy(self) -> _Cursor:
        return _Cursor(self.fh, self.z.copy(), self.tail, self.pos, self.end)

    def take(self, n: int, keep: bool = True) -> bytes:
        """The next ``n`` decompressed bytes (``keep`` False: skip them, return b"")."""
        parts, need = [], n
        while need:
            if not self.tail:
                if self.pos >= self.end:
                    raise DamagedChunk("the compressed chunk ends before its rows")
                self.fh.seek(self.pos)
                self.tail = self.fh.read(min(PIECE_BYTES, self.end - self.pos))
                if not self.tail:
                    raise DamagedChunk("the file ends inside a compressed chunk")
                self.pos += len(self.tail)
            before = len(self.tail)
            out = self.z.decompress(self.tail, need if keep else min(need, _SKIP_BYTES))
            self.tail = self.z.unconsumed_tail
            if not out and (self.z.eof or len(self.tail) == before):
                raise DamagedChunk("the compressed chunk ends before its rows")
            need -= len(out)
            if keep:
                parts.append(out)
        return b"".join(parts) if keep else b""


class PlaneReader:
    """Rows of one dataset read from its compressed chunks, decoded by planes: in order
    (a read starting elsewhere than where the last ended decodes its chunk from the start
    up to it again).

    Parameters
    ----------
    layout : PlaneLayout
        The dataset's chunks.
    fh : file object
        The HDF5 file opened for reading in binary.
    """

    def __init__(self, layout: PlaneLayout, fh) -> None:
        self.layout, self.fh = layout, fh
        self.cursors: list[_Cursor] | None = None
        self.row = -1  # the next row the cursors give

    def _start(self, row: int) -> None:
        """Cursors for ``row`` onward in its chunk: one per plane (shuffled) or one."""
        lay = self.layout
        off, size = lay.chunks[row // lay.chunk_rows]
        at = row % lay.chunk_rows
        run = _Cursor(self.fh, zlib.decompressobj(), b"", off, off + size)
        itemsize = lay.dtype.itemsize
        if not lay.shuffled:
            run.take(at * itemsize, keep=False)
            self.cursors = [run]
        else:
            cursors, done = [], 0
            for j in range(itemsize):
                run.take(j * lay.chunk_rows + at - done, keep=False)
                done = j * lay.chunk_rows + at
                cursors.append(run if j == itemsize - 1 else run.copy())
            self.cursors = cursors
        self.row = row

    def rows(self, a: int, b: int) -> np.ndarray:
        """The values of rows ``a:b`` in the stored type (cheapest when ``a`` is where the
        last read ended).

        Raises
        ------
        DamagedChunk
            A chunk ends early; zlib.error: a chunk does not decompress; OSError.
        """
        lay = self.layout
        out = np.empty(b - a, lay.dtype)
        at = 0
        while a < b:
            if self.cursors is None or a != self.row:
                self._start(a)
            stop = min(b, (a // lay.chunk_rows + 1) * lay.chunk_rows)
            m = stop - a
            dest = out[at:at + m]
            if lay.shuffled:
                planes = dest.view(np.uint8).reshape(m, lay.dtype.itemsize)
                for j, cur in enumerate(self.cursors):
                    planes[:, j] = np.frombuffer(cur.take(m), np.uint8)
            else:
                dest.view(np.uint8)[:] = np.frombuffer(
                    self.cursors[0].take(m * lay.dtype.itemsize), np.uint8)
            at, a, self.row = at + m, stop, stop
            if stop % lay.chunk_rows == 0:  # the chunk is done: free its decompressors
                self.cursors = None
        return out
