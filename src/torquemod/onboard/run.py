"""``torquemod onboard RUN.toml --out DIR``: a run's recordings through the on-board
estimator, written as ``track.parquet`` (one row per window, :data:`TRACK_COLUMNS`),
``onboard.json`` (provenance and summary), figures and ``report.html``.
"""

from __future__ import annotations

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
        for a, ch in stream.chunks(step):
            rows = est.feed(*signals(ch, a, stream.t0_s))
            if rows:
                frames.append(pd.DataFrame(rows))
    track = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    if track.empty:
        raise InputError("the recording is shorter than one estimator window",
                         path=entry.path, hint="record longer or shorten [onboard] "
                         "window_periods")
    return OnboardResult(run, entry.axle, track, config, notes,
                         time.perf_counter() - t_start, est.tracker.n_fits,
                         truth=load_truth(run), changes_m=tuple(est.tracker.changes),
                         delay_s=est.delay_s)


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
    from .folder import save_onboard
    check_formats(export)  # a bad format is refused before the work
    run = run_path if isinstance(run_path, Run) else read_run(run_path)
    results = estimate_run(run, config)
    save_onboard(results, out_dir, force=force, command=command, export=export)
    return results
