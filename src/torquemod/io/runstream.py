"""Train-run recordings read by row ranges, in constant memory.

A run's fast channels (``torque_nm``, ``wheel_speed_rad_s``: the logger's rate) are read by
row ranges through the streaming tables of :mod:`torquemod.io.stream` (HDF5 and MATLAB v7.3
slices, MDF4 record ranges, TDMS channel slices; Parquet and CSV by a pass over their
blocks). The slow channels (``vehicle_speed_m_s``, ``position_m``: a radar, GNSS or
odometer, often in their own MDF channel group or with their own time vector) are small
(a 10 Hz radar over 10 h is 360 000 samples) and are read whole, each with its own time
base, then brought onto the rows asked for with the whole-file reader's own functions
(:func:`torquemod.io.timebase._plan` and ``_interpolated``: linear interpolation at the
torque's sample times, or a whole-sample shift). Those act element by element, so every
row holds bit for bit the value :func:`torquemod.io.read_recording` gives for it; the time
base, the cut to the span all channels share and the notes are found the way
:func:`torquemod.io.timebase.assemble_recording` finds them (tests/io/test_onboard_stream.py
compares all of it with the whole-file reader on MDF4 and HDF5 twin runs).

Anything this module does not handle (a channel of the rig besides the run's, a sample rate
from the manifest together with a channel on its own time base, date-time stamps, a
time vector of a slow channel in a CSV or Parquet file, any error while opening) is read
whole with :func:`~torquemod.io.read_recording` instead, with a note saying so: never a
different answer, only more memory. Errors therefore carry the whole-file reader's message.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from torquemod.errors import InputError
from torquemod.io._stream_tables import DEFAULT_CHUNK_ROWS, _open_table, _Table
from torquemod.io.channels import (
    TIME,
    TORQUE,
    ChannelMap,
    RawChannel,
    _converted,
    resolve_channel_map,
)
from torquemod.io.experiment import CHANNELS, OPTIONAL_CHANNELS, Recording
from torquemod.io.recording import read_recording
from torquemod.io.timebase import (
    _Grid,
    _interpolated,
    _own_grid,
    _Plan,
    _plan,
    _with_own_time,
    note_cut,
    prepared,
    shared_span,
)
from torquemod.io.validate import TIME_FIT_BLOCK, fit_time_grid_blocks

#: The channels of a train run (docs/format.md), in :data:`~torquemod.io.experiment.CHANNELS` order.
RUN_CHANNELS = ("torque_nm", "wheel_speed_rad_s", "vehicle_speed_m_s", "position_m")
FAST_CHANNELS = RUN_CHANNELS[:2]


class _CannotStream(Exception):
    """This layout is read whole (the message says why)."""


class RunStream:
    """A run recording read by row ranges; a context manager.

    ``fs_hz`` [Hz], ``t0_s`` [s] (row k at ``t0_s + k/fs_hz``), ``n_samples``, ``channels``
    and ``notes`` are those of :func:`~torquemod.io.read_recording` on the same file;
    ``read(a, b)`` gives rows ``a..b-1`` of every channel (float64, SI), bit for bit the
    whole-file values. ``streamed`` is False when the file was read whole (the first note
    says why: a layout that cannot be read in parts).

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    group : str or None
        A group inside the file. Default None.
    channel_map : ChannelMap or dict or None
        The run's ``[channels]`` table; None: the method's names in SI units.
    sample_rate_hz : float or None
        Sample rate [Hz] overriding the file's time base. Default None.

    Raises
    ------
    InputError
        When the file is read whole, whatever :func:`~torquemod.io.read_recording` raises.
    """

    def __init__(self, path: str | Path, *, group: str | None = None,
                 channel_map: ChannelMap | dict | None = None,
                 sample_rate_hz: float | None = None) -> None:
        self.path = Path(path)
        self.group, self.channel_map, self.sample_rate_hz = group, channel_map, sample_rate_hz
        self.table: _Table | None = None
        self.rec: Recording | None = None
        try:
            self._open()
            self.streamed = True
        except (_CannotStream, InputError) as why:
            self.close()
            reason = str(why) if isinstance(why, _CannotStream) else "opening it streamed failed"
            self._whole(reason)

    # -- set-up
    def _whole(self, reason: str) -> None:
        rec = read_recording(self.path, group=self.group, channel_map=self.channel_map,
                             sample_rate_hz=self.sample_rate_hz)
        self.rec, self.streamed = rec, False
        self.fs_hz, self.t0_s, self.n_samples = rec.fs_hz, rec.t0_s, rec.n_samples
        self.channels = tuple(c for c in CHANNELS if c in rec.channels)
        self.notes = [f"read whole, not in chunks ({reason})", *rec.notes]

    def _open(self) -> None:
        path = self.path
        if not path.is_file() or path.suffix.lower() not in _SUFFIXES:
            raise _CannotStream("not a streamable file")
        cmap = resolve_channel_map(self.channel_map, path).with_sample_rate(
            self.sample_rate_hz, path=path)
        self.cmap = cmap
        table = self.table = _open_table(path, self.group)
        found: dict[str, str] = {}
        for c in CHANNELS:
            spec = cmap.spec(c)
            if table.has(spec.name):
                if c not in RUN_CHANNELS:
                    raise _CannotStream(f"it holds the rig channel '{spec.name}' too")
                found[c] = spec.name
            elif c not in OPTIONAL_CHANNELS or spec.explicit:
                raise _CannotStream(f"no channel '{spec.name}'")
        if TORQUE not in found or "wheel_speed_rad_s" not in found:
            raise _CannotStream("a required channel is missing")
        table.first_name = found[TORQUE]
        base = table.own_base(found[TORQUE])
        lookup = _whole_lookup(table, path)
        streamed, own = [], {}
        padding: list[str] = []
        for c, name in found.items():
            spec = cmap.spec(c)
            if c in FAST_CHANNELS or (not spec.time and table.own_base(name) == base):
                if spec.time or table.own_base(name) != base:
                    raise _CannotStream(f"'{name}' is not on {TORQUE}'s time base")
                streamed.append(c)
            elif lookup is None:
                raise _CannotStream(f"'{name}' has its own time base in a "
                                    f"{path.suffix} file")
            else:
                raw = lookup(name)
                own[c] = _with_own_time(spec, raw, lookup, path, None, padding)
        if not table.sequential:
            sizes = {table.column_length(found[c]) for c in streamed}
            if len(sizes) > 1:
                raise _CannotStream("the streamed channels differ in length")
            table.n_rows = sizes.pop()
        self.names = {c: found[c] for c in streamed}
        self.units = {c: table.unit(found[c]) for c in streamed}
        n = table.length()
        # notes in the whole-file order: the reader's, then the conversions', then alignment
        notes = [*_reader_notes(table), *padding]
        head = self._raw_rows(list(dict.fromkeys(self.names.values())), 0, min(n, 2))
        slow: dict[str, np.ndarray] = {}
        for c in found:
            if c in own:
                slow[c] = _converted(cmap.spec(c), own[c], path, notes)
            else:
                _converted(cmap.spec(c), RawChannel(head[self.names[c]], self.units[c]),
                           path, notes)
        if n < 2:
            raise _CannotStream("fewer than two samples")
        ref, grid = self._grids(base, n, bool(own))
        plans: dict[str, _Plan] = {}
        fitted: list = []
        for c, raw in own.items():
            g = _own_grid(raw, slow[c].size, path, c, fitted)
            if slow[c].size < 2:
                raise _CannotStream(f"'{found[c]}' has fewer than two samples")
            plans[c] = _plan(c, g, slow[c].size, ref, n, path)
        lo, hi = self._cut(plans, slow, ref, n, notes)
        self.plans, self.slow, self.lo = plans, slow, lo
        self.fs_hz = float(grid.fs_hz)
        self.t0_s = float(grid.t0_s + lo / grid.fs_hz)
        if not (math.isfinite(self.fs_hz) and self.fs_hz > 0 and math.isfinite(self.t0_s)):
            raise _CannotStream("no usable time base")
        self.n_samples = hi + 1 - lo
        self.channels = tuple(c for c in CHANNELS if c in found)
        self.notes = notes

    def _grids(self, base: tuple | None, n: int, has_own: bool) -> tuple[_Grid, _Grid]:
        """``(reference grid of the alignment, grid of the recording)`` by the precedence
        of ``assemble_recording``: manifest rate, time channel, torque's base, file rate."""
        cmap, table, path = self.cmap, self.table, self.path
        if cmap.sample_rate_hz is not None:
            if has_own:
                raise _CannotStream("a manifest sample rate with a channel on its own base")
            g = _Grid(cmap.sample_rate_hz, cmap.t0_s)
            return g, g
        spec = cmap.time
        if table.has(spec.name):
            if base is not None:
                raise _CannotStream("a time column beside the channels' own time base")
            unit = table.unit(spec.name)
            first = self._raw_rows([spec.name], 0, min(n, 2))[spec.name]
            if first.dtype.kind in "mM":
                raise _CannotStream("date-time stamps")
            count = [0]

            def stamps() -> Iterator[np.ndarray]:
                count[0] = 0
                for b in _reblocked(self._blocks([spec.name]), spec.name, TIME_FIT_BLOCK):
                    count[0] += b.size
                    yield _converted(spec, RawChannel(b, unit), path)

            fs, anchor, rel = fit_time_grid_blocks(stamps, path=path, channel=TIME)
            if count[0] != n:
                raise _CannotStream("the time column's length differs")
            g = _Grid(fs, anchor, rel)
            return g, g
        if spec.explicit:
            raise _CannotStream(f"no time channel '{spec.name}'")
        if base is not None and base[0] == "rate":
            g = _Grid(float(base[1]), float(base[2]))
            if not (math.isfinite(g.fs_hz) and g.fs_hz > 0 and math.isfinite(g.t0_s)):
                raise _CannotStream("the torque's time base is not usable")
            return g, g
        if base is not None:
            fs, anchor, rel = fit_time_grid_blocks(
                lambda: table.stamps_blocks(base[1], TIME_FIT_BLOCK), path=path,
                channel=TORQUE)
            g = _Grid(fs, anchor, rel)
            return g, g
        if table.native_rate is not None:
            g = _Grid(float(table.native_rate[0]), float(table.native_rate[1]))
            return g, g
        raise _CannotStream("no time base")

    def _cut(self, plans: dict[str, _Plan], slow: dict[str, np.ndarray], ref: _Grid, n: int,
             notes: list[str]) -> tuple[int, int]:
        """First and last torque row kept, and the notes, as ``timebase._align`` gives them
        (the slow channels faster than the torque are low-passed here, whole)."""
        span = shared_span(plans, ref, n, self.path)
        if span is None:
            return 0, n - 1
        lo, hi = span
        for c in RUN_CHANNELS:
            if c in plans:
                slow[c] = prepared(c, slow[c], plans[c], ref, notes)
        note_cut(lo, hi, n, notes)
        return lo, hi

    # -- raw access
    def _blocks(self, names: list[str]) -> Iterator[dict[str, np.ndarray]]:
        return self.table.blocks(names, DEFAULT_CHUNK_ROWS)

    def _raw_rows(self, names: list[str], a: int, b: int) -> dict[str, np.ndarray]:
        """Raw values of file rows ``a..b-1`` (a pass over the blocks of sequential files)."""
        table = self.table
        if type(table).read is not _Table.read:
            return table.read(names, a, b) if b > a else {k: np.zeros(0) for k in names}
        parts: dict[str, list[np.ndarray]] = {k: [] for k in names}
        pos = 0
        for block in self._blocks(names):
            size = next(iter(block.values())).size
            if pos + size > a and pos < b:
                for k in names:
                    parts[k].append(np.asarray(block[k])[max(a - pos, 0):b - pos])
            pos += size
            if pos >= b:
                break
        return {k: np.concatenate(v) if v else np.zeros(0) for k, v in parts.items()}

    # -- rows
    def read(self, a: int, b: int, channels: tuple[str, ...] | None = None
             ) -> dict[str, np.ndarray]:
        """Rows ``a..b-1`` (0 <= a <= b <= n_samples) of every channel (or of
        ``channels`` only: the slow ones then need no file access), float64 in SI."""
        if not 0 <= a <= b <= self.n_samples:
            raise ValueError(f"rows {a}..{b} outside 0..{self.n_samples}")
        want = self.channels if channels is None else tuple(
            c for c in self.channels if c in channels)
        if self.rec is not None:
            return {c: self.rec.channels[c][a:b] for c in want}
        out: dict[str, np.ndarray] = {}
        fa, fb = self.lo + a, self.lo + b
        names = {c: name for c, name in self.names.items() if c in want}
        raw = self._raw_rows(list(dict.fromkeys(names.values())), fa, fb) if names else {}
        for c, name in names.items():
            x = _converted(self.cmap.spec(c), RawChannel(raw[name], self.units[c]), self.path)
            out[c] = np.asarray(x, dtype=np.float64)
        for c, plan in self.plans.items():
            if c not in want:
                continue
            x = self.slow[c]
            if plan.shift is not None:
                out[c] = x[fa - plan.shift:fb - plan.shift]
            elif fb > fa:
                out[c] = _interpolated(x, plan, fa, fb - 1)
            else:
                out[c] = np.zeros(0)
        return {c: out[c] for c in want}

    def chunks(self, chunk_rows: int, start: int = 0, stop: int | None = None
               ) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        """``(first row, rows)`` of consecutive chunks of ``chunk_rows`` rows from ``start``
        to ``stop`` (default: the end)."""
        if chunk_rows < 1:
            raise ValueError("chunk_rows must be positive")
        stop = self.n_samples if stop is None else stop
        if self.rec is not None or type(self.table).read is not _Table.read:
            for a in range(start, stop, chunk_rows):
                yield a, self.read(a, min(stop, a + chunk_rows))
            return
        # a sequential file: one pass, skipping to ``start``
        names = list(dict.fromkeys(self.names.values()))
        pending: list[dict[str, np.ndarray]] = []
        pos, a = 0, start
        for block in self._blocks(names):
            size = next(iter(block.values())).size
            lo_f, hi_f = self.lo + a, self.lo + stop
            if pos + size > lo_f and pos < hi_f:
                pending.append({k: np.asarray(v)[max(lo_f - pos, 0):hi_f - pos]
                                for k, v in block.items()})
            pos += size
            while pending and (sum(p[names[0]].size for p in pending) >= chunk_rows
                               or pos >= hi_f):
                raw = {k: np.concatenate([p[k] for p in pending]) for k in names}
                take = min(chunk_rows, raw[names[0]].size)
                yield a, self._rows_from_raw({k: v[:take] for k, v in raw.items()}, a)
                a += take
                pending = [{k: v[take:] for k, v in raw.items()}] if raw[names[0]].size > take \
                    else []
                if a >= stop:
                    return

    def _rows_from_raw(self, raw: dict[str, np.ndarray], a: int) -> dict[str, np.ndarray]:
        b = a + next(iter(raw.values())).size
        out: dict[str, np.ndarray] = {}
        for c, name in self.names.items():
            x = _converted(self.cmap.spec(c), RawChannel(raw[name], self.units[c]), self.path)
            out[c] = np.asarray(x, dtype=np.float64)
        fa, fb = self.lo + a, self.lo + b
        for c, plan in self.plans.items():
            x = self.slow[c]
            out[c] = x[fa - plan.shift:fb - plan.shift] if plan.shift is not None \
                else _interpolated(x, plan, fa, fb - 1)
        return {c: out[c] for c in self.channels}

    @property
    def random_access(self) -> bool:
        """Whether ``read`` reaches any rows directly (HDF5, MAT v7.3, MDF4, TDMS, or read
        whole), rather than by a pass over the file's blocks from its start (CSV,
        Parquet)."""
        return self.rec is not None or type(self.table).read is not _Table.read

    def __enter__(self) -> RunStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self.table is not None:
            self.table.close()
            self.table = None


