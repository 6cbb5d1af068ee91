"""The processing orchestrator: experiment in, per-cycle and per-step results out.

:func:`process_experiment` reads every recording, splits files that span several platform
revolutions into cycles, runs the chain of :mod:`torquemod.processing.chain` on each cycle, aligns
the
cycles of a step and measures their phase, then aggregates per step. It returns a
:class:`ProcessResult` held in memory; :mod:`torquemod.results.folder` writes and reads it.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import os
import time
from collections import deque
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from torquemod._util.blas import single_blas
from torquemod._util.fsutil import sha256_file
from torquemod._util.jitlink import lean_cached_kernels, release_compiler_pages
from torquemod._util.progress import WarmupBar
from torquemod._util.records import ColumnarRecords
from torquemod._version import __version__
from torquemod.errors import InputError
from torquemod.io import read_entry, read_experiment
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Experiment, Recording, RecordingEntry
from torquemod.io.stream import hash_file_async, open_stream
from torquemod.io.validate import check_finite, clipping_notes
from torquemod.processing import chain, cyclechecks, nanfill
from torquemod.processing.cycles import revolution_bounds
from torquemod.processing.stepmeasure import (
    InOrderStep,
    finish_in_order,
    in_order_steps,
    measure_at_end,
)
from torquemod.processing.steptable import STEP_COLUMNS, aggregate_steps, detect_slip

__all__ = ["CYCLE_COLUMNS", "STEP_COLUMNS", "TRACE_NAMES", "ProcessResult", "ProcessingConfig",
           "aggregate_steps", "detect_slip", "process_experiment", "resolve_config"]

CYCLE_COLUMNS = ["step", "cycle", "torque_peak_hz", "wheel_peak_hz", "modulation_hz",
                 "phase_deg", "creepage", "coa", "phase_se_deg", "coa_torque", "coa_source",
                 "speed_m_s", "torque_amplitude_nm", "wheel_amplitude_rad_s", "creepage_swing",
                 "creepage_drift"]
#: Raw signals are subsampled to at most this many points for the figures' traces.
TRACE_POINTS = 20_000
#: The named arrays of one cycle in :attr:`ProcessResult.traces` (times [s] from the start of
#: the recording; raw signals subsampled, resampled/filtered ones at the chain's rate).
TRACE_NAMES = ("t_raw_s", "torque_raw_nm", "wheel_speed_raw_rad_s", "t_s",
               "torque_resampled_nm", "wheel_speed_resampled_rad_s", "torque_filtered_nm",
               "wheel_speed_filtered_rad_s", "phase_window_s")


@dataclass
class ProcessResult:
    """Everything the processing produced, in memory.

    Attributes
    ----------
    experiment : Experiment
        The experiment processed.
    config : ProcessingConfig
        The processing parameters used.
    cycles : pandas.DataFrame
        One row per modulation cycle (:data:`CYCLE_COLUMNS`): frequencies [Hz], phase lag
        of the wheel speed behind the torque ``phase_deg`` and its standard error
        ``phase_se_deg`` [deg], ``creepage`` [-], ``coa`` [-], ``speed_m_s`` [m/s],
        ``torque_amplitude_nm`` [N*m], ``wheel_amplitude_rad_s`` [rad/s],
        ``creepage_swing`` and ``creepage_drift`` [-].
    steps : pandas.DataFrame
        One row per torque step (:data:`STEP_COLUMNS`): ``dc_torque_nm`` [N*m], the cycle
        means and standard deviations of the phase [deg], creepage [-] and CoA [-],
        ``n_cycles``, ``slip`` and the step means of the per-cycle amplitudes.
    cycle_details : sequence of dict
        Per cycle: the means of every channel (SI units), filters, windows, slip reason
        (a :class:`~torquemod._util.records.ColumnarRecords` when processed here: each item
        is rebuilt as a new dict when read; a list when loaded from a results folder).
    traces : dict
        ``(step, cycle)`` -> named arrays (:data:`TRACE_NAMES`) for the figures.
    warnings : list of str
        What the user should know.
    timing_s : dict
        Wall time of the stages [s].
    nan_actions : list of str
        What the NaN policy did.
    input_sha256 : dict of str to str
        SHA-256 digest of each recording file.
    created_utc : str
        ISO 8601 time of the processing (UTC).
    torquemod_version : str
        The version that processed it.
    command : list of str or None
        The command line that processed it.
    """

    experiment: Experiment
    config: ProcessingConfig
    cycles: pd.DataFrame
    steps: pd.DataFrame
    cycle_details: Sequence[dict]
    traces: dict[tuple[int, int], dict[str, np.ndarray]]
    warnings: list[str]
    timing_s: dict = field(default_factory=dict)
    nan_actions: list[str] = field(default_factory=list)
    input_sha256: dict[str, str] = field(default_factory=dict)  # file path -> digest
    created_utc: str = ""
    torquemod_version: str = __version__
    command: list[str] | None = None  # the command line that processed it, for provenance

    @property
    def name(self) -> str:
        """The experiment's name: its manifest's folder name (or the manifest's stem)."""
        path = Path(self.experiment.manifest_path)
        return path.parent.name or path.stem

    def __repr__(self) -> str:
        slip = [int(s) for s, f in zip(self.steps["step"], self.steps["slip"], strict=True)
                if f]
        return (f"<ProcessResult {self.name!r}: {len(self.steps)} steps, {len(self.cycles)} "
                f"cycles, phase method {self.config.phase.method!r}, "
                f"{len(self.warnings)} warnings" + (f", slip at steps {slip}" if slip else "")
                + ">")

    def _repr_html_(self) -> str:
        from html import escape
        cols = ["step", "dc_torque_nm", "phase_deg", "creepage", "coa", "n_cycles", "slip"]
        return (f"<p>{escape(repr(self))}</p>"
                + self.steps[cols].to_html(index=False, float_format=lambda v: f"{v:.5g}"))

    def plot_signals(self, step: int, cycle: int, *, ax=None):
        """Paper Figure 2 for one cycle: torque and wheel speed, raw and band-pass filtered.
        ``ax`` one Axes (the wheel speed goes on a twin axis) or a pair of Axes, returned as
        given; without one a new two-panel Figure (not pyplot), whose two Axes are
        returned."""
        from torquemod.processing.figures import signals_figure
        if (step, cycle) not in self.traces:
            raise InputError(f"no traces for step {step} cycle {cycle}; available: "
                             f"{sorted(self.traces)}")
        return signals_figure(self.traces[(step, cycle)], step=step, cycle=cycle, ax=ax)


def resolve_config(experiment: Experiment, config: ProcessingConfig | None = None, *,
                   phase_method: str | None = None, nan_policy: str | None = None
                   ) -> ProcessingConfig:
    """The processing parameters of a run.

    Parameters
    ----------
    experiment : Experiment
        The experiment (its ``[processing]`` table, :attr:`Experiment.processing`).
    config : ProcessingConfig or None
        Given parameters; None: the manifest's table.
    phase_method : {"paper", "sinefit"} or None
        Flat override of the phase method. Default None.
    nan_policy : {"raise", "interpolate", "drop-cycle"} or None
        Flat override of the NaN policy. Default None.

    Returns
    -------
    ProcessingConfig
        The parameters.

    Raises
    ------
    InputError
        A bad ``[processing]`` table or override value.
    """
    cfg = config if config is not None else experiment.processing
    cfg = cfg.with_phase_method(phase_method)
    if nan_policy is not None:
        cfg = dataclasses.replace(cfg, nan_policy=nan_policy)
    return cfg


def _cycles_of(entry: RecordingEntry, rec: Recording, where: str, notes: list[str]
               ) -> list[tuple[int, Recording, tuple[int, int]]]:
    """(cycle number, samples, index range) of a recording: the whole file when the manifest
    names its cycle, else one per whole platform revolution."""
    if entry.cycle is not None:
        return [(entry.cycle, rec, (0, rec.n_samples))]
    if "platform_speed_rad_s" not in rec.channels:
        notes.append(f"{where}: no platform speed to split the file by revolutions; the whole "
                     "file is cycle 1")
        return [(1, rec, (0, rec.n_samples))]
    bounds = revolution_bounds(rec.channels["platform_speed_rad_s"], rec.fs_hz)
    if not bounds:
        raise InputError("recording spans less than one platform revolution", path=where,
                         channel="platform_speed_rad_s",
                         hint="give its 'cycle' in the manifest or record a whole revolution")
    tail = rec.n_samples - bounds[-1][1]
    rev = float(np.mean([b - a for a, b in bounds]))
    if tail > 0.01 * rev:  # a sample or two past the last revolution's end is not news
        notes.append(f"{where}: dropped a trailing part of {tail / rec.fs_hz:.3g} s "
                     f"({100 * tail / rev:.0f} % of a platform revolution)")
    return [(k + 1, rec.slice(a, b), (a, b)) for k, (a, b) in enumerate(bounds)]


def _subsample(x: np.ndarray) -> np.ndarray:
    """Every k-th sample, at most TRACE_POINTS of them, as float32 (for plotting only)."""
    stride = max(1, int(np.ceil(x.size / TRACE_POINTS)))
    return x[::stride].astype(np.float32)


#: Files that span several revolutions and are at least this size [bytes] are split while
#: they are read (:meth:`torquemod.io.stream.RecordingStream.revolutions`): memory holds one
#: revolution and one chunk instead of the whole file; the cycles are identical (tests).
STREAM_MIN_BYTES = 256 * 2**20
#: Binary files (:data:`_DECODED_SIZE_SUFFIXES`) are streamed from this many bytes of samples
#: as float64 (time base included), whatever their size on disk: read whole, a file costs
#: about 2.3 times that at the peak (measured: 648 MiB for 4 min of the rig's 6 channels),
#: streamed a constant ~490 MiB with the fit and the report. Their streamed cycles are the
#: whole-file ones bit for bit (tests).
STREAM_MIN_DECODED_BYTES = 64 * 2**20
#: Rows read at a time from a streamed file (1 << 16: 3.9 s at 16.67 kHz, 0.5 MiB per
#: channel): the revolutions cut are the same for any chunk size (tests), a smaller one
#: holds less beside the revolution being cut.
STREAM_CHUNK_ROWS = 1 << 16
#: Binary formats whose decoded size is known from the file's description alone (TDMS and
#: MDF4 from their metadata: a 10-min float32 TDMS recording of the rig, 229 MiB on disk,
#: was read whole at a peak of 929 MiB; streamed, a 60-min one peaked at 306 MiB).
_DECODED_SIZE_SUFFIXES = (".h5", ".hdf5", ".mat", ".parquet", ".pq", ".tdms", ".mf4", ".mdf")


def _open_stream(entry: RecordingEntry, exp: Experiment, cfg: ProcessingConfig):
    """A stream of a long multi-revolution file, or None for the whole-file path (short
    files, a manifest cycle, or a file streaming cannot align: channels on their own time
    bases, .mat v5)."""
    if entry.cycle is not None:
        return None
    try:
        size = entry.path.stat().st_size
        binary = entry.path.suffix.lower() in _DECODED_SIZE_SUFFIXES
        if size < STREAM_MIN_BYTES and not (binary and size >= STREAM_MIN_DECODED_BYTES // 8):
            return None
        stream = open_stream(entry, experiment=exp)
    except (InputError, OSError):
        return None  # the whole-file reader aligns it, or names what is wrong
    decoded = 8 * stream.info.n_samples * (len(stream.info.channels) + 1)  # with the time
    if "platform_speed_rad_s" not in stream.info.file_names or (
            size < STREAM_MIN_BYTES and decoded < STREAM_MIN_DECODED_BYTES):
        stream.close()
        return None
    return stream


_TRIM = []


def release_freed_memory() -> None:
    """Hand the heap pages freed so far back to the system (glibc's ``malloc_trim``; a no-op
    elsewhere). The chain frees its per-cycle arrays at once, but the allocator keeps the
    pages, and a long run's resident size would creep up with the fragments."""
    if not _TRIM:
        try:
            import ctypes
            _TRIM.append(ctypes.CDLL("libc.so.6").malloc_trim)
        except (OSError, AttributeError):
            _TRIM.append(None)
    if _TRIM[0] is not None:
        _TRIM[0](0)


#: A streamed file's freed memory is handed back every this-many revolutions.
TRIM_EVERY = 32

#: Whether the next cycle processed releases LLVM's pages (set by process_experiment: the
#: first cycle of a run loads the chain's kernels, the rest run without LLVM).
_COMPILER_PAGES_DUE = [True]


def _kernels_loaded() -> None:
    """After a run's first cycle: the chain's kernels are loaded; LLVM's pages are released
    (:func:`~torquemod._util.jitlink.release_compiler_pages`) once per run."""
    if _COMPILER_PAGES_DUE[0]:
        _COMPILER_PAGES_DUE[0] = False
        release_compiler_pages()


def _streamed_cycles(stream, where: str, notes: list[str], runs=None):
    """(cycle, segment, (start, stop)) of every whole revolution of a stream, each checked
    for NaN/inf and clipping as it comes (with ``runs``, a
    :class:`~torquemod.processing.nanfill.NonFiniteRuns`, filled first); the stream is closed
    at the end."""
    seen: set[str] = set()
    with stream:
        revs = []
        for k, seg, ab in stream.revolutions(chunk_rows=STREAM_CHUNK_ROWS,
                                             fill=None if runs is None else runs.fill):
            if runs is None:
                check_finite(seg, path=where)
            for note in clipping_notes(seg, path=where):
                key = note.split(" sits at ")[0]
                if key not in seen:  # once per channel, not per revolution
                    seen.add(key)
                    notes.append(note)
            revs.append(ab[1] - ab[0])
            yield k, seg, ab
            if k % TRIM_EVERY == 0:
                release_freed_memory()
        if not revs:
            raise InputError("recording spans less than one platform revolution", path=where,
                             channel="platform_speed_rad_s",
                             hint="give its 'cycle' in the manifest or record a whole "
                             "revolution")
        tail, rev = stream.tail_samples, float(np.mean(revs))
        if tail > 0.01 * rev:
            notes.append(f"{where}: dropped a trailing part of {tail / stream.info.fs_hz:.3g} s "
                         f"({100 * tail / rev:.0f} % of a platform revolution)")


def _load_and_process(entry: RecordingEntry, exp: Experiment, cfg: ProcessingConfig,
                      reduce=None, recording: Recording | None = None
                      ) -> tuple[float, float, str, list[str], list[str], list]:
    """Steps 1-5 and 8 of the chain on one recording.

    Reads the recording, applies the NaN policy, splits it into cycles and runs the steps on
    each. Runs in a worker thread, so it reports by return value, not by warnings.

    Parameters
    ----------
    entry : RecordingEntry
        The recording.
    exp : Experiment
        Its experiment.
    cfg : ProcessingConfig
        The parameters.
    reduce : callable or None
        Maps each cycle's item to what is kept of it (None: nothing is listed), as soon as
        the cycle is done, so that a long file's cycles are not all held at once. Default
        None.
    recording : Recording or None
        The entry's samples already in memory, as :func:`~torquemod.io.read_entry` would
        return them (nothing is read; the digest is empty). Default None.

    Returns
    -------
    tuple
        (read [s], compute [s], sha256, NaN actions, notes, cycles).

    Raises
    ------
    InputError
        What reading the file or a cycle's steps raise.
    """
    where = str(entry.path) + (f":{entry.group}" if entry.group else "")
    lean_cached_kernels()  # the chain's kernels load without their linking IR held
    t0 = time.perf_counter()
    # the input's SHA-256 (provenance) in a background thread while the file is read and
    # processed: hashlib releases the GIL, so on a free core it costs no wall time
    digest_future = hash_file_async(entry.path) if recording is None else _NoDigest()
    stream = _open_stream(entry, exp, cfg) if recording is None else None
    actions: list[str] = []
    notes: list[str] = []
    drop = None  # (start, stop) -> whether --nan-policy drop-cycle drops those rows
    if stream is not None:  # a long file: revolution by revolution while it is read
        runs = None
        if cfg.nan_policy != "raise":  # a first pass finds the NaN/inf runs
            actions, runs, drop = nanfill.stream_policy(stream, cfg.nan_policy, where,
                                                        STREAM_CHUNK_ROWS)
        t1 = time.perf_counter()
        segments = _streamed_cycles(stream, where, notes, runs)
    else:
        rec = read_entry(exp, entry) if recording is None else recording
        t1 = time.perf_counter()
        # what the reader did to the time bases (offsets, other rates), for provenance
        notes += [f"{where}: {n}" for n in getattr(rec, "notes", [])]
        notes += clipping_notes(rec, path=where)
        if cfg.nan_policy == "raise":
            check_finite(rec, path=where)
        elif cfg.nan_policy == "drop-cycle" and entry.cycle is not None and not all(
                np.isfinite(x).all() for x in rec.channels.values()):
            actions.append(f"{where}: dropped step {entry.step} cycle {entry.cycle} "
                           "(NaN/inf samples)")
            return (t1 - t0, time.perf_counter() - t1, digest_future.result(), actions,
                    notes, [])
        else:
            filled, drop = nanfill.record_policy(rec, cfg.nan_policy, where)
            actions += filled
        segments = _cycles_of(entry, rec, where, notes)
    out = []
    for cyc, seg, (a, b) in segments:
        if drop is not None and drop(a, b):
            actions.append(nanfill.drop_action(where, entry.step, cyc))
            continue
        item = _cycle_item(entry, exp, cfg, where, cyc, seg)
        _kernels_loaded()
        notes += item[1].notes
        kept = item if reduce is None else reduce(item)
        if kept is not None:  # None: the reducer keeps what it needs itself
            out.append(kept)
    return t1 - t0, time.perf_counter() - t1, digest_future.result(), actions, notes, out


class _NoDigest:
    """The digest of a recording that was never a file: empty."""

    def result(self) -> str:
        return ""


def _cycle_item(entry: RecordingEntry, exp: Experiment, cfg: ProcessingConfig, where: str,
                cyc: int, seg: Recording) -> tuple:
    """Steps 1-5 and 8 of the chain on one cycle's samples: ``(cycle, CycleSignals, info,
    raw traces)`` as :func:`_load_and_process` lists them."""
    cwhere = f"{where} (step {entry.step} cycle {cyc})"
    cyclechecks.check_cycle_length(seg.n_samples, seg.fs_hz, exp.test.modulation_frequency_hz,
                             cfg, where=cwhere)
    sig = chain.process_cycle(seg, exp.rig, cfg, where=cwhere,
                              nominal_hz=exp.test.modulation_frequency_hz,
                              normal_load_n=exp.test.normal_load_n)
    info = {"step": entry.step, "cycle": cyc, "dc_torque_nm": entry.dc_torque_nm,
            "source": where, "n_samples": seg.n_samples, "fs_hz": seg.fs_hz,
            "t0_s": seg.t0_s}
    raw = {"t_raw_s": _subsample(seg.time_s() - seg.t0_s),
           "torque_raw_nm": _subsample(seg.channels["torque_nm"]),
           "wheel_speed_raw_rad_s": _subsample(seg.channels["wheel_speed_rad_s"])}
    return cyc, sig, info, raw


#: steps 1-5 and 8 of one recording, for callers that distribute them (torquemod.fleet.run)
load_and_process = _load_and_process

#: Figure traces (:data:`TRACE_NAMES`) are kept for the first this-many cycles of each step,
#: by cycle number: the paper records three cycles a step, so an ordinary experiment keeps
#: them all, while a recording of thousands of revolutions keeps a bounded amount.
TRACE_CYCLES = 5


def _prefetched(exp: Experiment, cfg: ProcessingConfig, workers: int, reducers=None):
    """Yield (entry, result of :func:`_load_and_process`) in manifest order, with at most
    ``workers + 1`` recordings in flight so memory stays bounded on long experiments.
    ``reducers`` (step -> the ``reduce`` of :func:`_load_and_process`) applies to the
    recordings of those steps."""
    entries = list(exp.recordings)
    red = reducers or {}
    if workers <= 1:
        for e in entries:
            yield e, _load_and_process(e, exp, cfg, red.get(e.step))
        return
    with ThreadPoolExecutor(max_workers=workers) as pool:
        pending: deque = deque()
        it = iter(entries)
        for e in it:
            pending.append((e, pool.submit(_load_and_process, e, exp, cfg, red.get(e.step))))
            if len(pending) > workers:
                break
        while pending:
            e, fut = pending.popleft()
            nxt = next(it, None)
            if nxt is not None:
                pending.append((nxt, pool.submit(_load_and_process, nxt, exp, cfg,
                                                 red.get(nxt.step))))
            try:
                yield e, fut.result()
            except BaseException:
                for _, f in pending:
                    f.cancel()
                raise


@single_blas
def process_experiment(experiment: Experiment | str | Path, *,
                       config: ProcessingConfig | None = None, progress: bool = False,
                       workers: int | None = None, loaded=None) -> ProcessResult:
    """Run the whole chain on an experiment (a parsed manifest or its path).

    Recordings are read and put through steps 1-5 and 8 by ``workers`` threads (numpy, scipy
    and pyarrow release the GIL), then each step's cycles are aligned and their phases
    measured in order (steps 6-7 of the V-Track paper's processing [1]_).

    Parameters
    ----------
    experiment : Experiment or str or pathlib.Path
        The experiment.
    config : ProcessingConfig or None
        The parameters; None: the manifest's ``[processing]`` table (:func:`resolve_config`).
    progress : bool
        Show progress on stderr. Default False.
    workers : int or None
        Reader threads; None: the number of CPUs, at most 4.
    loaded : list or None
        Pairs (entry, result of :func:`load_and_process`) in manifest order, computed
        elsewhere (the fleet's one task per recording); None reads the recordings here.

    Returns
    -------
    ProcessResult
        Cycles, steps, details, traces, notes and timing.

    Raises
    ------
    InputError
        A bad manifest or recording, no cycle that could be processed, a step emptied by the
        NaN policy, or cycle numbers given twice in a step.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Section 2.4.
    """
    workers = workers if workers is not None else min(4, os.cpu_count() or 1)
    lean_cached_kernels()  # the kernels load without their linking IR held (~59 MiB)
    _COMPILER_PAGES_DUE[0] = True
    exp = experiment if isinstance(experiment, Experiment) else read_experiment(experiment)
    cfg = resolve_config(exp, config)
    created = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    notes: list[str] = []
    nan_actions: list[str] = []
    per_step: dict[int, list[tuple[int, chain.CycleSignals, dict]]] = {}
    traces: dict[tuple[int, int], dict[str, np.ndarray]] = {}
    hashes: dict[str, str] = {}
    if Path(exp.manifest_path).is_file():
        hashes[str(exp.manifest_path)] = sha256_file(exp.manifest_path)
    t_read = t_compute = 0.0
    t_start = time.perf_counter()
    # a step that is one long recording is aligned and measured cycle by cycle while it is
    # read, so that memory does not grow with its revolutions (only with the fleet's
    # precomputed results, which hold their cycles anyway, is it done at the end)
    in_order = ({s: InOrderStep(s, cfg, TRACE_CYCLES, CYCLE_COLUMNS)
                 for s in in_order_steps(exp)} if loaded is None else {})
    bar = WarmupBar(total=len(exp.recordings), desc="processing", unit="rec",
                    disable=not progress, leave=False)
    try:  # the bar is cleared before any error line is printed
        for entry, done in (_prefetched(exp, cfg, workers, in_order) if loaded is None
                            else loaded):
            read_s, compute_s, digest, actions, rec_notes, cycles_out = done
            hashes[str(entry.path)] = digest
            t_read += read_s
            t_compute += compute_s
            nan_actions += actions
            notes += rec_notes
            for cyc, sig, info, raw in cycles_out:
                if entry.step not in in_order:  # an in-order step keeps its own cycles
                    per_step.setdefault(entry.step, []).append((cyc, sig, info))
                if raw is not None:
                    traces[(entry.step, cyc)] = dict(raw)
            bar.update()
    finally:
        bar.close()
    present = set(per_step) | {s for s, m in in_order.items() if m.count}
    if not present:
        raise InputError("no cycle could be processed", path=exp.manifest_path,
                         hint="every cycle was dropped; see --nan-policy")
    emptied = [s for s in exp.steps if s not in present]
    if emptied:
        raise InputError(f"step {emptied[0]} has no cycle left after --nan-policy drop-cycle "
                         f"(every cycle held NaN/inf samples; steps without cycles: "
                         f"{emptied})", path=exp.manifest_path,
                         hint="repair the files, use --nan-policy interpolate, or remove the "
                         "step from the manifest")
    t1 = time.perf_counter()
    rows: list[tuple] = []
    details = ColumnarRecords()
    slipped: dict[int, bool] = {}
    for step in sorted(present):
        if step in in_order:  # measured while read (InOrderStep)
            slipped[step] = finish_in_order(in_order.pop(step), cfg, notes, rows, details)
        else:
            slipped[step] = measure_at_end(step, per_step.pop(step), cfg, exp, notes, rows,
                                           details, traces, TRACE_CYCLES, CYCLE_COLUMNS)
    t_compute += time.perf_counter() - t1
    if not rows:
        raise InputError("no cycle could be processed", path=exp.manifest_path,
                         hint="every cycle was dropped; see --nan-policy")
    cycles = pd.DataFrame(rows, columns=CYCLE_COLUMNS)
    del rows
    dc = {e.step: e.dc_torque_nm for e in exp.recordings}
    steps = aggregate_steps(cycles, dc, slipped)
    timing = {"wall_s": time.perf_counter() - t_start, "read_thread_s": t_read,
              "compute_thread_s": t_compute, "workers": workers}
    release_freed_memory()  # what the cycles used, before the fit and the report
    release_compiler_pages()  # and LLVM's pages, touched again if a step loaded kernels
    return ProcessResult(exp, cfg, cycles, steps, details, traces, notes + nan_actions,
                         timing, nan_actions, hashes, created)


