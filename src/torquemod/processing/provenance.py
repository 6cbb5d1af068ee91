"""Provenance: the block every torquemod output folder carries in ``provenance.json``
(:func:`provenance_block`: the software, the parameters, the inputs with their SHA-256, the
time and command line) and the processing run's record built on it (:func:`provenance`:
the block plus the experiment, the warnings, per-cycle details and timing).

Written for people and for the reports; torquemod never reads it back as input
(:func:`torquemod.results.writer.read_provenance` reads it for people and tests).
"""

from __future__ import annotations

import platform
import sys
from collections.abc import Iterable
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

from torquemod._util.fsutil import sha256_file
from torquemod._version import __version__

if TYPE_CHECKING:
    from torquemod.processing.pipeline import ProcessResult

__all__ = ["BLOCK_KEYS", "SOFTWARE_KEYS", "file_digest", "provenance", "provenance_block",
           "software_versions", "utc_now"]

#: the keys of the provenance block, in every output folder's ``provenance.json``
BLOCK_KEYS = ("kind", "torquemod_version", "created_utc", "command", "software",
              "parameters", "inputs")
#: the keys of its ``software`` table
SOFTWARE_KEYS = ("torquemod", "python", "numpy", "scipy", "pandas", "platform")


def file_digest(path) -> str | None:
    """SHA-256 of a file.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.

    Returns
    -------
    str or None
        The hex digest; None when the file cannot be read any more (moved inputs).
    """
    try:
        return sha256_file(Path(path))
    except OSError:
        return None


def utc_now() -> str:
    """The current time (``created_utc``).

    Returns
    -------
    str
        UTC, ISO 8601 to the second.
    """
    return datetime.now(UTC).isoformat(timespec="seconds")


def software_versions() -> dict:
    """Versions of torquemod, Python and the numerical libraries used.

    Returns
    -------
    dict of str to str
        By package (:data:`SOFTWARE_KEYS`).
    """
    import numpy
    import pandas
    import scipy
    return {"torquemod": __version__, "python": sys.version.split()[0],
            "numpy": numpy.__version__, "scipy": scipy.__version__,
            "pandas": pandas.__version__, "platform": platform.platform()}


def provenance_block(kind: str, parameters: dict, inputs: Iterable = (), *,
                     command: list[str] | None = None, created_utc: str | None = None,
                     torquemod_version: str | None = None) -> dict:
    """The provenance block of an output folder (:data:`BLOCK_KEYS`).

    Parameters
    ----------
    kind : str
        What wrote the folder: ``"results"`` (process), ``"onboard"``, ``"fleet"``,
        ``"sweep"``.
    parameters : dict
        Every setting the outputs depend on (JSON-ready).
    inputs : iterable of path or dict
        The input files: a path (hashed here) or a dict with ``"file"`` and, when known
        already, ``"sha256"`` (other keys are kept); the SHA-256 is None for a file that
        cannot be read.
    command : list of str, optional
        The command line.
    created_utc, torquemod_version : str, optional
        When and by which version the results were made (default: now, this version).

    Returns
    -------
    dict
        ``{"kind", "torquemod_version", "created_utc", "command", "software",
        "parameters", "inputs": [{"file", "sha256", ...}, ...]}``.
    """
    entries, hashed = [], {}
    for item in inputs:
        entry = dict(item) if isinstance(item, dict) else {"file": item}
        entry["file"] = str(entry["file"])
        if not entry.get("sha256"):
            if entry["file"] not in hashed:
                hashed[entry["file"]] = file_digest(entry["file"])
            entry["sha256"] = hashed[entry["file"]]
        hashed.setdefault(entry["file"], entry["sha256"])
        entries.append({"file": entry.pop("file"), "sha256": entry.pop("sha256"), **entry})
    return {"kind": kind, "torquemod_version": torquemod_version or __version__,
            "created_utc": created_utc or utc_now(), "command": command,
            "software": software_versions(), "parameters": parameters, "inputs": entries}


def provenance(result: ProcessResult, *, command: list[str] | None = None) -> dict:
    """The provenance record of a processing run: :func:`provenance_block` (kind
    ``"results"``) with the experiment, the warnings, the NaN actions, the per-cycle details
    and the timing.

    Parameters
    ----------
    result : ProcessResult
        The run.
    command : list of str or None
        The command line. Default None.

    Returns
    -------
    dict
        JSON-ready: kind, version, time, command, software, the experiment (manifest and
        inputs with their SHA-256, rig, test, channels), the parameters, warnings, NaN
        actions, cycles and timing [s].
    """
    exp = result.experiment
    known = result.input_sha256
    block = provenance_block(
        "results", result.config.to_dict(),
        [{"file": e.path, "group": e.group, "sha256": known.get(str(e.path)),
          "step": e.step, "cycle": e.cycle, "dc_torque_nm": e.dc_torque_nm}
         for e in exp.recordings],
        command=command, created_utc=result.created_utc,
        torquemod_version=result.torquemod_version)
    return {
        "kind": block["kind"],
        "torquemod_version": block["torquemod_version"],
        "created_utc": block["created_utc"],
        "command": command,
        "software": block["software"],
        "experiment": {
            "manifest": str(exp.manifest_path),
            "manifest_sha256": known.get(str(exp.manifest_path))
            or file_digest(exp.manifest_path),
            "rig": {"wheel_radius_m": exp.rig.wheel_radius_m,
                    "platform_radius_m": exp.rig.platform_radius_m, **exp.rig.extra},
            "test": {"normal_load_n": exp.test.normal_load_n,
                     "modulation_frequency_hz": exp.test.modulation_frequency_hz,
                     "modulation_amplitude_nm": exp.test.modulation_amplitude_nm,
                     **exp.test.extra},
            "channels": exp.channel_map,
        },
        "inputs": block["inputs"],
        "parameters": block["parameters"],
        "warnings": result.warnings,
        "nan_actions": result.nan_actions,
        "cycles": result.cycle_details,
        "timing_s": result.timing_s,
    }
