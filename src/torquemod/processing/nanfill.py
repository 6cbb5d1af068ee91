"""The NaN policy (``--nan-policy interpolate|drop-cycle``) on a recording read whole or
streamed.

Both policies fill every NaN/inf sample of a channel by linear interpolation between the
nearest finite samples of that channel (before the first and after the last finite sample:
that sample's value), ``numpy.interp`` over the sample indices; ``drop-cycle`` then drops
every cycle holding a non-finite sample in any channel.

Read whole, :func:`fill_record` fills the record at once. Streamed, a first pass over the
chunks (:func:`scan_nonfinite`) keeps, per channel, each run of non-finite samples and the
values of its two finite neighbours, in memory proportional to the number of runs (not the
length of the file); :meth:`NonFiniteRuns.fill` then fills the chunks of the second pass.
``numpy.interp`` of a sample between two finite neighbours reads only those two points
(``slope * (x - xp[j]) + fp[j]``), so a chunk filled from the neighbours of its own runs
holds the whole-file values bit for bit (tests).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from torquemod.errors import InputError
from torquemod.io.experiment import Recording

_NO_FINITE_HINT = "nothing to interpolate from; repair or remove the file"


def _fill_note(where: str, name: str, count: int) -> str:
    return f"{where}: channel '{name}': interpolated {count} NaN/inf samples"


def drop_action(where: str, step: int, cycle: int) -> str:
    """The NaN action noted for a cycle that ``drop-cycle`` drops.

    Parameters
    ----------
    where : str
        The file.
    step, cycle : int
        The cycle's step and number [-].

    Returns
    -------
    str
        The action, as the results' NaN actions list it.
    """
    return f"{where} (step {step} cycle {cycle}): dropped (NaN/inf samples)"


def fill_record(rec: Recording, where: str) -> list[str]:
    """Fill the NaN/inf samples of a whole record, channel by channel (each filled channel
    replaced by a filled copy).

    Parameters
    ----------
    rec : Recording
        The record; its ``channels`` dict is updated.
    where : str
        The file, named in the notes and errors.

    Returns
    -------
    list of str
        One note per filled channel: how many samples were interpolated.

    Raises
    ------
    InputError
        A channel holds no finite value.
    """
    notes = []
    for name, x in rec.channels.items():
        bad = ~np.isfinite(x)
        if bad.any():
            if bad.all():
                raise InputError("channel holds no finite value", path=where, channel=name,
                                 hint=_NO_FINITE_HINT)
            good = np.flatnonzero(~bad)
            y = x.copy()
            y[bad] = np.interp(np.flatnonzero(bad), good, x[good])
            rec.channels[name] = y
            notes.append(_fill_note(where, name, int(bad.sum())))
    return notes


def record_policy(rec: Recording, policy: str, where: str
                  ) -> tuple[list[str], Callable[[int, int], bool] | None]:
    """The NaN policy on a record read whole (``raise`` is checked by the caller).

    Parameters
    ----------
    rec : Recording
        The record, filled in place when it holds non-finite samples.
    policy : {"interpolate", "drop-cycle"}
        The policy.
    where : str
        The file, named in the notes and errors.

    Returns
    -------
    tuple
        (notes of the filled channels, ``drop(start, stop)``: whether rows [start, stop)
        held a non-finite sample in any channel, or None when nothing is dropped: the record
        was finite or the policy interpolates).

    Raises
    ------
    InputError
        A channel holds no finite value.
    """
    bad = np.zeros(rec.n_samples, dtype=bool)
    for x in rec.channels.values():
        bad |= ~np.isfinite(x)
    if not bad.any():
        return [], None
    notes = fill_record(rec, where)  # drop-cycle also fills, so that the file can be split
    return notes, ((lambda a, b: bool(bad[a:b].any())) if policy == "drop-cycle" else None)


def stream_policy(stream, policy: str, where: str, chunk_rows: int
                  ) -> tuple[list[str], NonFiniteRuns | None, Callable[[int, int], bool] | None]:
    """The NaN policy on a stream: a first pass over its chunks finds the non-finite runs.

    Parameters
    ----------
    stream : torquemod.io.stream.RecordingStream
        The open stream (closed here if this raises).
    policy : {"interpolate", "drop-cycle"}
        The policy.
    where : str
        The file, named in the notes and errors.
    chunk_rows : int
        Rows read at a time [-] (the runs do not depend on it).

    Returns
    -------
    tuple
        (notes of the channels to fill, as :func:`record_policy` gives them; the runs, whose
        :meth:`NonFiniteRuns.fill` fills the chunks of the stream's next pass, or None when
        every sample is finite; ``drop(start, stop)`` as :func:`record_policy` gives it).

    Raises
    ------
    InputError
        A channel holds no finite value, or what reading the file raises.
    """
    try:
        runs = scan_nonfinite(stream.chunks(chunk_rows=chunk_rows))
        notes = runs.notes(where)
    except BaseException:
        stream.close()
        raise
    if not runs.channels:
        return [], None, None
    return notes, runs, (runs.touches if policy == "drop-cycle" else None)


@dataclass(frozen=True, eq=False)
class ChannelRuns:
    """The runs of non-finite samples of one channel, in order.

    Attributes
    ----------
    start, stop : ndarray of int64
        Rows [start, stop) of each run (maximal: rows ``start - 1`` and ``stop`` are finite
        or outside the channel).
    left, right : ndarray of float64
        The values of rows ``start - 1`` and ``stop`` (NaN where the run starts at the first
        or ends at the last row).
    """

    start: np.ndarray
    stop: np.ndarray
    left: np.ndarray
    right: np.ndarray

    @property
    def count(self) -> int:
        """Non-finite samples [-]."""
        return int((self.stop - self.start).sum())


@dataclass(frozen=True, eq=False)
class NonFiniteRuns:
    """The non-finite samples of a recording, by channel (:func:`scan_nonfinite`).

    Attributes
    ----------
    n_samples : int
        Rows of the recording [-].
    channels : dict of str to ChannelRuns
        The channels holding non-finite samples, in the order they were read.
    """

    n_samples: int
    channels: dict[str, ChannelRuns]

    def notes(self, where: str) -> list[str]:
        """One note per channel, as :func:`fill_record` words it.

        Raises
        ------
        InputError
            A channel holds no finite value (the first such channel).
        """
        out = []
        for name, runs in self.channels.items():
            if runs.count == self.n_samples:
                raise InputError("channel holds no finite value", path=where, channel=name,
                                 hint=_NO_FINITE_HINT)
            out.append(_fill_note(where, name, runs.count))
        return out

    def touches(self, start: int, stop: int) -> bool:
        """Whether rows [start, stop) hold a non-finite sample in any channel."""
        for runs in self.channels.values():
            i = int(np.searchsorted(runs.stop, start, side="right"))
            if i < runs.start.size and runs.start[i] < stop:
                return True
        return False

    def fill(self, first_row: int, chunk: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The chunk starting at row ``first_row`` with its non-finite samples filled (the
        channels holding some replaced by filled copies): the values :func:`fill_record`
        gives those rows of the whole record."""
        out = dict(chunk)
        for name, x in chunk.items():
            runs = self.channels.get(name)
            if runs is None:
                continue
            i = int(np.searchsorted(runs.stop, first_row, side="right"))
            j = int(np.searchsorted(runs.start, first_row + x.size, side="left"))
            if i >= j:
                continue
            s, e = runs.start[i:j], runs.stop[i:j]
            has_left, has_right = s > 0, e < self.n_samples
            # the finite neighbours of the runs met here; a sample between two runs is the
            # right neighbour of one and the left of the next
            xp, first = np.unique(np.concatenate((s[has_left] - 1, e[has_right])),
                                  return_index=True)
            fp = np.concatenate((runs.left[i:j][has_left], runs.right[i:j][has_right]))[first]
            bad = np.flatnonzero(~np.isfinite(x))
            y = x.copy()
            y[bad] = np.interp(bad + first_row, xp, fp)
            out[name] = y
        return out


