"""Convert recordings in any supported format into the project's HDF5 layout, or, for one
file, into Parquet, MATLAB ``.mat`` or CSV (chosen by the output's suffix).

``torquemod convert`` calls these; the files they write hold the channels the input has
(absent optional channels stay absent) in SI units with their sample rate (the HDF5 files
also the reader's notes, ``torquemod_notes``), so they read back without any ``[channels]``
table. Parquet and ``.mat`` keep every float64 bit; CSV writes 9 significant digits.
"""

from __future__ import annotations

import os
import re
import tomllib
from pathlib import Path

from torquemod._util.fsutil import atomic_dir, atomic_file
from torquemod._version import __version__
from torquemod.errors import InputError
from torquemod.io.channels import ChannelMap
from torquemod.io.hdf5 import write_hdf5
from torquemod.io.manifest import read_experiment, write_manifest
from torquemod.io.recording import read_entry, read_recording, write_recording

_H5_SUFFIXES = (".h5", ".hdf5")
#: output suffix -> writer format of :func:`torquemod.io.recording.write_recording`
_OUTPUT_FORMATS = {".h5": "hdf5", ".hdf5": "hdf5", ".parquet": "parquet", ".mat": "mat",
                   ".csv": "csv"}
#: Per-recording manifest keys that describe the source file and are dropped on conversion.
_SOURCE_KEYS = ("file", "group", "sample_rate_hz")


def _attrs(source: Path, group: str | None) -> dict:
    attrs = {"converted_from": str(source), "torquemod_version": __version__}
    if group:
        attrs["converted_from_group"] = group
    return attrs


def convert_file(input_path: str | Path, output_path: str | Path, *,
                 channel_map: ChannelMap | dict | None = None, group: str | None = None,
                 sample_rate_hz: float | None = None, force: bool = False) -> Path:
    """Convert one recording (any supported format) to the project's layout.

    HDF5, or Parquet, ``.mat`` or CSV when the output is named so. The output is written
    whole or not at all (:func:`~torquemod._util.fsutil.atomic_file`).

    Parameters
    ----------
    input_path : str or pathlib.Path
        The recording.
    output_path : str or pathlib.Path
        The output, ``.h5``/``.hdf5``, ``.parquet``, ``.mat`` or ``.csv``.
    channel_map : ChannelMap or dict or None
        A manifest ``[channels]`` table (raw or resolved). Default None.
    group : str or None
        The group inside the input. Default None.
    sample_rate_hz : float or None
        Sample rate [Hz] overriding the input's time base
        (:func:`torquemod.io.recording.read_recording`). Default None.
    force : bool
        Replace an existing output (never the input). Default False.

    Returns
    -------
    pathlib.Path
        The output.

    Raises
    ------
    InputError
        An unknown output suffix, a missing or unreadable input, an existing output without
        ``force``, or the output being the input.
    """
    src, out = Path(input_path), Path(output_path)
    fmt = _OUTPUT_FORMATS.get(out.suffix.lower())
    if fmt is None:
        raise InputError(f"output must be {', '.join(_OUTPUT_FORMATS)}", path=out,
                         hint="name the output like recording.h5 (or .parquet, .mat, .csv)")
    if not src.is_file():
        raise InputError("no such recording file" if not src.exists() else
                         "is not a recording file", path=src, hint="check the INPUT path")
    with atomic_file(out, force=force, inputs=[src]) as tmp:
        rec = read_recording(src, group=group, channel_map=channel_map,
                             sample_rate_hz=sample_rate_hz)
        if fmt == "hdf5":
            write_hdf5(tmp, rec, attrs=_attrs(src, group))
        else:
            write_recording(tmp, rec, fmt=fmt)
    return out


