"""The experiment manifest ``experiment.toml`` (format in docs/format.md).

The format is written by hand by users: keys are checked and every mistake is reported with the
file, the key and what to do.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import tomli_w

from torquemod._util.tomlcheck import (
    POSITIVE,
    Check,
    between,
    check_key,
    checked,
    default_checks,
    prefixed,
    read_table,
)
from torquemod.errors import InputError, ManifestError
from torquemod.io.channels import resolve_channel_map
from torquemod.io.experiment import Experiment, RecordingEntry, Rig, TestSetup


@dataclass(frozen=True)
class RecordingTable:
    """One ``[[recording]]`` table as written, each key's check declared on its field.

    Attributes
    ----------
    step : int
        The torque step, from 1.
    dc_torque_nm : float
        Its DC torque [N*m].
    file : str
        The recording, relative to the manifest's folder.
    cycle : int or None
        The platform revolution, from 1 (None: the file may span several).
    group : str or None
        The group inside the file.
    sample_rate_hz : float or None
        The recording's sample rate [Hz], replacing the file's time base.
    note, comment : object
        Free text.
    """

    step: int = checked(check=between(1, None))
    dc_torque_nm: float = checked()
    file: str = checked(check=Check(test=lambda f: bool(f.strip()), need="a non-empty string"))
    cycle: int | None = checked(None, between(1, None))
    group: str | None = None
    sample_rate_hz: float | None = checked(None, POSITIVE)
    note: object = None
    comment: object = None


#: file suffixes of recordings (a recording given where the manifest belongs gets a clear
#: message instead of a TOML syntax error)
_RECORDING_SUFFIXES = {".csv": "CSV", ".h5": "HDF5", ".hdf5": "HDF5",
                       ".tdms": "TDMS", ".mf4": "MDF4", ".mdf": "MDF", ".mat": "MATLAB",
                       ".parquet": "Parquet", ".pq": "Parquet"}


def _load_toml(path: Path, name: str = "experiment.toml") -> dict:
    """The parsed manifest ``path`` (``name``: experiment.toml or run.toml, for messages)."""
    what = "experiment manifest" if name == "experiment.toml" else "run manifest"
    if not path.exists():
        raise ManifestError(f"{what} not found", path=path, hint=f"give the path of a {name}")
    if path.is_dir():
        candidate = path / name
        if candidate.exists():
            path = candidate
        else:
            raise ManifestError(f"is a folder without {name}", path=path)
    kind = _RECORDING_SUFFIXES.get(path.suffix.lower())
    if kind is not None:
        raise ManifestError(f"is a {kind} recording, not a{'n' if what[0] == 'e' else ''} "
                            f"{what}", path=path,
                            hint=f"write a {name} that lists it under [[recording]] "
                            "(docs/format.md), or convert it with 'torquemod convert'")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ManifestError(f"cannot read the manifest ({exc})", path=path) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        # tomllib's message already says "(at line L, column C)"
        text = str(exc)
        hint = "fix the line named"
        if text.startswith(("Cannot overwrite a value", "Cannot declare")):
            hint = "a key or table is given twice; keep one of them"
        raise ManifestError(f"TOML syntax error: {text}", path=path, hint=hint) from None


def _recording_entry(i: int, rec: dict, folder: Path, path: Path) -> RecordingEntry:
    where = f"recording #{i + 1}"
    r = read_table(RecordingTable, rec, section="recording", path=path, key_prefix="",
                   error=prefixed(where, ManifestError))
    resolved, group, fs = recording_file(rec, where, folder, path)
    return RecordingEntry(step=r.step, cycle=r.cycle, dc_torque_nm=r.dc_torque_nm,
                          path=resolved, group=group, index=i, sample_rate_hz=fs)


def recording_file(rec: dict, where: str, folder: Path, path: Path, kind: str = "experiment"
                   ) -> tuple[Path, str | None, float | None]:
    """The checked file, group and sample rate of one ``[[recording]]`` table.

    Shared by experiment.toml and run.toml; each value is checked as
    :class:`RecordingTable` declares it.

    Parameters
    ----------
    rec : dict
        The table.
    where : str
        The entry, named in messages (e.g. "recording #2").
    folder : pathlib.Path
        The manifest's folder; ``file`` is resolved inside it.
    path : pathlib.Path
        The manifest, named in messages.
    kind : str
        "experiment" or "run", for messages. Default "experiment".

    Returns
    -------
    file : pathlib.Path
        The resolved file.
    group : str or None
        The group inside it.
    sample_rate_hz : float or None
        Its sample rate [Hz].

    Raises
    ------
    ManifestError
        ``file`` empty or pointing outside the folder, ``group`` not a string, or
        ``sample_rate_hz`` not a positive number.
    """
    error = prefixed(where, ManifestError)

    def value(key: str):
        v = rec.get(key)
        return v if v is None else check_key(RecordingTable, key, v, key, path, error=error)
    file = value("file")
    resolved = (folder / file).resolve()
    if not resolved.is_relative_to(folder.resolve()):
        raise ManifestError(f"{where}: file '{file}' points outside the {kind} folder",
                            path=path, hint=f"copy the recording into the {kind} folder")
    return resolved, value("group"), value("sample_rate_hz")


def checked_channel_map(channel_map: object, path: Path, rates=()) -> dict:
    """A manifest's raw ``[channels]`` table after checking it.

    Each recording's ``sample_rate_hz`` is checked against it too.

    Parameters
    ----------
    channel_map : object
        The table as read (None or a dict).
    path : pathlib.Path
        The manifest, named in messages.
    rates : sequence of float or None
        The recordings' own ``sample_rate_hz`` [Hz], in manifest order. Default ().

    Returns
    -------
    dict
        The table, unchanged.

    Raises
    ------
    ManifestError
        Not a table, a bad key or unit, or a sample rate that cannot be used with it.
    """
    if not isinstance(channel_map, dict):
        raise ManifestError("[channels] must be a table", path=path)
    try:  # checked here so a mistake in [channels] shows before any recording is read
        cmap = resolve_channel_map(channel_map, path)
    except InputError as exc:  # same text, raised as a manifest error
        err = ManifestError(str(exc))
        err.path, err.channel, err.hint = exc.path, exc.channel, exc.hint
        raise err from None
    for i, fs in enumerate(rates):
        try:
            cmap.with_sample_rate(fs)
        except InputError as exc:  # named by the recording and its key
            raise ManifestError(f"recording #{i + 1}: 'sample_rate_hz' = {fs!r} cannot be "
                                f"used: {exc}", path=path, hint="give the sample rate either "
                                "in the [[recording]] or as the recording's time channel in "
                                "[channels], not both") from None
    return channel_map


def read_experiment(path: str | Path) -> Experiment:
    """Parse and validate an ``experiment.toml``; the recordings are not opened.

    Parameters
    ----------
    path : str or pathlib.Path
        The manifest.

    Returns
    -------
    Experiment
        The parsed experiment.

    Raises
    ------
    ManifestError
        An unreadable file, TOML syntax, or anything :func:`experiment_from_doc` refuses; the
        message names the file and key.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "experiment.toml"
    return experiment_from_doc(_load_toml(path), path)


