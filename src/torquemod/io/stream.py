"""Streaming readers (issue 11): a recording delivered in chunks of rows, in constant memory.

Every format the whole-file readers handle can be streamed: HDF5 and MATLAB v7.3 by dataset
slices (h5py), MDF4 by record ranges (asammdf ``MDF.get(record_offset=, record_count=)``),
TDMS by channel slices of a streamed file (nptdms ``TdmsFile.open``), Parquet by row batches
(``ParquetFile.iter_batches``) and CSV through pyarrow's streaming reader
(``pyarrow.csv.open_csv``). Each chunk is a dict of float64 arrays holding exactly the values
the whole-file reader (:func:`torquemod.io.read_recording`) gives for those rows: the same
``[channels]`` map, the same unit conversion (applied element by element, so per chunk it
is the same arithmetic), the same time base, found the same way (the manifest's sample rate,
a time column fitted in blocks by :func:`~torquemod.io.validate.fit_time_grid_blocks`, the
torque's own time base, the file's sample rate).

Streaming needs the channels on one time base. Channels on their own time bases (TDMS
channels with different offsets or rates, MDF channels in several channel groups, a
``time`` key in ``[channels]``) are put on a common base by the whole-file reader, which needs
the whole channel; they are refused here with a hint to read the file whole or convert it.

:func:`hash_file_async` hashes a file in a background thread (hashlib releases the GIL), so
the input digest costs no separate pass after reading.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data import CHANNELS, OPTIONAL_CHANNELS, RecordingEntry
from ..errors import InputError
from .channels import (
    TIME,
    ChannelMap,
    RawChannel,
    _converted,
    library_error,
    resolve_channel_map,
    source_name,
)
from .validate import fit_time_grid_blocks

DEFAULT_CHUNK_ROWS = 1 << 18  # 262 144 rows: 15.7 s at 16.67 kHz, 2 MiB per channel
CSV_BLOCK_BYTES = 1 << 22  # text parsed per step by pyarrow's streaming CSV reader
_REFUSE_HINT = ("read the file whole (torquemod.io.read_recording) or convert it to one "
                "time base first (torquemod convert)")


# ------------------------------------------------------------------------------ tables
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


class _H5Table(_Table):
    """HDF5 (project layout or mapped) and MATLAB v7.3: datasets below a group, sliced."""

    def __init__(self, path: Path, group: str | None, *, mat: bool) -> None:
        import h5py

        from . import hdf5 as hdf5_io
        from . import matlab as matlab_io
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
            obj = self.g.get(key) if key else None
            self._ds[name] = obj if isinstance(obj, h5py.Dataset) else None
        return self._ds[name]

    def has(self, name: str) -> bool:
        return self._dataset(name) is not None

    def unit(self, name: str) -> str | None:
        from . import hdf5 as hdf5_io
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
        from . import hdf5 as hdf5_io
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
                values = np.asarray(values)
                if not self.mat:  # CF scale/offset as the whole-file reader applies them
                    scale = [hdf5_io._attr_number(ds, k, name, self.path)
                             for k in ("scale_factor", "add_offset")]
                    if scale != [None, None] and values.dtype.kind in "biuf":
                        values = values.astype(np.float64)
                        if scale[0] is not None:
                            values *= scale[0]
                        if scale[1] is not None:
                            values += scale[1]
            except InputError:
                raise
            except Exception as exc:  # h5py on damaged chunks
                raise library_error(exc, path=self.path, what=f"cannot read '{name}'",
                                    hint="is the file complete?") from None
            out[name] = values
        return out

    def close(self) -> None:
        self.fh.close()


class _ParquetTable(_Table):
    """Parquet: row batches of the wanted columns (``ParquetFile.iter_batches``)."""

    def __init__(self, path: Path, group: str | None) -> None:
        import pyarrow.parquet as pq

        from . import parquet as parquet_io
        if group is not None:
            raise InputError(f"'group' ({group!r}) has no meaning for a Parquet file",
                             path=path, hint="remove 'group' from the recording's entry")
        self.path = path
        try:
            self.pf = pq.ParquetFile(path)
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
        from . import parquet as parquet_io
        return parquet_io._meta_text(self.schema.field(name).metadata, "unit")

    def blocks(self, names: list[str], chunk_rows: int) -> Iterator[dict[str, np.ndarray]]:
        import pyarrow as pa

        from . import parquet as parquet_io
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
        from . import csv as csv_io
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
        from . import tdms as tdms_io
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
        from . import tdms as tdms_io
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
        from . import mdf as mdf_io
        asammdf = mdf_io._import_asammdf(path)
        self.path = path
        self.mdf, error = mdf_io._open(asammdf, path)
        if error is not None:
            raise error
        try:
            self.index = mdf_io._Index(self.mdf, path, group)
        except Exception:
            self.mdf.close()
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


def _open_table(path: Path, group: str | None) -> _Table:
    suffix = path.suffix.lower()
    if suffix in (".h5", ".hdf5"):
        return _H5Table(path, group, mat=False)
    if suffix == ".mat":
        from . import matlab as matlab_io
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


# ------------------------------------------------------------------------------ stream
@dataclass(frozen=True)
class StreamInfo:
    """What a stream delivers: ``channels`` (method names, SI) on ``n_samples`` samples at
    ``fs_hz`` [Hz] from ``t0_s`` [s] (sample k at ``t0_s + k/fs_hz``)."""

    path: Path
    source: str
    fs_hz: float
    t0_s: float
    n_samples: int
    channels: tuple[str, ...]
    file_names: dict = field(default_factory=dict)  # method channel -> name in the file


class RecordingStream:
    """An open recording read in chunks; use as a context manager (closes the file)."""

    def __init__(self, path: str | Path, *, group: str | None = None,
                 channel_map: ChannelMap | dict | None = None,
                 sample_rate_hz: float | None = None) -> None:
        path = Path(path)
        if not path.is_file():
            raise InputError("recording file not found", path=path,
                             hint="check the 'file' entry in the manifest")
        self.path = path
        self.cmap = resolve_channel_map(channel_map, path).with_sample_rate(sample_rate_hz,
                                                                            path=path)
        self.table = _open_table(path, group)
        try:
            self.info = self._describe(source_name(path, group))
        except BaseException:
            self.table.close()
            raise

    def __enter__(self) -> RecordingStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self.table.close()

    # -- what is there and on which time base
    def _describe(self, source: str) -> StreamInfo:
        cmap, table, path = self.cmap, self.table, self.path
        found: dict[str, str] = {}
        for c in CHANNELS:
            spec = cmap.spec(c)
            if spec.time:
                raise InputError(f"'{spec.name}' has its own time vector '{spec.time}' in "
                                 "[channels]: channels on their own time base cannot be "
                                 "streamed", path=path, channel=c, hint=_REFUSE_HINT)
            if table.has(spec.name):
                found[c] = spec.name
            elif c not in OPTIONAL_CHANNELS or spec.explicit:
                raise InputError(f"no channel '{spec.name}' in the file", path=path, channel=c,
                                 hint="map it in the manifest's [channels] table")
        forces = [c for c in ("fx_n", "fz_n") if c in found]
        if len(forces) == 1 or ("fy_n" in found and not forces):
            raise InputError("the forces need Fx and Fz together (Fy is optional)",
                             path=path, channel="fz_n" if "fx_n" in found else "fx_n",
                             hint="map the missing force or leave all force channels out")
        self.units = {c: table.unit(n) for c, n in found.items()}
        if not table.sequential:
            lengths = {c: table.column_length(n) for c, n in found.items()}
            if len(set(lengths.values())) > 1:
                raise InputError(f"the channels have different lengths ({lengths}): they are "
                                 "not on one time base", path=path, hint=_REFUSE_HINT)
            table.n_rows = lengths["torque_nm"]
        table.first_name = found["torque_nm"]
        bases = {c: table.own_base(n) for c, n in found.items()}
        if len(set(bases.values())) > 1:
            raise InputError("the channels are on different time bases (offsets, rates or "
                             "channel groups), which streaming cannot align", path=path,
                             hint=_REFUSE_HINT)
        base = bases["torque_nm"]
        time_name = cmap.time.name
        if cmap.sample_rate_hz is not None:
            fs, t0 = cmap.sample_rate_hz, cmap.t0_s
        elif table.has(time_name):
            if base is not None:
                raise InputError(f"a time column '{time_name}' beside the channels' own "
                                 "time base", path=path, channel=TIME, hint=_REFUSE_HINT)
            spec, unit = cmap.time, table.unit(time_name)
            counted = [0]

            def stamps() -> Iterator[np.ndarray]:
                counted[0] = 0
                for b in table.blocks([time_name], DEFAULT_CHUNK_ROWS):
                    t = _converted(spec, RawChannel(b[time_name], unit), path)
                    counted[0] += t.size
                    yield t

            fs, anchor, rel = fit_time_grid_blocks(stamps, path=path, channel=TIME)
            t0 = anchor + rel
            if table.n_rows is None:  # a sequential file: the fit's pass counted the rows
                table.n_rows = counted[0]
        elif cmap.time.explicit:
            raise InputError(f"no time channel '{time_name}' in the file", path=path,
                             channel=TIME, hint="check [channels] time")
        elif base is not None and base[0] == "rate":
            fs, t0 = base[1], base[2]
        elif base is not None:
            fs, anchor, rel = fit_time_grid_blocks(
                lambda: table.stamps_blocks(base[1], DEFAULT_CHUNK_ROWS), path=path,
                channel="torque_nm")
            t0 = anchor + rel
        elif table.native_rate is not None:
            fs, t0 = table.native_rate
        else:
            raise InputError(f"no time base: no time channel '{time_name}' and no sample rate "
                             "in the file", path=path, channel=TIME,
                             hint="map 'time' or set sample_rate_hz (docs/format.md)")
        if not (math.isfinite(fs) and fs > 0 and math.isfinite(t0)):
            raise InputError(f"time base {fs} Hz from {t0} s is not usable", path=path,
                             channel=TIME)
        n = table.length()
        if n < 2:
            raise InputError(f"fewer than two samples ({n})", path=path, channel="torque_nm")
        return StreamInfo(path, source, float(fs), float(t0), int(n), tuple(found), found)

    # -- the chunks
    def chunks(self, channels: list[str] | tuple[str, ...] | None = None,
               chunk_rows: int = DEFAULT_CHUNK_ROWS) -> Iterator[dict[str, np.ndarray]]:
        """Chunks of ``chunk_rows`` rows (the last one shorter) of ``channels`` (default all
        the file has), each a dict of float64 arrays in SI units."""
        if chunk_rows < 1:
            raise ValueError("chunk_rows must be positive")
        want = list(self.info.channels if channels is None else channels)
        missing = [c for c in want if c not in self.info.file_names]
        if missing:
            raise InputError(f"channel(s) {', '.join(missing)} not in the recording",
                             path=self.path, channel=missing[0])
        names = {c: self.info.file_names[c] for c in want}
        file_cols = list(dict.fromkeys(names.values()))
        pending: list[dict[str, np.ndarray]] = []
        held = 0
        for block in self.table.blocks(file_cols, chunk_rows):
            pending.append(block)
            held += next(iter(block.values())).size
            while held >= chunk_rows:
                chunk, pending, held = _take(pending, chunk_rows, held)
                yield self._convert(chunk, names)
        if held:
            chunk, pending, held = _take(pending, held, held)
            yield self._convert(chunk, names)

    def _convert(self, raw: dict[str, np.ndarray], names: dict[str, str]
                 ) -> dict[str, np.ndarray]:
        out = {}
        for c, n in names.items():
            x = _converted(self.cmap.spec(c), RawChannel(raw[n], self.units[c]), self.path)
            out[c] = np.asarray(x, dtype=np.float64)
        return out


def _take(pending: list[dict[str, np.ndarray]], rows: int, held: int
          ) -> tuple[dict[str, np.ndarray], list[dict[str, np.ndarray]], int]:
    """The first ``rows`` rows of the queued blocks, and the rest."""
    out: dict[str, list[np.ndarray]] = {k: [] for k in pending[0]}
    need, rest = rows, []
    for i, block in enumerate(pending):
        size = next(iter(block.values())).size
        if need >= size:
            for k, v in block.items():
                out[k].append(v)
            need -= size
        else:
            if need:
                for k, v in block.items():
                    out[k].append(v[:need])
            rest = [{k: v[need:] for k, v in block.items()}, *pending[i + 1:]]
            need = 0
            break
        if need == 0:
            rest = pending[i + 1:]
            break
    chunk = {k: v[0] if len(v) == 1 else np.concatenate(v) for k, v in out.items()}
    return chunk, rest, held - rows


def open_stream(entry_or_path: RecordingEntry | str | Path, *, experiment=None,
                group: str | None = None, channel_map: ChannelMap | dict | None = None,
                sample_rate_hz: float | None = None) -> RecordingStream:
    """A :class:`RecordingStream` of a path, or of a manifest's ``[[recording]]`` entry (its
    group and sample rate; the ``experiment``'s ``[channels]`` map when given)."""
    if isinstance(entry_or_path, RecordingEntry):
        entry = entry_or_path
        return RecordingStream(entry.path, group=entry.group,
                               channel_map=(experiment.channel_map if experiment is not None
                                            else channel_map),
                               sample_rate_hz=entry.sample_rate_hz)
    return RecordingStream(entry_or_path, group=group, channel_map=channel_map,
                           sample_rate_hz=sample_rate_hz)


