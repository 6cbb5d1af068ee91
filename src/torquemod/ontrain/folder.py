"""The on-board results folder: the one writer (:func:`save_onboard`; the reader is
:func:`torquemod.ontrain.load.load_onboard`) of what ``torquemod onboard`` writes::

    track.parquet              the first axle's track (TRACK_COLUMNS), one row per window
    track_axle<N>.parquet      every further axle's
    along_track.csv            the first axle per segment between detected friction changes
    segments.csv               the first axle's available adhesion per segment, fitted from
                               all the segment's windows (segments_axle<N>.csv: the others)
    along_track_km.csv         ... and per kilometre (along_track_axle<N>*.csv: the others)
    onboard.json               provenance, settings and each axle's summary
    provenance.json            the provenance block every torquemod folder carries
    *.png, report.html         the figures and the report of the first axle
    track.csv, track.mat       with ``export`` ("csv", "mat"): the tracks in those formats

The ``results`` arguments are lists of
:class:`~torquemod.ontrain.result.OnboardResult`.
"""

from __future__ import annotations

import json
from pathlib import Path

from torquemod._util.fsutil import check_output_dir
from torquemod._util.jsonutil import dump_json
from torquemod.errors import InputError
from torquemod.io.run import Run
from torquemod.processing.provenance import provenance_block
from torquemod.results.export import check_formats, write_table
from torquemod.results.writer import write_folder

__all__ = ["check_onboard_out", "onboard_provenance", "save_onboard", "track_name"]

META = "onboard.json"


def track_name(results: list, r, stem: str = "track") -> str:
    """The file stem of an axle's table.

    Parameters
    ----------
    results : list of OnboardResult
        The axles of the run.
    r : OnboardResult
        One of them.
    stem : str
        The table's stem. Default "track".

    Returns
    -------
    str
        ``stem`` for the first axle, ``stem_axle<N>`` for the others.
    """
    return stem if r is results[0] else f"{stem}_axle{r.axle}"


def onboard_provenance(results: list, command: list[str] | None = None) -> dict:
    """The provenance block of an on-board folder.

    Parameters
    ----------
    results : list of OnboardResult
        The axles of one run.
    command : list of str or None
        The command line. Default None.

    Returns
    -------
    dict
        :func:`~torquemod.processing.provenance.provenance_block` (kind ``"onboard"``) of
        the ``[onboard]`` settings, run.toml and every axle's recording with their SHA-256.
    """
    run = results[0].run
    return provenance_block(
        "onboard", results[0].config.to_dict(),
        [{"file": run.manifest_path, "role": "manifest"},
         *({"file": e.path, "role": "recording", "axle": e.axle} for e in run.recordings)],
        command=command)


def _meta(results: list, prov: dict) -> dict:
    """``onboard.json``: the provenance block's software, time and command, the run (with
    the block's SHA-256 of each file), the settings and each axle's summary."""
    run = results[0].run
    sha = {e["file"]: e["sha256"] for e in prov["inputs"]}
    return {"torquemod_version": prov["torquemod_version"],
            "created_utc": prov["created_utc"],
            "command": prov["command"], "software": prov["software"],
            "run": {"manifest": str(run.manifest_path),
                    "manifest_sha256": sha[str(run.manifest_path)],
                    "vehicle": {k: getattr(run.vehicle, k) for k in
                                run.vehicle.__dataclass_fields__},
                    "modulation_frequency_hz": run.modulation_frequency_hz,
                    "modulation_amplitude_nm": run.modulation_amplitude_nm,
                    "channels": dict(run.channel_map),
                    "extra": dict(run.extra),
                    "recordings": [{"file": str(e.path), "axle": e.axle, "group": e.group,
                                    "sample_rate_hz": e.sample_rate_hz,
                                    "sha256": sha[str(e.path)]} for e in run.recordings]},
            "onboard": results[0].config.to_dict(),
            "axles": [dict(r.summary(), notes=list(r.notes), warnings=list(r.warnings),
                           track_file=track_name(results, r) + ".parquet")
                      for r in results]}


def write_onboard(folder: Path, results: list, *,
                  command: list[str] | None = None, export=(),
                  provenance: dict | None = None) -> None:
    """Write the on-board results folder's files, all but ``provenance.json`` (the results
    writer's), into an existing, empty folder.

    The atomic publishing is :func:`save_onboard`'s.

    Parameters
    ----------
    folder : pathlib.Path
        The folder.
    results : list of OnboardResult
        The axles of one run.
    command : list of str or None
        The command line, for the provenance. Default None.
    export : sequence of str
        Further table formats (:func:`torquemod.results.export.check_formats`).
    provenance : dict or None
        The provenance block (default: :func:`onboard_provenance`), whose time, versions and
        SHA-256 ``onboard.json`` repeats.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from torquemod.ontrain.report import write_figures, write_report
    formats = check_formats(export)
    meta = _meta(results, provenance or onboard_provenance(results, command))
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
    """Refuse, before any work, an unusable results folder.

    Parameters
    ----------
    run : torquemod.io.run.Run
        The run (its inputs).
    out_dir : str or pathlib.Path
        The results folder.
    force : bool
        An occupied folder may be replaced. Default False.

    Raises
    ------
    InputError
        ``out_dir`` is occupied (without ``force``) or is or holds one of the run's inputs.
    """
    inputs = [run.manifest_path, *(e.path for e in run.recordings)]
    check_output_dir(out_dir, force=force, inputs=inputs)


def save_onboard(results: list, out_dir, *, force: bool = False,
                 command: list[str] | None = None, export=()) -> Path:
    """Write the results folder of a run's axles atomically: whole or not at all.

    Parameters
    ----------
    results : list of OnboardResult
        The axles of one run (the first one's figures and report).
    out_dir : str or pathlib.Path
        The results folder.
    force : bool
        Replace an existing folder. Default False.
    command : list of str or None
        The command line, for the provenance. Default None.
    export : sequence of str
        Further table formats (:func:`torquemod.results.export.check_formats`).

    Returns
    -------
    pathlib.Path
        The folder written.

    Raises
    ------
    InputError
        No results, a bad export format, or an unusable ``out_dir``.
    """
    if not results:
        raise InputError("no axle results to save")
    check_formats(export)
    run = results[0].run
    inputs = [run.manifest_path, *(e.path for e in run.recordings)]
    prov = onboard_provenance(results, command)
    with write_folder(Path(out_dir), kind="onboard", provenance=prov, force=force,
                      refuse=inputs) as w:
        write_onboard(w.path, results, command=command, export=export, provenance=prov)
    return Path(out_dir)