def experiment_from_doc(doc: dict, path: str | Path) -> Experiment:
    """Check the tables of an already parsed ``experiment.toml`` and build the experiment.

    Nothing is read.

    Parameters
    ----------
    doc : dict
        The parsed TOML.
    path : str or pathlib.Path
        Where the manifest is (or would be): its folder holds the recordings and messages
        name it.

    Returns
    -------
    Experiment
        The experiment.

    Raises
    ------
    ManifestError
        A train run, no recordings, a missing section or key, an unknown key, a bad value, a
        recording listed twice, or a step with two DC torques.
    """
    path = Path(path)
    if "vehicle" in doc and "rig" not in doc:
        raise ManifestError("is a train run (it has [vehicle], no [rig])", path=path,
                            hint="process it with 'torquemod onboard' (docs/format.md)")
    for section in ("rig", "test"):
        if not isinstance(doc.get(section), dict):
            raise ManifestError(f"missing section [{section}]", path=path,
                                hint="see docs/format.md for the manifest layout")
    positive = {"checks": default_checks(Rig, {}) | default_checks(TestSetup, {}),
                "path": path, "error": ManifestError, "extra": "extra"}
    rig = read_table(Rig, doc["rig"], section="rig", **positive)
    test = read_table(TestSetup, doc["test"], section="test", **positive)
    recs = doc.get("recording", [])
    if not isinstance(recs, list) or not recs:
        raise ManifestError("the experiment lists no [[recording]]", path=path,
                            hint="add one [[recording]] table per recorded file")
    folder = path.parent
    entries = tuple(_recording_entry(i, r, folder, path) for i, r in enumerate(recs))
    seen: dict[tuple, int] = {}
    for e in entries:
        key = (e.step, e.cycle, e.path, e.group)
        if e.cycle is not None:
            key = (e.step, e.cycle)
        if key in seen:
            what = f"step {e.step} cycle {e.cycle}" if e.cycle else f"step {e.step} file {e.path}"
            raise ManifestError(f"{what} is listed twice (recordings #{seen[key] + 1} and "
                                f"#{e.index + 1})", path=path, hint="remove the duplicate")
        seen[key] = e.index
    files: dict[tuple, int] = {}
    for e in entries:  # one file (group) read twice would count its cycles twice
        if (e.path, e.group) in files:
            what = f"file '{e.path.name}'" + (f" group '{e.group}'" if e.group else "")
            raise ManifestError(f"{what} is listed twice (recordings #{files[e.path, e.group] + 1}"
                                f" and #{e.index + 1})", path=path,
                                hint="give each recorded file (or group) once")
        files[e.path, e.group] = e.index
    dc_by_step: dict[int, float] = {}
    for e in entries:
        if e.step in dc_by_step and not math.isclose(dc_by_step[e.step], e.dc_torque_nm,
                                                     rel_tol=1e-9, abs_tol=1e-9):
            raise ManifestError(f"step {e.step} has different dc_torque_nm values "
                                f"({dc_by_step[e.step]} and {e.dc_torque_nm})", path=path,
                                hint="give every recording of a step the same DC torque, or "
                                "number the steps apart")
        dc_by_step.setdefault(e.step, e.dc_torque_nm)
    channel_map = checked_channel_map(doc.get("channels", {}), path,
                                      [e.sample_rate_hz for e in entries])
    extra = {k: v for k, v in doc.items() if k not in ("rig", "test", "recording", "channels")}
    return Experiment(manifest_path=path.resolve(), rig=rig, test=test, recordings=entries,
                      channel_map=channel_map, extra=extra)


def write_manifest(path: str | Path, *, rig: dict, test: dict, recordings: list[dict],
                   extra: dict | None = None) -> Path:
    """Write an ``experiment.toml`` from plain dicts (the inverse of :func:`read_experiment`).

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    rig : dict
        The ``[rig]`` table (``wheel_radius_m`` [m], ``platform_radius_m`` [m], ...).
    test : dict
        The ``[test]`` table (``normal_load_n`` [N], ``modulation_frequency_hz`` [Hz],
        ``modulation_amplitude_nm`` [N*m], ...).
    recordings : list of dict
        With ``step``, optional ``cycle``, ``dc_torque_nm`` [N*m], ``file``.
    extra : dict or None
        Further top-level tables. Default None.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    doc = {"rig": dict(rig), "test": dict(test)}
    if extra:
        doc.update(extra)
    doc["recording"] = [dict(r) for r in recordings]
    path.write_text(tomli_w.dumps(doc), encoding="utf-8")
    return path
