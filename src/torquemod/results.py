"""The results folder of ``torquemod process`` (docs/format.md, "Results").

``cycles.csv`` and ``steps.csv`` (columns as documented), ``provenance.json`` (version, every
parameter, inputs with SHA-256, warnings, per-cycle details, timing) and ``traces.npz``
(signals for the figures).
"""

from __future__ import annotations

import datetime as _dt
import platform
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ._version import __version__
from .fsutil import atomic_dir, sha256_file
from .jsonutil import dump_json

if TYPE_CHECKING:
    from .pipeline import ProcessResult


def software_versions() -> dict:
    """Versions of torquemod, Python and the numerical libraries used."""
    import numpy
    import pandas
    import scipy
    return {"torquemod": __version__, "python": sys.version.split()[0],
            "numpy": numpy.__version__, "scipy": scipy.__version__,
            "pandas": pandas.__version__, "platform": platform.platform()}


def provenance(result: ProcessResult, *, command: list[str] | None = None) -> dict:
    """The provenance record of a processing run."""
    exp = result.experiment
    inputs, hashed = [], {}
    for e in exp.recordings:
        if e.path not in hashed:
            hashed[e.path] = result.input_sha256.get(str(e.path)) or sha256_file(e.path)
        inputs.append({"file": str(e.path), "group": e.group, "sha256": hashed[e.path],
                       "step": e.step, "cycle": e.cycle, "dc_torque_nm": e.dc_torque_nm})
    return {
        "torquemod_version": __version__,
        "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "command": command,
        "software": software_versions(),
        "experiment": {
            "manifest": str(exp.manifest_path),
            "manifest_sha256": sha256_file(exp.manifest_path),
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


def write_results(result: ProcessResult, out_dir: str | Path, *, force: bool = False,
                  command: list[str] | None = None,
                  post: Callable[[Path], object] | None = None) -> Path:
    """Write the results folder atomically (see :func:`torquemod.fsutil.atomic_dir`).

    ``post(folder)`` runs on the complete but not yet published folder (the fit and report
    stages), so a failure there leaves nothing behind either."""
    prov = provenance(result, command=command)
    with atomic_dir(out_dir, force=force) as tmp:
        result.cycles.to_csv(tmp / "cycles.csv", index=False, float_format="%.10g")
        result.steps.to_csv(tmp / "steps.csv", index=False, float_format="%.10g")
        (tmp / "provenance.json").write_text(dump_json(prov), encoding="utf-8")
        np.savez(tmp / "traces.npz", **result.traces)
        if post is not None:
            post(tmp)
    return Path(out_dir)