def convert_listed_file(input_path: str | Path, manifest_path: str | Path,
                        output_path: str | Path, *, force: bool = False) -> Path:
    """Convert one recording with an experiment's ``[channels]`` table.

    ``torquemod convert INPUT --manifest experiment.toml --out OUT.h5`` (docs/format.md).
    When the manifest lists ``input_path``, that entry's ``group`` and ``sample_rate_hz``
    apply too; a logger file that needs a map (names, units, its channels' own time vectors)
    converts this way.

    Parameters
    ----------
    input_path : str or pathlib.Path
        The recording.
    manifest_path : str or pathlib.Path
        The experiment.toml.
    output_path : str or pathlib.Path
        The output.
    force : bool
        Replace an existing output. Default False.

    Returns
    -------
    pathlib.Path
        The output.

    Raises
    ------
    InputError
        As :func:`convert_file`, or a bad manifest.
    """
    exp = read_experiment(manifest_path)
    src = Path(input_path)
    entry = next((e for e in exp.recordings if _same_file(e.path, src)), None)
    return convert_file(src, output_path, channel_map=exp.channel_map,
                        group=entry.group if entry else None,
                        sample_rate_hz=entry.sample_rate_hz if entry else None, force=force)


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return Path(a).absolute() == Path(b).absolute()


def _file_name(stem: str, group: str | None, used: set[str]) -> str:
    base = stem + (f"_{group}" if group else "")
    base = re.sub(r"[^A-Za-z0-9_.-]+", "_", base).strip("._") or "recording"
    name, k = f"{base}.h5", 2
    while name.lower() in used:
        name, k = f"{base}_{k}.h5", k + 1
    used.add(name.lower())
    return name


def convert_experiment(manifest_path: str | Path, out_dir: str | Path, *,
                       force: bool = False) -> Path:
    """Convert every recording of an experiment to HDF5, with a rewritten manifest.

    The new ``experiment.toml`` keeps the rig, test and recording keys, without
    ``[channels]``, ``group`` or ``sample_rate_hz`` (which the HDF5 files no longer need).
    ``out_dir`` is built in a temporary folder and renamed into place at the end, so it is
    complete or absent (:func:`~torquemod._util.fsutil.atomic_dir`).

    Parameters
    ----------
    manifest_path : str or pathlib.Path
        The experiment.toml.
    out_dir : str or pathlib.Path
        The output folder; never is nor holds the experiment's manifest or recordings.
    force : bool
        Replace an existing non-empty ``out_dir``, only if torquemod wrote it. Default False.

    Returns
    -------
    pathlib.Path
        The new manifest.

    Raises
    ------
    InputError
        A bad manifest or recording, an occupied ``out_dir``, or one holding the inputs.
    """
    exp = read_experiment(manifest_path)
    out = Path(out_dir).absolute()
    folder = exp.folder.resolve()
    if out.resolve() == folder or folder.is_relative_to(out.resolve()):
        raise InputError("the output folder holds the experiment being converted", path=out,
                         hint="choose a new folder for --out")
    doc = tomllib.loads(exp.manifest_path.read_text(encoding="utf-8"))
    raw_recordings = doc.get("recording", [])
    written: dict[tuple, str] = {}
    used: set[str] = {"experiment.toml"}
    new_recordings = []
    inputs = [exp.manifest_path, *(e.path for e in exp.recordings)]
    with atomic_dir(out, force=force, inputs=inputs, kind="converted experiment") as tmp:
        for entry, raw in zip(exp.recordings, raw_recordings, strict=True):
            key = (entry.path, entry.group, entry.sample_rate_hz)
            if key not in written:
                rec = read_entry(exp, entry)
                name = _file_name(entry.path.stem, entry.group, used)
                write_hdf5(tmp / name, rec, attrs=_attrs(entry.path, entry.group))
                written[key] = name
            new = {k: v for k, v in raw.items() if k not in _SOURCE_KEYS}
            new["file"] = written[key]
            new_recordings.append(new)
        extra = {k: v for k, v in doc.items() if k not in ("rig", "test", "recording",
                                                             "channels")}
        write_manifest(tmp / "experiment.toml", rig=doc["rig"], test=doc["test"],
                       recordings=new_recordings, extra=extra)
    return out / "experiment.toml"