def iter_chunks(entry_or_path: RecordingEntry | str | Path,
                channels: list[str] | tuple[str, ...] | None = None,
                chunk_rows: int = DEFAULT_CHUNK_ROWS, *, experiment=None,
                group: str | None = None, channel_map: ChannelMap | dict | None = None,
                sample_rate_hz: float | None = None) -> Iterator[dict[str, np.ndarray]]:
    """Chunks of ``chunk_rows`` rows of a recording (see :class:`RecordingStream`); the file
    stays open while the iterator runs and is closed at its end."""
    with open_stream(entry_or_path, experiment=experiment, group=group,
                     channel_map=channel_map, sample_rate_hz=sample_rate_hz) as stream:
        yield from stream.chunks(channels, chunk_rows)


# ------------------------------------------------------------------------------ hashing
_HASH_POOL: ThreadPoolExecutor | None = None


def _sha256(path: Path, block: int) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while data := fh.read(block):
            h.update(data)  # releases the GIL for large blocks
    return h.hexdigest()


def hash_file_async(path: str | Path, *, block: int = 1 << 22) -> Future:
    """Start hashing a file (SHA-256, hex) in a background thread; ``.result()`` gives the
    digest. hashlib releases the GIL while it hashes, so reading and processing go on."""
    global _HASH_POOL
    if _HASH_POOL is None:
        _HASH_POOL = ThreadPoolExecutor(max_workers=2, thread_name_prefix="torquemod-sha256")
    return _HASH_POOL.submit(_sha256, Path(path), block)
