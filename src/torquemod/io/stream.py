"""Streaming readers: a recording delivered in chunks of rows, in constant memory.

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

:meth:`RecordingStream.revolutions` splits a long recording into its platform revolutions
(the pipeline's cycles) in one pass, holding at most a revolution and a chunk, with the same
index ranges and samples as the whole-file split, so the chain's results on them are the
whole-file results.

:func:`hash_file_async` hashes a file in a background thread (hashlib releases the GIL), so
the input digest costs no separate pass after reading.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from torquemod._util.fsutil import sha256_file
from torquemod.errors import InputError
from torquemod.io._stream_tables import DEFAULT_CHUNK_ROWS, _open_table, _Table
from torquemod.io.channels import (
    TIME,
    ChannelMap,
    RawChannel,
    _converted,
    resolve_channel_map,
    source_name,
)
from torquemod.io.experiment import CHANNELS, OPTIONAL_CHANNELS, Recording, RecordingEntry
from torquemod.io.validate import fit_time_grid_blocks

#: ``fill(first row, chunk) -> chunk`` of :meth:`RecordingStream.chunks`.
_Fill = Callable[[int, dict[str, np.ndarray]], dict[str, np.ndarray]]

_REFUSE_HINT = ("read the file whole (torquemod.io.read_recording) or convert it to one "
                "time base first (torquemod convert)")


# ------------------------------------------------------------------------------ stream
@dataclass(frozen=True)
class StreamInfo:
    """What a stream delivers.

    Attributes
    ----------
    path : pathlib.Path
        The file.
    source : str
        ``Recording.source`` of the same file.
    fs_hz : float
        Sample rate [Hz].
    t0_s : float
        Time of the first sample [s]; sample k at ``t0_s + k/fs_hz``.
    n_samples : int
        Samples per channel [-].
    channels : tuple of str
        The method channels present (SI units).
    file_names : dict
        The file's name of each method channel.
    """

    path: Path
    source: str
    fs_hz: float
    t0_s: float
    n_samples: int
    channels: tuple[str, ...]
    file_names: dict = field(default_factory=dict)  # method channel -> name in the file


class RecordingStream:
    """An open recording read in chunks; use as a context manager (closes the file).

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    group : str or None
        A group inside the file (per format, :func:`~torquemod.io.recording.read_recording`).
    channel_map : ChannelMap or dict or None
        The ``[channels]`` table (raw or resolved); None: the method's names in SI units.
    sample_rate_hz : float or None
        Sample rate [Hz] overriding the file's time base. Default None.

    Raises
    ------
    InputError
        The file is missing or unreadable, a channel is missing, the forces lack Fx or Fz,
        the channels are on different time bases (streaming cannot align them: read the file
        whole), or the time base is unusable.
    """

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
               chunk_rows: int = DEFAULT_CHUNK_ROWS, *, fill: _Fill | None = None
               ) -> Iterator[dict[str, np.ndarray]]:
        """Chunks of ``chunk_rows`` rows (the last one shorter) of ``channels`` (default all
        the file has), each a dict of float64 arrays in SI units; ``fill(first row, chunk)``,
        if given, maps each chunk to what is delivered (e.g. its NaN/inf samples filled,
        :meth:`torquemod.processing.nanfill.NonFiniteRuns.fill`)."""
        if chunk_rows < 1:
            raise ValueError("chunk_rows must be positive")
        want = list(self.info.channels if channels is None else channels)
        missing = [c for c in want if c not in self.info.file_names]
        if missing:
            raise InputError(f"channel(s) {', '.join(missing)} not in the recording",
                             path=self.path, channel=missing[0])
        names = {c: self.info.file_names[c] for c in want}
        file_cols = list(dict.fromkeys(names.values()))

        def delivered(chunk: dict[str, np.ndarray], first_row: int) -> dict[str, np.ndarray]:
            values = self._convert(chunk, names)
            return values if fill is None else fill(first_row, values)

        pending: list[dict[str, np.ndarray]] = []
        held = pos = 0
        for block in self.table.blocks(file_cols, chunk_rows):
            pending.append(block)
            held += next(iter(block.values())).size
            while held >= chunk_rows:
                chunk, pending, held = _take(pending, chunk_rows, held)
                yield delivered(chunk, pos)
                pos += chunk_rows
        if held:
            chunk, pending, held = _take(pending, held, held)
            yield delivered(chunk, pos)

    def revolutions(self, chunk_rows: int = DEFAULT_CHUNK_ROWS,
                    channels: tuple[str, ...] | list[str] | None = None, *,
                    fill: _Fill | None = None
                    ) -> Iterator[tuple[int, Recording, tuple[int, int]]]:
        """``(k, recording of revolution k, (start, stop))`` for every whole platform
        revolution, k = 1, 2, ..., read in one pass holding at most a revolution and a
        chunk: the same index ranges as :func:`torquemod.processing.cycles.revolution_bounds` on the
        whole platform speed (the angle is the same trapezoidal sum, accumulated in the same
        order, so bit for bit the same) and the same samples as ``Recording.slice``. After
        the last one, ``self.tail_samples`` holds the samples of the partial revolution
        left at the end. ``channels`` (default all) limits what is read and delivered; it
        must hold ``platform_speed_rad_s`` (only that one finds the ranges cheaply). ``fill``
        maps the chunks as in :meth:`chunks` before the revolutions are cut from them."""
        info = self.info
        if channels is not None and "platform_speed_rad_s" not in channels:
            raise ValueError("channels must include platform_speed_rad_s")
        if "platform_speed_rad_s" not in info.file_names:
            raise InputError("no platform speed to split the file by revolutions",
                             path=self.path, channel="platform_speed_rad_s",
                             hint="give the recording's 'cycle' in the manifest")
        fs = info.fs_hz
        dx = 1.0 / fs
        held: dict[str, np.ndarray] | None = None
        held_start = 0  # global row of held[...][0]
        pos = 0  # rows seen
        carry, w_last = 0.0, 0.0  # angle [rad] and speed at the last row seen
        k, edge, count = 1, 0, 0
        self.tail_samples = 0

        def cut(b: int) -> Recording:
            a = edge
            ch = {c: v[a - held_start:b - held_start].copy() for c, v in held.items()}
            return Recording(ch, fs, info.t0_s + a / fs, info.source, [])

        for chunk in self.chunks(channels, chunk_rows, fill=fill):
            w = chunk["platform_speed_rad_s"]
            if pos == 0:
                ang = np.cumsum(np.concatenate(([0.0], dx * (w[1:] + w[:-1]) / 2.0)))
            else:
                ww = np.concatenate(([w_last], w))
                ang = np.cumsum(np.concatenate(([carry], dx * (ww[1:] + ww[:-1]) / 2.0)))[1:]
            if held is None:
                held = chunk
            else:
                held = {c: np.concatenate((held[c][edge - held_start:], v))
                        for c, v in chunk.items()}
                held_start = edge
            while 2 * np.pi * k <= ang[-1]:
                target = 2 * np.pi * k
                i = int(np.searchsorted(ang, target))
                a_before = ang[i - 1] if i > 0 else (carry if pos > 0 else ang[0])
                b = pos + i - 1 if abs(a_before - target) < abs(ang[i] - target) \
                    else pos + i
                if b > edge:
                    count += 1
                    yield count, cut(b), (edge, b)
                    edge = b
                k += 1
            carry, w_last = float(ang[-1]), float(w[-1])
            pos += w.size
        if held is None:
            return
        end = carry + w_last / fs  # the end of the last sample's interval
        n_rev = int(np.floor((end + abs(w_last) / fs) / (2 * np.pi)))
        while k <= n_rev:  # reached only within the last sample's interval
            target = 2 * np.pi * k
            b = pos - 1 if abs(carry - target) < abs(end - target) else pos
            if b > edge:
                count += 1
                yield count, cut(b), (edge, b)
                edge = b
            k += 1
        self.tail_samples = pos - edge

    @property
    def random_access(self) -> bool:
        """Whether :meth:`read_rows` reads just the rows asked for (HDF5, .mat v7.3, TDMS,
        MDF4) rather than every row up to them (Parquet, CSV)."""
        return type(self.table).read is not _Table.read

    def read_rows(self, start: int, stop: int,
                  channels: tuple[str, ...] | list[str] | None = None) -> Recording:
        """Rows ``start:stop`` of ``channels`` (default all the file has) as a Recording:
        the values and time base (``t0_s + start/fs_hz``) of the same rows of
        :meth:`chunks` and :meth:`revolutions`. Formats with random access (HDF5, .mat
        v7.3, TDMS, MDF4) read just those rows; Parquet and CSV are read in order up to
        ``stop``."""
        info = self.info
        if not 0 <= start < stop <= info.n_samples:
            raise ValueError(f"rows {start}:{stop} outside 0:{info.n_samples}")
        want = list(info.channels if channels is None else channels)
        missing = [c for c in want if c not in info.file_names]
        if missing:
            raise InputError(f"channel(s) {', '.join(missing)} not in the recording",
                             path=self.path, channel=missing[0])
        names = {c: info.file_names[c] for c in want}
        if self.random_access:
            raw = self.table.read(list(dict.fromkeys(names.values())), start, stop)
            ch = self._convert(raw, names)
        else:
            parts: dict[str, list[np.ndarray]] = {c: [] for c in want}
            pos = 0
            for chunk in self.chunks(want):
                n = next(iter(chunk.values())).size
                if pos + n > start:
                    for c, v in chunk.items():
                        parts[c].append(v[max(0, start - pos):stop - pos])
                pos += n
                if pos >= stop:
                    break
            ch = {c: np.concatenate(v) if len(v) > 1 else v[0].copy()
                  for c, v in parts.items()}
        return Recording(ch, info.fs_hz, info.t0_s + start / info.fs_hz, info.source, [])

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
    """A :class:`RecordingStream` of a path or of a manifest's ``[[recording]]`` entry.

    Parameters
    ----------
    entry_or_path : RecordingEntry or str or pathlib.Path
        The entry (its file, group and sample rate) or a path.
    experiment : Experiment or None
        Whose ``[channels]`` map applies to an entry. Default None.
    group : str or None
        A group inside the file (per format, :func:`~torquemod.io.recording.read_recording`).
    channel_map : ChannelMap or dict or None
        The ``[channels]`` table (raw or resolved); None: the method's names in SI units.
    sample_rate_hz : float or None
        Sample rate [Hz] overriding the file's time base. Default None.

    Returns
    -------
    RecordingStream
        The open stream.

    Raises
    ------
    InputError
        As :class:`RecordingStream`.
    """
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
    """Chunks of rows of a recording; the file stays open while the iterator runs.

    Parameters
    ----------
    entry_or_path : RecordingEntry or str or pathlib.Path
        The entry or a path.
    channels : sequence of str or None
        The method channels wanted; None: all present.
    chunk_rows : int
        Rows per chunk [-]. Default :data:`DEFAULT_CHUNK_ROWS`.
    experiment : Experiment or None
        Whose ``[channels]`` map applies to an entry. Default None.
    group : str or None
        A group inside the file (per format, :func:`~torquemod.io.recording.read_recording`).
    channel_map : ChannelMap or dict or None
        The ``[channels]`` table (raw or resolved); None: the method's names in SI units.
    sample_rate_hz : float or None
        Sample rate [Hz] overriding the file's time base. Default None.

    Yields
    ------
    dict of str to ndarray
        Each channel's rows, float64 in SI units.

    Raises
    ------
    InputError
        As :class:`RecordingStream`, or a channel asked for is not in the recording.
    ValueError
        ``chunk_rows`` is not positive.
    """
    with open_stream(entry_or_path, experiment=experiment, group=group,
                     channel_map=channel_map, sample_rate_hz=sample_rate_hz) as stream:
        yield from stream.chunks(channels, chunk_rows)


# ------------------------------------------------------------------------------ hashing
_HASH_POOL: ThreadPoolExecutor | None = None


def hash_file_async(path: str | Path, *, block: int = 1 << 22) -> Future:
    """Start hashing a file (SHA-256) in a background thread.

    hashlib releases the GIL while it hashes, so reading and processing go on.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    block : int
        Bytes read at a time [B]. Default 4 MiB.

    Returns
    -------
    concurrent.futures.Future
        ``.result()`` gives the hex digest.
    """
    global _HASH_POOL
    if _HASH_POOL is None:
        _HASH_POOL = ThreadPoolExecutor(max_workers=2, thread_name_prefix="torquemod-sha256")
    return _HASH_POOL.submit(sha256_file, Path(path), chunk=block)  # hashlib frees the GIL
