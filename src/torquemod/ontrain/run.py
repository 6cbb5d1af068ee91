"""``torquemod onboard RUN.toml --out DIR``: a run's recordings through the on-board
estimator, written as ``track.parquet`` (one row per window, :data:`TRACK_COLUMNS`),
``onboard.json`` (provenance and summary), figures and ``report.html``.
"""

from __future__ import annotations

import time
from pathlib import Path

from torquemod._util.blas import single_blas
from torquemod.errors import InputError
from torquemod.io.run import Run, RunRecording, read_run
from torquemod.io.truth import load_truth
from torquemod.ontrain.chunks import (  # noqa: F401  (the fleet's chunk tasks: torquemod.fleet.tasks)
    CHUNK_S,
    AxlePart,
    _AxleSignals,
    assemble_axle,
    axle_config,
    axle_estimator,
    axle_stream,
    measure_axle_chunk,
    plan_axle_chunks,
)
from torquemod.ontrain.estimator import TRACK_COLUMNS, OnboardConfig
from torquemod.ontrain.quality import (
    modulation_line_hz,
    premise_warnings,
    reference_rate_hz,
)
from torquemod.ontrain.result import OnboardResult

__all__ = ["TRACK_COLUMNS", "OnboardResult", "estimate_axle", "estimate_run", "load_truth",
           "run_onboard", "track_table"]


@single_blas
def estimate_axle(run: Run, entry: RunRecording, config: OnboardConfig | None = None,
                  *, chunk_s: float = CHUNK_S) -> OnboardResult:
    """Run one axle's recording through the on-board estimator, a chunk at a time.

    ``chunk_s`` of rows at a time as :class:`~torquemod.io.runstream.RunStream` reads them:
    memory does not grow with the run (a layout the stream cannot read in parts is read
    whole; its note says so). The track is the one the whole recording fed in the same
    chunks gives.

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run.
    entry : torquemod.io.run.RunRecording
        The axle's recording.
    config : OnboardConfig or None
        The settings; None: the run's ``[onboard]`` table, else the defaults.
    chunk_s : float
        Length of the chunks read [s]. Default :data:`~torquemod.ontrain.chunks.CHUNK_S`.

    Returns
    -------
    OnboardResult
        The axle's track, segments, notes, warnings and measured delay.

    Raises
    ------
    InputError
        The recording is shorter than one window, its torque's modulation line is at another
        frequency than declared, or no window can be measured
        (:func:`~torquemod.ontrain.quality.premise_warnings`).
    """
    import pandas as pd
    config = axle_config(run, config)
    t_start = time.perf_counter()
    frames = []  # one small columnar table per chunk: a dict per window would grow ~2 kB each
    with axle_stream(run, entry) as stream:
        notes = list(stream.notes)
        signals = _AxleSignals(run, entry, stream.channels, stream.fs_hz, notes)
        est = axle_estimator(run, stream, config)
        step = max(1, round(chunk_s * stream.fs_hz))
        first = None  # the first chunk's torque: which line it has, if not the declared
        coarse = None  # a note when the reference speed updates too rarely
        for a, ch in stream.chunks(step):
            sig = signals(ch, a, stream.t0_s)
            if first is None:
                first = sig[0]
                check_modulation_line(run, first, stream.fs_hz, config)
                coarse = coarse_reference(sig[2], stream.fs_hz, est.n_win / stream.fs_hz,
                                          entry.axle)
            rows = est.feed(*sig)
            if rows:
                frames.append(pd.DataFrame(rows))
    track = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    segments = est.finish()
    if track.empty:
        raise InputError("the recording is shorter than one estimator window",
                         path=entry.path, hint="record longer or shorten [onboard] "
                         "window_periods")
    track, warnings = premise_warnings(run, entry, track, config, first, stream.fs_hz)
    warnings += [coarse] if coarse else []
    return OnboardResult(run, entry.axle, track, config, notes,
                         time.perf_counter() - t_start, est.tracker.n_fits,
                         truth=load_truth(run), changes_m=tuple(est.tracker.changes),
                         delay_s=est.delay_s, warnings=warnings, segments=segments)


