"""The on-board results folder: the one writer (:func:`save_onboard`) and reader
(:func:`load_onboard`) of what ``torquemod onboard`` writes::

    track.parquet              the first axle's track (TRACK_COLUMNS), one row per window
    track_axle<N>.parquet      every further axle's
    along_track.csv            the first axle per segment between detected friction changes
    segments.csv               the first axle's available adhesion per segment, fitted from
                               all the segment's windows (segments_axle<N>.csv: the others)
    along_track_km.csv         ... and per kilometre (along_track_axle<N>*.csv: the others)
    onboard.json               provenance, settings and each axle's summary
    *.png, report.html         the figures and the report of the first axle
    track.csv, track.mat       with ``export`` ("csv", "mat"): the tracks in those formats
"""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path

from .._version import __version__
from ..errors import InputError
from ..export import check_formats, write_table
from ..fsutil import atomic_dir, check_output_dir, sha256_file
from ..io.run import Run, RunRecording, Vehicle
from ..jsonutil import dump_json
from ..provenance import software_versions
from .estimator import OnboardConfig
from .result import OnboardResult

__all__ = ["check_onboard_out", "load_onboard", "save_onboard", "track_name"]

META = "onboard.json"


def track_name(results: list[OnboardResult], r: OnboardResult, stem: str = "track") -> str:
    """The file stem of axle ``r``'s table ``stem``: ``stem`` for the first axle,
    ``stem_axle<N>`` for the others."""
    return stem if r is results[0] else f"{stem}_axle{r.axle}"


def _meta(results: list[OnboardResult], command: list[str] | None) -> dict:
    run = results[0].run
    return {"torquemod_version": __version__,
            "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
            "command": command, "software": software_versions(),
            "run": {"manifest": str(run.manifest_path),
                    "manifest_sha256": sha256_file(run.manifest_path),
                    "vehicle": {k: getattr(run.vehicle, k) for k in
                                run.vehicle.__dataclass_fields__},
                    "modulation_frequency_hz": run.modulation_frequency_hz,
                    "modulation_amplitude_nm": run.modulation_amplitude_nm,
                    "channels": dict(run.channel_map),
                    "extra": dict(run.extra),
                    "recordings": [{"file": str(e.path), "axle": e.axle, "group": e.group,
                                    "sample_rate_hz": e.sample_rate_hz,
                                    "sha256": sha256_file(e.path)} for e in run.recordings]},
            "onboard": results[0].config.to_dict(),
            "axles": [dict(r.summary(), notes=list(r.notes), warnings=list(r.warnings),
                           track_file=track_name(results, r) + ".parquet")
                      for r in results]}


def write_onboard(folder: Path, results: list[OnboardResult], *,
                  command: list[str] | None = None, export=()) -> None:
    """Write the folder's files into ``folder`` (an existing, empty folder: the atomic
    publishing is :func:`save_onboard`'s)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from .report import write_figures, write_report
    formats = check_formats(export)
    meta = _meta(results, command)
    stamp = json.dumps({k: meta[k] for k in ("torquemod_version", "created_utc",
                                             "onboard")}).encode()
    for r in results:
        name = track_name(results, r)
        frame = r.to_frame()
        table = pa.Table.from_pandas(frame, preserve_index=False)
        table = table.replace_schema_metadata({**(table.schema.metadata or {}),
                                               b"torquemod": stamp})
        pq.write_table(table, folder / f"{name}.parquet")
        for fmt in formats:
            if fmt != "parquet":  # written above, with its metadata
                write_table(frame, folder / name, fmt, name="track")
        stretch = track_name(results, r, "along_track")
        r.along_track().to_csv(folder / f"{stretch}.csv", index=False)
        r.along_track("km").to_csv(folder / f"{stretch}_km.csv", index=False)
        r.segment_table().to_csv(folder / f"{track_name(results, r, 'segments')}.csv",
                                 index=False)
    (folder / META).write_text(dump_json(meta))
    figs = write_figures(folder, results[0])
    write_report(folder / "report.html", results[0], meta, figs)


def check_onboard_out(run: Run, out_dir, *, force: bool = False) -> None:
    """Refuse, before any work, an ``out_dir`` that is occupied (without ``force``) or is
    or holds one of the run's inputs (:func:`torquemod.fsutil.check_output_dir`)."""
    inputs = [run.manifest_path, *(e.path for e in run.recordings)]
    check_output_dir(out_dir, force=force, inputs=inputs)


