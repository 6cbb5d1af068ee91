"""``torquemod onboard RUN.toml --out DIR``: a run's recordings through the on-board
estimator, written as ``track.parquet`` (one row per window, :data:`TRACK_COLUMNS`),
``onboard.json`` (provenance and summary), figures and ``report.html``.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from .._version import __version__
from ..blas import single_blas
from ..errors import InputError
from ..fsutil import atomic_dir, sha256_file
from ..io.run import Run, RunRecording, read_run
from ..jsonutil import dump_json
from ..provenance import software_versions
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


@dataclass
class OnboardResult:
    """The track of one axle (``track``: a DataFrame with :data:`TRACK_COLUMNS` and
    diagnostics), the run, the settings and what the reader noted."""

    run: Run
    axle: int
    track: object
    config: OnboardConfig
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0
    n_fits: int = 0
    truth: object | None = None

    def summary(self) -> dict:
        t = self.track
        given = t["mu"].notna()
        out = {"axle": self.axle, "windows": len(t), "mu_given_share": float(given.mean()),
               "low_adhesion_share": float(t["low_adhesion"].mean()),
               "slip_share": float(t["slip"].mean()), "mu_fits": self.n_fits,
               "seconds": self.seconds,
               "length_m": float(t["position_m"].iloc[-1] - t["position_m"].iloc[0])
               if len(t) else 0.0}
        if given.any():
            out["mu_median"] = float(t.loc[given, "mu"].median())
        if "delay_s" in t and len(t):
            # the net torque-behind-speed delay measured from the run and taken out
            # (beyond the declared one; 0 while the windows did not determine it)
            out["measured_delay_s"] = float(t["delay_s"].iloc[-1])
        return out


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
                         truth=load_truth(run))


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
    t = result.track[list(TRACK_COLUMNS)].copy()
    t["low_adhesion"] = t["low_adhesion"].astype(bool)
    t["slip"] = t["slip"].astype(bool)
    return t


def _write(folder: Path, results: list[OnboardResult], command: list[str] | None) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    from .report import write_figures, write_report
    run = results[0].run
    meta = {"torquemod_version": __version__,
            "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
            "command": command, "software": software_versions(),
            "run": {"manifest": str(run.manifest_path),
                    "manifest_sha256": sha256_file(run.manifest_path),
                    "vehicle": {k: getattr(run.vehicle, k) for k in
                                run.vehicle.__dataclass_fields__},
                    "modulation_frequency_hz": run.modulation_frequency_hz,
                    "modulation_amplitude_nm": run.modulation_amplitude_nm,
                    "recordings": [{"file": str(e.path), "axle": e.axle,
                                    "sha256": sha256_file(e.path)} for e in run.recordings]},
            "onboard": results[0].config.to_dict(),
            "axles": [dict(r.summary(), notes=r.notes) for r in results]}
    for r in results:
        name = "track.parquet" if r is results[0] else f"track_axle{r.axle}.parquet"
        table = pa.Table.from_pandas(track_table(r), preserve_index=False)
        table = table.replace_schema_metadata({**(table.schema.metadata or {}),
                                               b"torquemod": json.dumps(
                                                   {k: meta[k] for k in
                                                    ("torquemod_version", "created_utc",
                                                     "onboard")}).encode()})
        pq.write_table(table, folder / name)
    (folder / "onboard.json").write_text(dump_json(meta))
    figs = write_figures(folder, results[0])
    write_report(folder / "report.html", results[0], meta, figs)


def run_onboard(run_path: str | Path, out_dir: str | Path, *, force: bool = False,
                config: OnboardConfig | None = None, command: list[str] | None = None
                ) -> list[OnboardResult]:
    """Estimate every axle of the run ``run_path`` and write the results folder
    ``out_dir`` atomically (nothing is left behind on an error)."""
    run = read_run(run_path)
    inputs = [run.manifest_path, *(e.path for e in run.recordings)]
    results = [estimate_axle(run, e, config) for e in run.recordings]
    with atomic_dir(Path(out_dir), force=force, inputs=inputs, kind="onboard") as tmp:
        _write(tmp, results, command)
    return results
