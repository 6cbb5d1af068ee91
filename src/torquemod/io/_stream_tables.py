"""Format tables of the streaming readers (:mod:`torquemod.io.stream`): one open file seen
as columns of raw values, read by row ranges or in order."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from torquemod.errors import InputError
from torquemod.io.channels import library_error

DEFAULT_CHUNK_ROWS = 1 << 18  # 262 144 rows: 15.7 s at 16.67 kHz, 2 MiB per channel
#: Text parsed per step by pyarrow's streaming CSV reader [bytes]. The reader keeps about
#: 35 blocks of parsed values alive: 4 MiB blocks held ~140 MiB (a 10-min recording's
#: `process` peaked at 483 MiB), 1 MiB blocks ~35 MiB for +0.3 CPU-s per 10 min of the rig.
CSV_BLOCK_BYTES = 1 << 20


class _Table:
    """One open file seen as columns of raw values. Subclasses set ``n_rows`` (None when
    only a pass can tell), ``native_rate`` and implement the methods below."""

    n_rows: int | None = None
    native_rate: tuple[float, float] | None = None
    sequential = False  # rows can only be read in order (CSV)

    def has(self, name: str) -> bool:
        raise NotImplementedError

    def unit(self, name: str) -> str | None:
        return None

    def own_base(self, name: str) -> tuple | None:
        """The column's own time base: ``("rate", fs_hz, t0_s)``, ``("stamps", key)`` or
        None (on the recording's base)."""
        return None

    def stamps_blocks(self, key: object, chunk_rows: int) -> Iterator[np.ndarray]:
        raise NotImplementedError

    def read(self, names: list[str], a: int, b: int) -> dict[str, np.ndarray]:
        raise NotImplementedError

    def blocks(self, names: list[str], chunk_rows: int) -> Iterator[dict[str, np.ndarray]]:
        """Consecutive blocks of raw values (any sizes) of ``names``, from row 0."""
        n = self.length()
        for a in range(0, n, chunk_rows):
            yield self.read(names, a, min(n, a + chunk_rows))

    def length(self) -> int:
        if self.n_rows is None:
            name = self.first_name
            self.n_rows = sum(next(iter(b.values())).size
                              for b in self.blocks([name], DEFAULT_CHUNK_ROWS))
        return self.n_rows

    first_name = ""

    def close(self) -> None:
        pass


def _dataset_for_stream(group, key: str):
    """The HDF5 dataset ``key`` below ``group``, opened with the chunk cache a stream needs.

    A stream reads each chunk of a dataset once, in order, a block of rows at a time (a
    block may end inside a chunk). Chunks stored without filters are read straight from the
    file into the block (HDF5 does so for a chunk larger than the cache): the cache is set
    to 0 bytes, whatever the chunk size. HDF5 2.0's default cache of 8 MiB a dataset held
    48 MiB for a recording's 6 channels, and a cache of one chunk held the chunks whole:
    6 x 32 MiB for chunks of 2**22 float64 samples. A compressed (filtered) chunk can only
    be decompressed whole by HDF5, so its cache holds one chunk (each chunk is decompressed
    once); a pass in order over large deflate-compressed chunks does not use it
    (:meth:`_H5Table.blocks`, :mod:`torquemod.io._h5planes`).
    HDF5 sets a dataset's cache when the dataset is first opened, so it is opened here, not
    through ``group[key]``. Contiguous datasets get the default access (no chunk cache is
    used), and so does any dataset the cache cannot be set on.
    """
    import h5py
    ds = None
    try:
        probe = h5py.h5d.open(group.id, key.encode())  # its layout; closed when dropped
        layout, itemsize = probe.get_create_plist(), probe.dtype.itemsize
        del probe
        chunks = layout.get_chunk() if layout.get_layout() == h5py.h5d.CHUNKED else None
        if chunks:
            filtered = layout.get_nfilters() > 0
            dapl = h5py.h5p.create(h5py.h5p.DATASET_ACCESS)
            nslots, _, w0 = dapl.get_chunk_cache()
            dapl.set_chunk_cache(nslots, int(np.prod(chunks)) * itemsize if filtered else 0,
                                 w0)
            ds = h5py.Dataset(h5py.h5d.open(group.id, key.encode(), dapl=dapl))
    except Exception:  # an HDF5 or h5py without per-dataset access lists
        ds = None
    return ds if ds is not None else group[key]


class _H5Table(_Table):
    """HDF5 (project layout or mapped) and MATLAB v7.3: datasets below a group, sliced."""

    def __init__(self, path: Path, group: str | None, *, mat: bool) -> None:
        import h5py

        from torquemod.io import hdf5 as hdf5_io
        from torquemod.io import matlab as matlab_io
        self.path, self.mat = path, mat
        try:
            self.fh = h5py.File(path, "r")
        except Exception as exc:  # OSError for non-HDF5 or truncated files
            raise library_error(exc, path=path, what="cannot open as HDF5",
                                hint="is the file complete and really HDF5?") from None
        where = ("/".join(matlab_io._parts(group)) or "/") if (mat and group) else (group or "/")
        g = self.fh.get(where)
        if not isinstance(g, h5py.Group):
            self.fh.close()
            raise InputError(f"no group '{where}' in the file", path=path,
                             hint="check the 'group' entry in the manifest")
        self.g = g
        self._ds: dict[str, object] = {}
        self._layouts: dict[str, object] = {}  # name -> _h5planes.PlaneLayout or None
        if mat:
            def scalar(n: str):
                return matlab_io._read_dataset(g, n, path)
            self.native_rate = matlab_io._native_rate(scalar, path)
        else:
            self.native_rate = hdf5_io._group_rate(g, path)

    def _dataset(self, name: str):
        import h5py
        if name not in self._ds:
            key = "/".join(p for p in name.replace(".", "/").split("/") if p) if self.mat \
                else name
            kind = self.g.get(key, getclass=True) if key else None
            self._ds[name] = _dataset_for_stream(self.g, key) if kind is h5py.Dataset else None
        return self._ds[name]

    def has(self, name: str) -> bool:
        return self._dataset(name) is not None

    def unit(self, name: str) -> str | None:
        from torquemod.io import hdf5 as hdf5_io
        ds = self._dataset(name)
        return None if self.mat or "unit" not in ds.attrs else hdf5_io._attr_text(
            ds.attrs["unit"])

    def column_length(self, name: str) -> int:
        shape = self._dataset(name).shape
        if len(shape) == 1 or (len(shape) == 2 and min(shape) == 1):
            return int(max(shape)) if shape else 0
        raise InputError(f"expected a 1-D signal, got shape {shape}", path=self.path,
                         channel=name, hint="map a vector (one value per sample)")

    def read(self, names: list[str], a: int, b: int) -> dict[str, np.ndarray]:
        out = {}
        for name in names:
            ds = self._dataset(name)
            try:
                if len(ds.shape) == 1:
                    values = ds[a:b]
                elif ds.shape[0] == 1:
                    values = ds[0, a:b]
                else:
                    values = ds[a:b, 0]
            except Exception as exc:  # h5py on damaged chunks
                raise library_error(exc, path=self.path, what=f"cannot read '{name}'",
                                    hint="is the file complete?") from None
            out[name] = self._scaled(name, ds, np.asarray(values))
        return out

    def _scaled(self, name: str, ds, values: np.ndarray) -> np.ndarray:
        """``values`` with the CF scale/offset the whole-file reader applies (HDF5)."""
        from torquemod.io import hdf5 as hdf5_io
        if not self.mat:
            scale = [hdf5_io._attr_number(ds, k, name, self.path)
                     for k in ("scale_factor", "add_offset")]
            if scale != [None, None] and values.dtype.kind in "biuf":
                values = values.astype(np.float64)
                if scale[0] is not None:
                    values *= scale[0]
                if scale[1] is not None:
                    values += scale[1]
        return values

    def blocks(self, names: list[str], chunk_rows: int) -> Iterator[dict[str, np.ndarray]]:
        """As :meth:`_Table.blocks`; datasets in large deflate-compressed chunks are decoded
        by planes as the rows are read (:mod:`torquemod.io._h5planes`), the others read
        through HDF5."""
        from torquemod.io import _h5planes
        for name in names:
            if name not in self._layouts:
                ds = self._dataset(name)
                self._layouts[name] = _h5planes.plane_layout(ds) if ds is not None else None
        planes = [name for name in names if self._layouts[name] is not None]
        if not planes:
            yield from super().blocks(names, chunk_rows)
            return
        rest = [name for name in names if name not in planes]
        n = self.length()
        with open(self.path, "rb") as raw:  # this pass's own handle: passes may interleave
            readers = {name: _h5planes.PlaneReader(self._layouts[name], raw) for name in planes}
            for a in range(0, n, chunk_rows):
                b = min(n, a + chunk_rows)
                out = self.read(rest, a, b)
                for name, reader in readers.items():
                    try:
                        values = reader.rows(a, b)
                    except Exception as exc:  # zlib, a chunk ending early, the file
                        raise library_error(exc, path=self.path, what=f"cannot read '{name}'",
                                            hint="is the file complete?") from None
                    out[name] = self._scaled(name, self._dataset(name), values)
                yield {name: out[name] for name in names}

    def close(self) -> None:
        self.fh.close()


class _ParquetTable(_Table):
    """Parquet: row batches of the wanted columns (``ParquetFile.iter_batches``)."""

    def __init__(self, path: Path, group: str | None) -> None:
        import pyarrow.parquet as pq

        from torquemod.io import parquet as parquet_io
        if group is not None:
            raise InputError(f"'group' ({group!r}) has no meaning for a Parquet file",
                             path=path, hint="remove 'group' from the recording's entry")
        self.path = path
        try:
            # pre_buffer (pyarrow's default) reads ahead the column chunks of every row group
            # an iteration covers and holds them until it ends: iter_batches over a 10-min
            # float32 recording held the whole file (220 MiB) by the end; without it, one
            # row group is held at a time (36 MiB there)
            self.pf = pq.ParquetFile(path, pre_buffer=False)
            self.schema = self.pf.schema_arrow
        except Exception as exc:  # ArrowInvalid/OSError on damaged files
            raise library_error(exc, path=path, what="cannot open as Parquet",
                                hint="is the file complete and really Parquet?") from None
        self.n_rows = int(self.pf.metadata.num_rows)
        self.native_rate = parquet_io._native_rate(self.schema.metadata, path)

    def has(self, name: str) -> bool:
        return name in self.schema.names

    def column_length(self, name: str) -> int:
        return self.n_rows

    def unit(self, name: str) -> str | None:
        from torquemod.io import parquet as parquet_io
        return parquet_io._meta_text(self.schema.field(name).metadata, "unit")

    def blocks(self, names: list[str], chunk_rows: int) -> Iterator[dict[str, np.ndarray]]:
        import pyarrow as pa

        from torquemod.io import parquet as parquet_io
        try:
            for batch in self.pf.iter_batches(batch_size=chunk_rows, columns=names):
                yield {n: parquet_io._column_values(pa.chunked_array([batch.column(n)]),
                                                    self.path, n) for n in names}
        except InputError:
            raise
        except Exception as exc:  # damaged pages, bad compression
            raise library_error(exc, path=self.path, what="cannot read the Parquet data",
                                hint="is the file complete and really Parquet?") from None


class _CsvTable(_Table):
    """CSV: pyarrow's streaming reader, one block of text at a time."""

    sequential = True

    def __init__(self, path: Path, group: str | None) -> None:
        from torquemod.io import csv as csv_io
        self.path = path
        self.header = csv_io._header(path)
        self.first_name = self.header[0]

    def has(self, name: str) -> bool:
        return name in self.header

    def blocks(self, names: list[str], chunk_rows: int) -> Iterator[dict[str, np.ndarray]]:
        import pyarrow as pa
        from pyarrow import csv as pa_csv
        try:
            reader = pa_csv.open_csv(
                self.path,
                read_options=pa_csv.ReadOptions(use_threads=False,
                                                block_size=CSV_BLOCK_BYTES),
                convert_options=pa_csv.ConvertOptions(
                    include_columns=names, column_types={n: pa.float64() for n in names}))
            for batch in reader:
                yield {n: batch.column(n).to_numpy(zero_copy_only=False) for n in names}
        except Exception as exc:  # pyarrow's own errors for malformed text
            raise library_error(exc, path=self.path, what="cannot parse as CSV",
                                hint="check for truncated lines or text in numeric "
                                     "columns") from None


class _TdmsTable(_Table):
    """TDMS: channel slices of a file opened for streaming (nptdms ``TdmsFile.open``)."""

    def __init__(self, path: Path, group: str | None) -> None:
        from torquemod.io import tdms as tdms_io
        nptdms = tdms_io._import_nptdms(path)
        self.path = path
        try:
            self.fh = open(path, "rb")
        except OSError as exc:
            raise InputError(f"cannot open ({exc.strerror})", path=path) from None
        try:
            self.tdms = nptdms.TdmsFile.open(self.fh)
            self.index = tdms_io._Index(self.tdms, path, group)
        except InputError:
            self.fh.close()
            raise
        except Exception as exc:  # nptdms on damage
            self.fh.close()
            raise library_error(exc, path=path, what="cannot open as TDMS",
                                hint="is the file complete and really TDMS?") from None

    def has(self, name: str) -> bool:
        return self.index.find(name) is not None

    def unit(self, name: str) -> str | None:
        unit = self.index.find(name).properties.get("unit_string")
        return unit if isinstance(unit, str) else None

    def own_base(self, name: str) -> tuple | None:
        from torquemod.io import tdms as tdms_io
        fs, t0 = tdms_io._wf_rate(dict(self.index.find(name).properties), self.path, name)
        return None if fs is None else ("rate", fs, t0)

    def column_length(self, name: str) -> int:
        return len(self.index.find(name))

    def read(self, names: list[str], a: int, b: int) -> dict[str, np.ndarray]:
        try:
            return {n: np.asarray(self.index.find(n)[a:b]) for n in names}
        except Exception as exc:  # nptdms on damaged segments
            raise library_error(exc, path=self.path, what="cannot read the TDMS data",
                                hint="is the file complete and really TDMS?") from None

    def close(self) -> None:
        self.fh.close()


class _MdfTable(_Table):
    """MDF: record ranges of one channel group (asammdf ``get(record_offset=,
    record_count=)``); the group's master channel is the time base."""

    def __init__(self, path: Path, group: str | None) -> None:
        from torquemod.io import mdf as mdf_io
        asammdf = mdf_io._import_asammdf(path)
        self.path = path
        self.fh, self.mdf = _mdf_on_file_object(asammdf, path)
        if self.mdf is None:  # a file asammdf reads only by name (or a damaged one)
            self.mdf, error = mdf_io._open(asammdf, path)
            if error is not None:
                raise error
        try:
            self.index = mdf_io._Index(self.mdf, path, group)
        except Exception:
            self.close()
            raise

    def _where(self, name: str) -> tuple[int, int] | None:
        idx = self.index
        occ = [o for o in idx.db.get(name, []) if idx.group is None or o[0] == idx.group]
        if not occ:
            return None
        if len({g for g, _ in occ}) > 1:
            raise InputError(f"channel '{name}' is in several channel groups",
                             path=self.path,
                             hint="set the recording's 'group' to the channel-group index")
        return occ[0]

    def has(self, name: str) -> bool:
        return self._where(name) is not None

    def _get(self, name: str, a: int, count: int):
        g, i = self._where(name)
        try:
            return self.mdf.get(name, group=g, index=i, record_offset=a, record_count=count)
        except Exception as exc:  # asammdf on damaged data blocks
            raise library_error(exc, path=self.path, what=f"cannot read channel '{name}'",
                                hint="is the file complete and really MDF?") from None

    def unit(self, name: str) -> str | None:
        unit = self._get(name, 0, 1).unit
        return unit if isinstance(unit, str) else None

    def own_base(self, name: str) -> tuple | None:
        return ("stamps", self._where(name)[0])

    def column_length(self, name: str) -> int:
        return int(self.mdf.groups[self._where(name)[0]].channel_group.cycles_nr)

    def stamps_blocks(self, key: object, chunk_rows: int) -> Iterator[np.ndarray]:
        n = int(self.mdf.groups[key].channel_group.cycles_nr)
        for a in range(0, n, chunk_rows):
            yield np.asarray(self.mdf.get_master(key, record_offset=a,
                                                 record_count=min(chunk_rows, n - a)),
                             dtype=np.float64)

    def read(self, names: list[str], a: int, b: int) -> dict[str, np.ndarray]:
        return {n: np.asarray(self._get(n, a, b - a).samples) for n in names}

    def close(self) -> None:
        try:
            self.mdf.close()
        except Exception:  # closing a damaged file
            pass
        if self.fh is not None:
            self.fh.close()


def _mdf_on_file_object(asammdf, path: Path):
    """``(file, MDF)`` of ``path`` opened by asammdf from an open file object, or
    ``(None, None)`` when that fails.

    Given a file name, asammdf (8.x) memory-maps the file and answers ``get`` with a record
    range by reading the channel's and the master's whole data and slicing them (for channel
    groups of 200 MiB or more): a stream of 65 536-row blocks then read the whole file once
    per block and channel (``process`` on a 10-min recording: 143 CPU-s, 1.4 GiB resident).
    Given a file object it reads only the data blocks that hold the range.
    """
    from torquemod.io import mdf as mdf_io
    try:
        fh = open(path, "rb")
    except OSError:
        return None, None
    mdf, error = mdf_io._open(asammdf, fh)  # hides a half-built MDF's finalizer errors
    if error is None:
        return fh, mdf
    fh.close()  # the caller opens it by name and reports what is wrong
    return None, None


def _open_table(path: Path, group: str | None) -> _Table:
    suffix = path.suffix.lower()
    if suffix in (".h5", ".hdf5"):
        return _H5Table(path, group, mat=False)
    if suffix == ".mat":
        from torquemod.io import matlab as matlab_io
        if not matlab_io.is_mat73(path):
            raise InputError("a MATLAB v4-v7 file cannot be streamed (its variables are "
                             "compressed whole)", path=path,
                             hint="save it with -v7.3, or read it whole")
        return _H5Table(path, group, mat=True)
    if suffix in (".parquet", ".pq"):
        return _ParquetTable(path, group)
    if suffix in (".csv", ".txt"):
        return _CsvTable(path, group)
    if suffix == ".tdms":
        return _TdmsTable(path, group)
    if suffix in (".mf4", ".mdf"):
        return _MdfTable(path, group)
    raise InputError(f"no streaming reader for '{suffix}' files", path=path,
                     hint="read it whole with torquemod.io.read_recording")