def coarse_reference(speed_m_s, fs_hz: float, window_s: float, axle: int) -> str | None:
    """A warning when the reference speed is updated less than twice per window.

    The windows' speed and acceleration, hence creepage and the slip flag, are then coarse.

    Parameters
    ----------
    speed_m_s : ndarray
        A stretch of the reference speed [m/s].
    fs_hz : float
        Its sampling rate [Hz].
    window_s : float
        The estimator's window length [s].
    axle : int
        The axle, named in the warning.

    Returns
    -------
    str or None
        The warning, or None when the reference is updated often enough (or is constant).
    """
    rate = reference_rate_hz(speed_m_s, fs_hz)
    if 0.0 < rate < 2.0 / window_s:
        return (f"axle {axle}: the reference speed is updated only about {rate:.2g} times a "
                f"second, less than twice per {window_s:.3g} s window: creepage, "
                "acceleration and the slip flag are coarse (record the reference faster)")
    return None


def check_modulation_line(run: Run, torque_nm, fs_hz: float, config: OnboardConfig) -> None:
    """Refuse a run whose torque has its modulation line at another frequency than declared.

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run (declared ``modulation_frequency_hz`` and amplitude).
    torque_nm : ndarray
        A stretch of the axle torque, e.g. its first 30 s [N*m].
    fs_hz : float
        Its sampling rate [Hz].
    config : OnboardConfig
        The settings (``min_modulation_ratio`` sizes the smallest line).

    Raises
    ------
    InputError
        :func:`~torquemod.ontrain.quality.modulation_line_hz` finds the line elsewhere; the
        message names it and run.toml.
    """
    f = run.modulation_frequency_hz
    found = modulation_line_hz(torque_nm, fs_hz, f,
                               config.min_modulation_ratio * run.modulation_amplitude_nm)
    if found is not None:
        raise InputError(f"the torque's modulation line is at {found:.3g} Hz, not at the "
                         f"declared test.modulation_frequency_hz = {f:g} Hz",
                         path=run.manifest_path, hint="correct [test] modulation_frequency_hz")


def track_table(result: OnboardResult):
    """The ``track.parquet`` table of an axle.

    Parameters
    ----------
    result : OnboardResult
        The axle's result.

    Returns
    -------
    pandas.DataFrame
        Exactly the columns :data:`TRACK_COLUMNS`.
    """
    return result.to_frame()


def estimate_run(run: Run, config: OnboardConfig | None = None) -> list[OnboardResult]:
    """Every axle of the run through the estimator, in the manifest's order.

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run.
    config : OnboardConfig or None
        The settings; None: the run's ``[onboard]`` table, else the defaults.

    Returns
    -------
    list of OnboardResult
        One per recording.
    """
    return [estimate_axle(run, e, config) for e in run.recordings]


def run_onboard(run_path: str | Path | Run, out_dir: str | Path, *, force: bool = False,
                config: OnboardConfig | None = None, command: list[str] | None = None,
                export=()) -> list[OnboardResult]:
    """Estimate every axle of a run and write the results folder: ``torquemod onboard``.

    The folder is written atomically: nothing is left behind on an error.

    Parameters
    ----------
    run_path : str, pathlib.Path or torquemod.io.run.Run
        The run.toml, or the run read.
    out_dir : str or pathlib.Path
        The results folder.
    force : bool
        Replace an existing results folder. Default False.
    config : OnboardConfig or None
        The settings; None: the run's ``[onboard]`` table, else the defaults.
    command : list of str or None
        The command line, recorded in the provenance. Default None.
    export : sequence of str
        Further table formats to write (:func:`torquemod.results.export.check_formats`).

    Returns
    -------
    list of OnboardResult
        One per axle.

    Raises
    ------
    InputError
        A bad export format, run.toml or recording, or an occupied ``out_dir`` without
        ``force`` (all before the work).
    """
    from torquemod.ontrain.folder import check_onboard_out, save_onboard
    from torquemod.results.export import check_formats
    check_formats(export)  # a bad format is refused before the work
    run = run_path if isinstance(run_path, Run) else read_run(run_path)
    check_onboard_out(run, out_dir, force=force)  # an occupied --out: before the work
    results = estimate_run(run, config)
    save_onboard(results, out_dir, force=force, command=command, export=export)
    return results
