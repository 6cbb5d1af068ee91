"""The provenance record of a processing run (``provenance.json``): the software, every
parameter, the inputs with their SHA-256, the warnings, per-cycle details and timing.

Written for people and for the report; torquemod never reads it back as input.
"""

from __future__ import annotations

import platform
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from torquemod._util.fsutil import sha256_file
from torquemod._version import __version__

if TYPE_CHECKING:
    from torquemod.processing.pipeline import ProcessResult

__all__ = ["provenance", "software_versions"]


def _digest(path) -> str | None:
    """SHA-256 of a file, None when it cannot be read any more (moved inputs)."""
    try:
        return sha256_file(Path(path))
    except OSError:
        return None


def software_versions() -> dict:
    """Versions of torquemod, Python and the numerical libraries used.

    Returns
    -------
    dict of str to str
        By package.
    """
    import numpy
    import pandas
    import scipy
    return {"torquemod": __version__, "python": sys.version.split()[0],
            "numpy": numpy.__version__, "scipy": scipy.__version__,
            "pandas": pandas.__version__, "platform": platform.platform()}


def provenance(result: ProcessResult, *, command: list[str] | None = None) -> dict:
    """The provenance record of a processing run.

    Parameters
    ----------
    result : ProcessResult
        The run.
    command : list of str or None
        The command line. Default None.

    Returns
    -------
    dict
        JSON-ready: version, time, command, software, the experiment (manifest and inputs
        with their SHA-256, rig, test, channels), the parameters, warnings, NaN actions,
        cycles and timing [s].
    """
    exp = result.experiment
    inputs, hashed = [], {}
    for e in exp.recordings:
        if e.path not in hashed:
            hashed[e.path] = result.input_sha256.get(str(e.path)) or _digest(e.path)
        inputs.append({"file": str(e.path), "group": e.group, "sha256": hashed[e.path],
                       "step": e.step, "cycle": e.cycle, "dc_torque_nm": e.dc_torque_nm})
    return {
        "torquemod_version": result.torquemod_version,
        "created_utc": result.created_utc,
        "command": command,
        "software": software_versions(),
        "experiment": {
            "manifest": str(exp.manifest_path),
            "manifest_sha256": result.input_sha256.get(str(exp.manifest_path))
            or _digest(exp.manifest_path),
            "rig": {"wheel_radius_m": exp.rig.wheel_radius_m,
                    "platform_radius_m": exp.rig.platform_radius_m, **exp.rig.extra},
            "test": {"normal_load_n": exp.test.normal_load_n,
                     "modulation_frequency_hz": exp.test.modulation_frequency_hz,
                     "modulation_amplitude_nm": exp.test.modulation_amplitude_nm,
                     **exp.test.extra},
            "channels": exp.channel_map,
        },
        "inputs": inputs,
        "parameters": result.config.to_dict(),
        "warnings": result.warnings,
        "nan_actions": result.nan_actions,
        "cycles": result.cycle_details,
        "timing_s": result.timing_s,
    }