def scan_nonfinite(chunks: Iterable[dict[str, np.ndarray]]) -> NonFiniteRuns:
    """The runs of non-finite samples of a recording delivered in consecutive chunks.

    Parameters
    ----------
    chunks : iterable of dict of str to ndarray
        Consecutive chunks of rows, each channel's float64 samples (as
        :meth:`torquemod.io.stream.RecordingStream.chunks` delivers them).

    Returns
    -------
    NonFiniteRuns
        Per channel, each run [start, stop) and its finite neighbours' values; the same for
        any chunk size.
    """
    found: dict[str, list[tuple[np.ndarray, ...]]] = {}
    open_run: dict[str, tuple[int, float]] = {}  # channel -> (start, left value) of a run
    last: dict[str, float] = {}  # channel -> value of the last row seen
    pos = 0
    for chunk in chunks:
        m = 0
        for name, x in chunk.items():
            m = x.size
            if m == 0:
                continue
            bad = ~np.isfinite(x)
            run = open_run.pop(name, None)
            if not bad.any():
                if run is not None:
                    _append(found, name, run[0], pos, run[1], x[0])
                last[name] = float(x[-1])
                continue
            edges = np.diff(bad.view(np.int8), prepend=np.int8(0), append=np.int8(0))
            starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
            left = x[np.maximum(starts - 1, 0)]
            right = x[np.minimum(stops, m - 1)]
            g_start = starts + pos
            if starts[0] == 0:  # the run goes on from the last chunk, or starts one
                if run is not None:
                    g_start[0], left[0] = run[0], run[1]
                else:
                    left[0] = last.get(name, np.nan) if pos > 0 else np.nan
            elif run is not None:
                _append(found, name, run[0], pos, run[1], x[0])
            if stops[-1] == m:  # still running at the chunk's end
                open_run[name] = (int(g_start[-1]), float(left[-1]))
                g_start, left, right, stops = g_start[:-1], left[:-1], right[:-1], stops[:-1]
            if stops.size:
                found.setdefault(name, []).append((g_start, stops + pos, left, right))
            last[name] = float(x[-1])
        pos += m
    for name, (start, lv) in open_run.items():
        _append(found, name, start, pos, lv, np.nan)
    runs = {}
    for name in last:  # in the chunks' order of channels
        if name in found:
            cols = zip(*found[name], strict=True)
            runs[name] = ChannelRuns(*(np.concatenate(c) for c in cols))
    return NonFiniteRuns(pos, runs)


def _append(found: dict, name: str, start: int, stop: int, left: float, right: float) -> None:
    found.setdefault(name, []).append((np.array([start], dtype=np.int64),
                                       np.array([stop], dtype=np.int64),
                                       np.array([left]), np.array([right])))
