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

import numpy as np

from .._version import __version__
from ..errors import InputError
from ..fsutil import atomic_dir, sha256_file
from ..io.recording import read_recording
from ..io.run import Run, RunRecording, read_run
from ..jsonutil import dump_json
from ..provenance import software_versions
from .estimator import TRACK_COLUMNS, OnboardConfig, OnboardEstimator

#: samples handed to the estimator at a time by the batch command
CHUNK_S = 30.0


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
        return out


def _channels(rec, run: Run, entry: RunRecording, notes: list[str]):
    ch = rec.channels
    veh = run.vehicle
    torque = ch["torque_nm"]
    wheel = ch["wheel_speed_rad_s"]
    if veh.gear_ratio:  # recorded at the motor: to the axle
        torque = torque * veh.gear_ratio
        wheel = wheel / veh.gear_ratio
        notes.append(f"torque and speed recorded at the motor: x{veh.gear_ratio:g} and "
                     f"/{veh.gear_ratio:g} to the axle")
    if "vehicle_speed_m_s" in ch:
        v = ch["vehicle_speed_m_s"]
    else:
        raise InputError("no reference speed (vehicle_speed) in the recording", path=entry.path,
                         channel="vehicle_speed_m_s",
                         hint="map the radar, GNSS or an unpowered axle's speed as "
                              "vehicle_speed in [channels] (docs/format.md)")
    if "position_m" in ch:
        x = ch["position_m"]
    else:
        x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / rec.fs_hz)])
        notes.append("no position channel: position integrated from the reference speed")
    return torque, wheel, v, x


def estimate_axle(run: Run, entry: RunRecording, config: OnboardConfig | None = None,
                  *, chunk_s: float = CHUNK_S) -> OnboardResult:
    """Read one axle's recording and run it through :class:`OnboardEstimator` in chunks."""
    import pandas as pd
    config = config or OnboardConfig.from_dict(run.extra.get("onboard"),
                                               source=str(run.manifest_path))
    t_start = time.perf_counter()
    rec = read_recording(entry.path, group=entry.group, channel_map=run.channel_map,
                         sample_rate_hz=entry.sample_rate_hz)
    notes = list(rec.notes)
    torque, wheel, v, x = _channels(rec, run, entry, notes)
    for name, arr in (("torque_nm", torque), ("wheel_speed_rad_s", wheel),
                      ("vehicle_speed_m_s", v), ("position_m", x)):
        if not np.isfinite(arr).all():
            raise InputError(f"{int((~np.isfinite(arr)).sum())} NaN/inf values",
                             path=entry.path, channel=name, hint="repair the recording")
    est = OnboardEstimator(run.vehicle, run.modulation_frequency_hz, rec.fs_hz,
                           config=config, t0_s=rec.t0_s)
    step = max(1, round(chunk_s * rec.fs_hz))
    rows = []
    for a in range(0, torque.size, step):
        rows += est.feed(torque[a:a + step], wheel[a:a + step], v[a:a + step], x[a:a + step])
    track = pd.DataFrame(rows)
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
