"""Reading an on-board results folder (:func:`torquemod.ontrain.folder.save_onboard`) back
into an :class:`~torquemod.ontrain.result.OnboardResult` (:func:`load_onboard`,
:func:`torquemod.load_onboard`)."""

from __future__ import annotations

import json
from pathlib import Path

from torquemod.errors import InputError
from torquemod.io.run import Run, RunRecording, Vehicle
from torquemod.ontrain.estimator import OnboardConfig
from torquemod.ontrain.folder import META
from torquemod.ontrain.result import OnboardResult

__all__ = ["load_onboard"]


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
    """Read an on-board result back from the folder :func:`save_onboard` wrote.

    Parameters
    ----------
    folder : str or os.PathLike
        The results folder (``torquemod onboard --out``).
    axle : int or None
        The axle to read; None: the first listed. Default None.

    Returns
    -------
    OnboardResult
        The track as written, the run, the settings, the notes, the segments and the friction
        changes; the simulated truth when the run's ``[truth] file`` is still where it was.

    Raises
    ------
    InputError
        No ``onboard.json`` in ``folder``, it or the track table is unreadable or damaged, it
        lists no axles, or not ``axle``.
    """
    import pandas as pd

    from torquemod.io.truth import load_truth
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