def save_onboard(results: list[OnboardResult], out_dir, *, force: bool = False,
                 command: list[str] | None = None, export=()) -> Path:
    """Write the results folder ``out_dir`` of ``results`` (the axles of one run, the first
    one's figures and report) atomically: it appears whole or not at all. Returns its
    path."""
    if not results:
        raise InputError("no axle results to save")
    check_formats(export)
    run = results[0].run
    inputs = [run.manifest_path, *(e.path for e in run.recordings)]
    with atomic_dir(Path(out_dir), force=force, inputs=inputs, kind="onboard") as tmp:
        write_onboard(tmp, results, command=command, export=export)
    return Path(out_dir)


def _run_from(meta: dict, where: Path) -> Run:
    try:
        r = meta["run"]
        veh = Vehicle(**r["vehicle"])
        recs = tuple(RunRecording(Path(e["file"]), axle=int(e["axle"]), group=e.get("group"),
                                  sample_rate_hz=e.get("sample_rate_hz"), index=i)
                     for i, e in enumerate(r["recordings"]))
        return Run(Path(r["manifest"]), veh, float(r["modulation_frequency_hz"]),
                   float(r["modulation_amplitude_nm"]), recs,
                   channel_map=dict(r.get("channels") or {}), extra=dict(r.get("extra") or {}))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{where}: the run description is damaged ({exc})",
                         hint="rerun torquemod onboard") from None


def load_onboard(folder, axle: int | None = None) -> OnboardResult:
    """Read the :class:`OnboardResult` of ``axle`` (None: the first) back from a folder
    :func:`save_onboard` (or ``torquemod onboard``) wrote: the track as written, the run,
    the settings, the notes and the friction changes; the simulated truth when the run's
    ``[truth] file`` is still where it was."""
    import pandas as pd

    from .run import load_truth
    folder = Path(folder)
    path = folder / META
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{folder}: no {META} here: not an on-board results folder",
                         hint="give the folder torquemod onboard --out wrote") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: unreadable ({exc})", hint="rerun torquemod onboard"
                         ) from None
    axles = meta.get("axles") or []
    if not axles:
        raise InputError(f"{path}: lists no axles", hint="rerun torquemod onboard")
    entry = axles[0] if axle is None else next(
        (a for a in axles if a.get("axle") == axle), None)
    if entry is None:
        raise InputError(f"{folder}: no axle {axle}; it holds axles "
                         f"{[a.get('axle') for a in axles]}")
    track_path = folder / entry.get("track_file", "track.parquet" if entry is axles[0]
                                    else f"track_axle{entry['axle']}.parquet")
    try:
        track = pd.read_parquet(track_path)
    except (OSError, ValueError) as exc:
        raise InputError(f"{track_path}: unreadable ({exc})", hint="rerun torquemod onboard"
                         ) from None
    run = _run_from(meta, path)
    try:
        config = OnboardConfig.from_dict(meta.get("onboard"), source=str(path))
    except TypeError as exc:
        raise InputError(f"{path}: damaged [onboard] settings ({exc})") from None
    return OnboardResult(run, int(entry["axle"]), track, config, entry.get("notes", ()),
                         float(entry.get("seconds", 0.0)), int(entry.get("mu_fits", 0)),
                         truth=load_truth(run), changes_m=entry.get("changes_m", ()),
                         delay_s=entry.get("measured_delay_s"),
                         warnings=entry.get("warnings", ()),
                         segments=entry.get("segments", ()))
