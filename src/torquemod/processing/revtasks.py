"""One long rig recording as several tasks: groups of platform revolutions.

:func:`torquemod.processing.pipeline.load_and_process` puts a whole recording through steps 1-5 and
8
of the chain; a recording spanning many revolutions (an hour of them) would be one long
task. Here the same work is cut in three:

1. :func:`plan_revolutions` (cheap) finds the recording's revolution index ranges exactly as
   ``load_and_process`` would split it, and what it would note before and after the cycles;
2. :func:`process_revolutions` (one task per group, e.g. a minute of recording) reads only
   the rows of its revolutions (:meth:`torquemod.io.stream.RecordingStream.read_rows`) and
   runs the chain on each;
3. :func:`merge_revolutions` puts the groups back together as the tuple
   ``load_and_process`` returns (same cycles, notes, NaN actions and SHA-256), so
   ``process_experiment(loaded=...)`` gives the numbers of ``torquemod process``.

``load_and_process`` has two ways to split a file, and each is reproduced:

* ``"stream"`` (files of at least :data:`torquemod.processing.pipeline.STREAM_MIN_BYTES`): the
  revolutions come from :meth:`~torquemod.io.stream.RecordingStream.revolutions`; each is
  checked for NaN/inf and clipping as it comes (a clipping note once per channel, from the
  first revolution showing it), the dropped tail is noted at the end. The plan reads only
  the platform-speed channel.
* ``"whole"`` (smaller files): the whole file is read (bounded by ``STREAM_MIN_BYTES``),
  its reader notes, clipping notes and NaN check taken on the whole record and the
  revolutions found by :func:`torquemod.processing.cycles.revolution_bounds`; the plan's task runs
  the
  first group on that record, the other groups read their rows through the stream, whose
  time base and sample count the plan checks against the whole-file reader's (else the
  recording stays one task). Only when ``revolutions_per_task`` is given: by default such a
  file (under 256 MiB, about 5 min of V-Track's channels) stays one task, since the plan's
  serial whole-file read and checks are ~40 % of its work (measured on a 4.3 min file: one
  task 0.82 s; plan 0.52 s + 4 groups of 0.14 s), so splitting it gained nothing on 2
  workers and cost ~20 % on one.

With ``--nan-policy interpolate|drop-cycle`` the plan also finds the file's runs of NaN/inf
samples (:func:`torquemod.processing.nanfill.scan_nonfinite`: a pass over every channel in
stream mode, the record read whole in whole mode); each group fills its rows from them
(:meth:`~torquemod.processing.nanfill.NonFiniteRuns.fill`, the values of the whole file
filled) and drop-cycle drops the revolutions they touch, as ``load_and_process`` does.

A recording stays one task (:func:`plan_revolutions` returns None) when the manifest names
its cycle, the file cannot be streamed (channels on their
own time bases, .mat v5) or only in order (Parquet, CSV: each group would read every row
before its own), it has no platform speed, or it is short (one group). Each group opens the
file's stream, which finds its time base again (for a file with a time column, a pass over
that column).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from torquemod.errors import InputError
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Experiment, Recording, RecordingEntry
from torquemod.io.stream import hash_file_async, open_stream
from torquemod.io.validate import check_finite, clipping_notes
from torquemod.processing import nanfill
from torquemod.processing.nanfill import NonFiniteRuns

#: Seconds of recording a group of revolutions aims at when ``revolutions_per_task`` is not
#: given: tasks of about a minute, never an hour (a lost task costs little to redo).
TASK_SECONDS = 60.0


@dataclass(frozen=True)
class RevolutionPlan:
    """How one recording is cut into groups of revolutions.

    Attributes
    ----------
    mode : {"stream", "whole"}
        Which split of ``load_and_process`` is reproduced.
    bounds : tuple of tuple of int
        The revolutions' row ranges [start, stop).
    fs_hz : float
        Sample rate [Hz].
    head_notes : tuple of str
        What ``load_and_process`` notes before the cycles' own notes.
    tail_notes : tuple of str
        What it notes after them.
    channel_order : tuple of str
        The whole-file reader's channel order (whole mode).
    read_s : float
        The plan's reading time [s].
    runs : NonFiniteRuns or None
        The file's runs of NaN/inf samples under a NaN policy other than ``raise`` (None:
        the policy raises, or every sample is finite).
    nan_notes : tuple of str
        The NaN actions noted before the cycles (the channels filled).
    drop : bool
        Whether revolutions holding NaN/inf samples are dropped (``drop-cycle``).
    """

    mode: str
    bounds: tuple[tuple[int, int], ...]
    fs_hz: float
    head_notes: tuple[str, ...]
    tail_notes: tuple[str, ...]
    channel_order: tuple[str, ...]
    read_s: float
    runs: NonFiniteRuns | None = None
    nan_notes: tuple[str, ...] = ()
    drop: bool = False

    def dropped(self, k: int) -> bool:
        """Whether revolution ``k`` (index into :attr:`bounds`) is dropped."""
        return self.drop and self.runs is not None and self.runs.touches(*self.bounds[k])

    def groups(self, revolutions_per_task: int | None = None) -> list[tuple[int, int]]:
        """Consecutive groups ``[first, stop)`` of revolution indices: ``revolutions_per_task``
        each, default as many as make about :data:`TASK_SECONDS` of recording."""
        n = len(self.bounds)
        if revolutions_per_task is None:
            rev_s = (self.bounds[-1][1] - self.bounds[0][0]) / n / self.fs_hz
            revolutions_per_task = max(1, round(TASK_SECONDS / rev_s))
        if revolutions_per_task < 1:
            raise ValueError("revolutions_per_task must be at least 1")
        return [(a, min(n, a + revolutions_per_task))
                for a in range(0, n, revolutions_per_task)]


def _where(entry: RecordingEntry) -> str:
    return str(entry.path) + (f":{entry.group}" if entry.group else "")


def _tail_note(where: str, tail: int, revs: list[int], fs_hz: float) -> list[str]:
    rev = float(np.mean(revs))
    if tail > 0.01 * rev:  # as torquemod.processing.pipeline words it
        return [f"{where}: dropped a trailing part of {tail / fs_hz:.3g} s "
                f"({100 * tail / rev:.0f} % of a platform revolution)"]
    return []


def plan_revolutions(entry: RecordingEntry, exp: Experiment, cfg: ProcessingConfig, *,
                     revolutions_per_task: int | None = None) -> RevolutionPlan | None:
    """The plan of a recording to cut into groups of revolutions.

    Parameters
    ----------
    entry : RecordingEntry
        The recording.
    exp : Experiment
        Its experiment.
    cfg : ProcessingConfig
        The parameters.
    revolutions_per_task : int or None
        Revolutions per group; None: about :data:`TASK_SECONDS` of recording.

    Returns
    -------
    RevolutionPlan or None
        None when it stays one task (also when it would make one group only).

    Raises
    ------
    InputError
        What reading the file raises; the caller then processes the recording as one task,
        which meets the same error as ``load_and_process``.
    """
    got = scan_revolutions(entry, exp, cfg, revolutions_per_task=revolutions_per_task,
                           first_group=False)
    return None if got is None else got[0]


def scan_revolutions(entry: RecordingEntry, exp: Experiment, cfg: ProcessingConfig, *,
                     revolutions_per_task: int | None = None, first_group: bool = True,
                     sha256: str | None = None
                     ) -> tuple[RevolutionPlan, RevolutionPart | None] | None:
    """:func:`plan_revolutions` and, in whole mode, the first group computed on the way.

    The first group's :class:`RevolutionPart` is computed from the record the plan has read
    anyway (the other groups then read their rows; a file read whole is read about once, not
    twice).

    Parameters
    ----------
    entry : RecordingEntry
        The recording.
    exp : Experiment
        Its experiment.
    cfg : ProcessingConfig
        The parameters.
    revolutions_per_task : int or None
        Revolutions per group; None: about :data:`TASK_SECONDS` of recording.
    first_group : bool
        Compute the first group in whole mode. Default True.
    sha256 : str or None
        The file's digest when the caller has just computed it (else the file is hashed).

    Returns
    -------
    tuple or None
        (plan, first part or None: in stream mode or without ``first_group``); None when the
        recording stays one task.
    """
    from torquemod.processing.pipeline import (
        STREAM_CHUNK_ROWS,
        STREAM_MIN_BYTES,
        _cycle_item,
        _cycles_of,
        _open_stream,
    )
    if entry.cycle is not None:
        return None
    where = _where(entry)
    t0 = time.perf_counter()
    try:  # what can be streamed, and how long it is (the file's description only)
        with open_stream(entry, experiment=exp) as probe:
            info, random_access = probe.info, probe.random_access
    except (InputError, OSError):
        return None
    if "platform_speed_rad_s" not in info.file_names or not random_access:
        return None  # Parquet, CSV: each group would read every row before its own
    if revolutions_per_task is None and info.n_samples / info.fs_hz < 1.5 * TASK_SECONDS:
        return None  # one group: not worth a plan
    stream = _open_stream(entry, exp, cfg)  # the choice load_and_process makes
    runs, nan_notes, drop = None, [], cfg.nan_policy == "drop-cycle"
    if stream is not None:
        if cfg.nan_policy != "raise":
            nan_notes, runs, _ = nanfill.stream_policy(stream, cfg.nan_policy, where,
                                                       STREAM_CHUNK_ROWS)
        with stream:
            bounds = [ab for _, _, ab in stream.revolutions(
                channels=("platform_speed_rad_s",), fill=None if runs is None else runs.fill)]
            tail = stream.tail_samples
        if not bounds:
            return None  # the one task names it
        plan = RevolutionPlan("stream", tuple(bounds), info.fs_hz, (),
                              tuple(_tail_note(where, tail, [b - a for a, b in bounds],
                                               info.fs_hz)),
                              info.channels, time.perf_counter() - t0, runs,
                              tuple(nan_notes), drop)
        first = None
    else:
        if entry.path.stat().st_size >= STREAM_MIN_BYTES or revolutions_per_task is None:
            return None  # by default a file read whole stays one task (see the docstring)
        from torquemod.io import read_entry
        digest = hash_file_async(entry.path) if first_group and sha256 is None else None
        rec = read_entry(exp, entry)
        if (rec.fs_hz != info.fs_hz or rec.t0_s != info.t0_s
                or rec.n_samples != info.n_samples or set(rec.channels) != set(info.channels)
                or "platform_speed_rad_s" not in rec.channels):
            return None  # the stream would not give the whole-file reader's samples
        notes = [f"{where}: {n}" for n in getattr(rec, "notes", [])]
        notes += clipping_notes(rec, path=where)
        if cfg.nan_policy == "raise":
            check_finite(rec, path=where)
        else:  # the runs fill the record as fill_record would, and the other groups' rows
            runs = nanfill.scan_nonfinite([rec.channels])
            nan_notes = runs.notes(where)
            runs = runs if runs.channels else None
            if runs is not None:
                rec.channels.update(runs.fill(0, rec.channels))
        cycles = _cycles_of(entry, rec, where, notes)  # notes the dropped tail
        plan = RevolutionPlan("whole", tuple(ab for _, _, ab in cycles), rec.fs_hz,
                              tuple(notes), (), tuple(rec.channels), time.perf_counter() - t0,
                              runs, tuple(nan_notes), drop)
        groups = plan.groups(revolutions_per_task)
        first = None
        if first_group and len(groups) > 1:  # the same segments load_and_process cuts
            t1 = time.perf_counter()
            out, actions = [], []
            for k, (cyc, seg, _) in enumerate(cycles[:groups[0][1]]):
                if plan.dropped(k):
                    actions.append(nanfill.drop_action(where, entry.step, cyc))
                else:
                    out.append(_cycle_item(entry, exp, cfg, where, cyc, seg))
            first = RevolutionPart(0.0, time.perf_counter() - t1,
                                   tuple((None, n) for c in out for n in c[1].notes), out,
                                   sha256 if digest is None else digest.result(),
                                   tuple(actions))
    if len(plan.groups(revolutions_per_task)) < 2:
        return None
    return plan, first


@dataclass(frozen=True)
class RevolutionPart:
    """What :func:`process_revolutions` gives for one group of revolutions.

    Attributes
    ----------
    read_s : float
        Reading time [s].
    compute_s : float
        Compute time [s].
    notes : tuple of tuple
        The notes in order, ``(clipping key or None, text)``; the key lets
        :func:`merge_revolutions` keep a channel's clipping note once.
    cycles : list
        The cycles as ``load_and_process`` lists them.
    sha256 : str or None
        The file's SHA-256 (the first group's only).
    actions : tuple of str
        The revolutions dropped by ``--nan-policy drop-cycle``, as NaN actions.
    """

    read_s: float
    compute_s: float
    notes: tuple[tuple[str | None, str], ...]
    cycles: list
    sha256: str | None = None
    actions: tuple[str, ...] = ()


def process_revolutions(entry: RecordingEntry, exp: Experiment, cfg: ProcessingConfig,
                        plan: RevolutionPlan, first: int, stop: int, *,
                        sha256: str | None = None) -> RevolutionPart:
    """Steps 1-5 and 8 on revolutions ``first:stop`` of a recording.

    Each revolution is read by its rows alone and checked as ``load_and_process`` checks it
    in the plan's mode. The first group (``first == 0``) also hashes the file, in a
    background thread while it computes, unless the caller gives the digest.

    Parameters
    ----------
    entry : RecordingEntry
        The recording.
    exp : Experiment
        Its experiment.
    cfg : ProcessingConfig
        The parameters.
    plan : RevolutionPlan
        The recording's plan.
    first : int
        First revolution (index into ``plan.bounds``; cycle number ``first + 1``).
    stop : int
        Revolution after the last.
    sha256 : str or None
        The file's digest when the caller has just computed it. Default None.

    Returns
    -------
    RevolutionPart
        The group's cycles and notes.

    Raises
    ------
    InputError
        The error ``load_and_process`` meets on these revolutions.
    """
    from torquemod.processing.pipeline import _cycle_item
    where = _where(entry)
    digest = hash_file_async(entry.path) if first == 0 and sha256 is None else None
    read_s = compute_s = 0.0
    notes: list[tuple[str | None, str]] = []
    out, actions = [], []
    with open_stream(entry, experiment=exp) as stream:
        for k in range(first, stop):
            a, b = plan.bounds[k]
            t0 = time.perf_counter()
            seg = stream.read_rows(a, b)
            ch = seg.channels if plan.runs is None else plan.runs.fill(a, seg.channels)
            if plan.mode == "whole":  # the whole-file reader's channel order
                ch = {c: ch[c] for c in plan.channel_order}
            seg = Recording(ch, seg.fs_hz, seg.t0_s, seg.source, [])
            t1 = time.perf_counter()
            if plan.mode == "stream":
                if plan.runs is None:
                    check_finite(seg, path=where)
                notes += [(n.split(" sits at ")[0], n) for n in clipping_notes(seg, path=where)]
            if plan.dropped(k):
                actions.append(nanfill.drop_action(where, entry.step, k + 1))
                read_s += t1 - t0
                continue
            item = _cycle_item(entry, exp, cfg, where, k + 1, seg)
            notes += [(None, n) for n in item[1].notes]
            out.append(item)
            read_s += t1 - t0
            compute_s += time.perf_counter() - t1
    return RevolutionPart(read_s, compute_s, tuple(notes), out,
                          (sha256 if first == 0 else None) if digest is None
                          else digest.result(), tuple(actions))


def merge_revolutions(plan: RevolutionPlan, parts: list[RevolutionPart]) -> tuple:
    """The groups of a recording, in order, as ``load_and_process`` returns the recording.

    Parameters
    ----------
    plan : RevolutionPlan
        The recording's plan.
    parts : list of RevolutionPart
        Its groups, in order.

    Returns
    -------
    tuple
        (read [s], compute [s], sha256, NaN actions, notes, cycles).

    Raises
    ------
    ValueError
        The first group is missing, or the cycles do not match the plan's revolutions.
    """
    notes = list(plan.head_notes)
    seen: set[str] = set()
    for part in parts:
        for key, text in part.notes:
            if key is not None:
                if key in seen:
                    continue
                seen.add(key)
            notes.append(text)
    notes += plan.tail_notes
    cycles = [c for part in parts for c in part.cycles]
    actions = [a for part in parts for a in part.actions]  # one per dropped revolution
    if parts[0].sha256 is None:
        raise ValueError("the first group (which hashes the file) is missing")
    if len(cycles) + len(actions) != len(plan.bounds):
        raise ValueError(f"{len(cycles)} cycles merged for {len(plan.bounds)} revolutions")
    read_s = plan.read_s + math.fsum(p.read_s for p in parts)
    compute_s = math.fsum(p.compute_s for p in parts)
    return read_s, compute_s, parts[0].sha256, [*plan.nan_notes, *actions], notes, cycles
