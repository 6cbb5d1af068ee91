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
from ..io.run import Run, RunRecording, read_run
from ..jsonutil import dump_json
from ..provenance import software_versions
from .chunks import (  # noqa: F401  (the fleet's chunk tasks: torquemod.fleettasks)
    AxlePart,
    assemble_axle,
    measure_axle_chunk,
    plan_axle_chunks,
)
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


class _AxleSignals:
    """A recording's rows as the estimator's four signals, chunk by chunk: torque [N*m] and
    wheel speed [rad/s] at the axle (times / divided by ``gear_ratio`` when recorded at the
    motor), reference speed [m/s] and position [m] (integrated from the reference speed by the
    trapezoid rule when the run has no position channel; the running sum is carried across
    chunks in the same order as over the whole recording, so it is bit for bit the same)."""

    def __init__(self, run: Run, entry: RunRecording, channels, fs_hz: float,
                 notes: list[str]) -> None:
        veh = run.vehicle
        self.entry, self.fs_hz, self.gear = entry, fs_hz, veh.gear_ratio
        if self.gear:
            notes.append(f"torque and speed recorded at the motor: x{self.gear:g} and "
                         f"/{self.gear:g} to the axle")
        if "vehicle_speed_m_s" not in channels:
            raise InputError("no reference speed (vehicle_speed) in the recording",
                             path=entry.path, channel="vehicle_speed_m_s",
                             hint="map the radar, GNSS or an unpowered axle's speed as "
                                  "vehicle_speed in [channels] (docs/format.md)")
        self.integrate = "position_m" not in channels
        if self.integrate:
            notes.append("no position channel: position integrated from the reference speed")
        self.v_last: float | None = None
        self.x_last = 0.0

    def _check(self, name: str, arr: np.ndarray, row: int, t0_s: float) -> None:
        bad = ~np.isfinite(arr)
        if bad.any():
            first = t0_s + (row + int(np.argmax(bad))) / self.fs_hz
            raise InputError(f"NaN/inf values (the first at t = {first:.3f} s)",
                             path=self.entry.path, channel=name, hint="repair the recording")

    def fast(self, ch: dict[str, np.ndarray], row: int, t0_s: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Torque and wheel speed at the axle and the reference speed of the rows from
        ``row`` on (``t0_s`` [s]: the time of row 0), checked for NaN/inf."""
        torque, wheel, v = ch["torque_nm"], ch["wheel_speed_rad_s"], ch["vehicle_speed_m_s"]
        if self.gear:
            torque = torque * self.gear
            wheel = wheel / self.gear
        for name, arr in (("torque_nm", torque), ("wheel_speed_rad_s", wheel),
                          ("vehicle_speed_m_s", v)):
            self._check(name, arr, row, t0_s)
        return torque, wheel, v

    def position(self, ch: dict[str, np.ndarray], v: np.ndarray, row: int, t0_s: float
                 ) -> np.ndarray:
        """Position [m] of the rows from ``row`` on; consecutive calls when integrated."""
        if not self.integrate:
            x = ch["position_m"]
        elif v.size:
            vv = v if self.v_last is None else np.concatenate([[self.v_last], v])
            inc = 0.5 * (vv[1:] + vv[:-1]) / self.fs_hz
            x = np.cumsum(np.concatenate([[self.x_last], inc]))
            x = x if self.v_last is None else x[1:]
            self.v_last, self.x_last = float(v[-1]), float(x[-1])
        else:
            x = np.zeros(0)
        self._check("position_m", x, row, t0_s)
        return x

    def __call__(self, ch: dict[str, np.ndarray], row: int, t0_s: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        torque, wheel, v = self.fast(ch, row, t0_s)
        return torque, wheel, v, self.position(ch, v, row, t0_s)


def estimate_axle(run: Run, entry: RunRecording, config: OnboardConfig | None = None,
                  *, chunk_s: float = CHUNK_S) -> OnboardResult:
    """Run one axle's recording through :class:`OnboardEstimator`, ``chunk_s`` [s] of rows
    at a time as :class:`~torquemod.io.runstream.RunStream` reads them: memory does not
    grow with the run (a layout the stream cannot read in parts is read whole; its note
    says so). The track is the one the whole recording fed in the same chunks gives."""
    import pandas as pd

    from ..io.runstream import RunStream
    config = config or OnboardConfig.from_dict(run.extra.get("onboard"),
                                               source=str(run.manifest_path))
    t_start = time.perf_counter()
    frames = []  # one small columnar table per chunk: a dict per window would grow ~2 kB each
    with RunStream(entry.path, group=entry.group, channel_map=run.channel_map,
                   sample_rate_hz=entry.sample_rate_hz) as stream:
        notes = list(stream.notes)
        signals = _AxleSignals(run, entry, stream.channels, stream.fs_hz, notes)
        est = OnboardEstimator(run.vehicle, run.modulation_frequency_hz, stream.fs_hz,
                               config=config, t0_s=stream.t0_s)
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
