"""``torquemod onboard RUN.toml --out DIR``: a run's recordings through the on-board
estimator, written as ``track.parquet`` (one row per window, :data:`TRACK_COLUMNS`),
``onboard.json`` (provenance and summary), figures and ``report.html``.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

from ..blas import single_blas
from ..errors import InputError
from ..io.run import Run, RunRecording, read_run
from .chunks import (  # noqa: F401  (the fleet's chunk tasks: torquemod.fleettasks)
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
from .estimator import TRACK_COLUMNS, OnboardConfig
from .quality import (
    QUALITY_OK,
    REASONS,
    modulation_line_hz,
    quality_warnings,
    reference_rate_hz,
    stepping,
    without_line_nearby,
)
from .result import OnboardResult

__all__ = ["TRACK_COLUMNS", "OnboardResult", "estimate_axle", "estimate_run", "load_truth",
           "run_onboard", "track_table"]


@single_blas
def estimate_axle(run: Run, entry: RunRecording, config: OnboardConfig | None = None,
                  *, chunk_s: float = CHUNK_S) -> OnboardResult:
    """Run one axle's recording through :class:`OnboardEstimator`, ``chunk_s`` [s] of rows
    at a time as :class:`~torquemod.io.runstream.RunStream` reads them: memory does not
    grow with the run (a layout the stream cannot read in parts is read whole; its note
    says so). The track is the one the whole recording fed in the same chunks gives."""
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
    """A warning when the reference speed (a stretch of it at ``fs_hz`` [Hz]) changes
    course less than twice per window of ``window_s`` [s]: the windows' speed and
    acceleration, hence creepage and the slip flag, are then coarse."""
    rate = reference_rate_hz(speed_m_s, fs_hz)
    if 0.0 < rate < 2.0 / window_s:
        return (f"axle {axle}: the reference speed is updated only about {rate:.2g} times a "
                f"second, less than twice per {window_s:.3g} s window: creepage, "
                "acceleration and the slip flag are coarse (record the reference faster)")
    return None


def check_modulation_line(run: Run, torque_nm, fs_hz: float, config: OnboardConfig) -> None:
    """Refuse a run whose torque (``torque_nm`` at ``fs_hz`` [Hz], e.g. its first 30 s) has
    its modulation line at another frequency than run.toml declares
    (:func:`~torquemod.onboard.quality.modulation_line_hz`)."""
    f = run.modulation_frequency_hz
    found = modulation_line_hz(torque_nm, fs_hz, f,
                               config.min_modulation_ratio * run.modulation_amplitude_nm)
    if found is not None:
        raise InputError(f"the torque's modulation line is at {found:.3g} Hz, not at the "
                         f"declared test.modulation_frequency_hz = {f:g} Hz",
                         path=run.manifest_path, hint="correct [test] modulation_frequency_hz")


def premise_warnings(run: Run, entry: RunRecording, track, config: OnboardConfig,
                     torque_nm=None, fs_hz: float | None = None):
    """``(track, warnings)``: the axle's track with the torque-stepping windows judged by
    their neighbours (:func:`~torquemod.onboard.quality.without_line_nearby`), and the
    warnings about the method's premise (:mod:`torquemod.onboard.quality`): the stretches
    without it, and a run with fewer measurable windows than the friction fit needs. No
    measurable window at all raises :class:`InputError` (as ``process`` refuses a recording
    without a modulation line), naming the line the torque has instead when ``torque_nm``
    (a stretch of the axle's torque at ``fs_hz`` [Hz]) shows one."""
    f = run.modulation_frequency_hz
    q = without_line_nearby(track["quality"].to_numpy(object), ~stepping(
        track["dc_step_nm"], run.modulation_amplitude_nm, config.max_dc_step_ratio))
    lost = q != track["quality"].to_numpy(object)
    if lost.any():
        track = track.copy()
        track.loc[lost, ["phase_deg", "phase_se_deg", "creep_coefficient", "mu", "mu_low_95",
                         "mu_high_95", "utilisation", "creepage",
                         "creep_coefficient_ref"]] = math.nan
        track.loc[lost, ["low_adhesion", "slip"]] = False
        track["quality"] = q
    n_ok = int((q == QUALITY_OK).sum())
    if n_ok == 0:
        flags = {k: int((q == k).sum()) for k in REASONS}
        worst = max(flags, key=flags.get)
        what = REASONS[worst].replace("the declared frequency", f"{f:g} Hz")
        hint = {"no_modulation": "record with the torque modulation on, or check [test] "
                                 "modulation_frequency_hz and modulation_amplitude_nm",
                "standstill": "record while the train runs (at least [onboard] "
                              f"min_speed_m_s = {config.min_speed_m_s:g} m/s)",
                "reverse": "the method needs forward running; if the run went forward, "
                           "the speed channels' sign is wrong"}[worst]
        raise InputError(f"no window of axle {entry.axle} can be measured: {what} "
                         f"({flags[worst]} of {q.size} windows)", path=entry.path, hint=hint)
    out = quality_warnings(track["position_m"], q, axle=entry.axle, frequency_hz=f)
    if n_ok < config.min_windows:
        out.append(f"axle {entry.axle}: only {n_ok} measurable windows, fewer than the "
                   f"{config.min_windows} the friction fit needs ([onboard] min_windows): "
                   "the run is too short for a friction estimate (mu stays empty)")
    return track, out


def load_truth(run: Run):
    """The simulated truth named by ``[truth] file`` in run.toml (None when absent)."""
    import pandas as pd
    t = run.extra.get("truth")
    if not isinstance(t, dict) or "file" not in t:
        return None
    path = run.folder / str(t["file"])
    try:
        return pd.read_parquet(path)
    except (OSError, ValueError):
        return None


def track_table(result: OnboardResult):
    """The ``track.parquet`` table: exactly :data:`TRACK_COLUMNS`."""
    return result.to_frame()


def estimate_run(run: Run, config: OnboardConfig | None = None) -> list[OnboardResult]:
    """Every axle of the run through the estimator, in the manifest's order."""
    return [estimate_axle(run, e, config) for e in run.recordings]


def run_onboard(run_path: str | Path | Run, out_dir: str | Path, *, force: bool = False,
                config: OnboardConfig | None = None, command: list[str] | None = None,
                export=()) -> list[OnboardResult]:
    """Estimate every axle of the run ``run_path`` and write the results folder
    ``out_dir`` atomically (nothing is left behind on an error): ``torquemod onboard``."""
    from ..export import check_formats
    from .folder import check_onboard_out, save_onboard
    check_formats(export)  # a bad format is refused before the work
    run = run_path if isinstance(run_path, Run) else read_run(run_path)
    check_onboard_out(run, out_dir, force=force)  # an occupied --out: before the work
    results = estimate_run(run, config)
    save_onboard(results, out_dir, force=force, command=command, export=export)
    return results