_SUFFIXES = (".h5", ".hdf5", ".mat", ".parquet", ".pq", ".csv", ".txt", ".tdms", ".mf4",
             ".mdf")


def _whole_lookup(table: _Table, path: Path) -> Callable[[str], RawChannel | None] | None:
    """The whole-file reader's ``lookup`` over the open table (None: not offered)."""
    from torquemod.io._stream_tables import _H5Table, _MdfTable, _TdmsTable
    if isinstance(table, _MdfTable | _TdmsTable):
        return table.index.lookup
    if isinstance(table, _H5Table):
        if table.mat:
            from torquemod.io import matlab as matlab_io

            def lookup(name: str) -> RawChannel | None:
                v = matlab_io._read_dataset(table.g, name, path)
                return None if v is None else RawChannel(v)
            return lookup
        from torquemod.io import hdf5 as hdf5_io
        return lambda name: hdf5_io._dataset(table.g, name, path)
    return None


def _reader_notes(table: _Table) -> list[str]:
    from torquemod.io._stream_tables import _H5Table
    if isinstance(table, _H5Table) and not table.mat:
        from torquemod.io import hdf5 as hdf5_io
        return hdf5_io._notes(table.g)
    return []


def _reblocked(blocks: Iterator[dict[str, np.ndarray]], name: str, size: int
               ) -> Iterator[np.ndarray]:
    """The column ``name`` of ``blocks`` in consecutive pieces of exactly ``size`` values
    (the last one shorter): the blocks of the whole-file time fit."""
    held: list[np.ndarray] = []
    count = 0
    for block in blocks:
        v = np.asarray(block[name])
        held.append(v)
        count += v.size
        while count >= size:
            cat = np.concatenate(held) if len(held) > 1 else held[0]
            yield cat[:size]
            held, count = [cat[size:]], count - size
    if count:
        yield np.concatenate(held) if len(held) > 1 else held[0]
