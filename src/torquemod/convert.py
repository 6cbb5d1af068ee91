"""Convert recordings in any supported format into the project's HDF5 layout.

``torquemod convert`` calls these; the HDF5 files they write hold the channels the input has
(absent optional channels stay absent) in SI units with their sample rate and the reader's
notes (``torquemod_notes``), so they read back without any ``[channels]`` table.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
import tomllib
from pathlib import Path

from ._version import __version__
from .data import Recording
from .errors import InputError, OutputError
from .fsutil import atomic_dir
from .io.channels import ChannelMap
from .io.hdf5 import write_hdf5
from .io.manifest import read_experiment, write_manifest
from .io.recording import read_entry, read_recording

_H5_SUFFIXES = (".h5", ".hdf5")
#: Per-recording manifest keys that describe the source file and are dropped on conversion.
_SOURCE_KEYS = ("file", "group", "sample_rate_hz")


def _attrs(source: Path, group: str | None) -> dict:
    attrs = {"converted_from": str(source), "torquemod_version": __version__}
    if group:
        attrs["converted_from_group"] = group
    return attrs


def _write_h5_atomic(out: Path, rec: Recording, attrs: dict) -> None:
    """Write ``rec`` to ``out`` via a temporary file beside it and one rename."""
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp_dir = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    except OSError as exc:
        raise OutputError(f"{out}: cannot create the output file ({exc.strerror})") from None
    try:
        tmp = tmp_dir / out.name
        write_hdf5(tmp, rec, attrs=attrs)
        os.replace(tmp, out)
    except OSError as exc:
        raise OutputError(f"{out}: cannot write ({exc.strerror or exc})") from None
    finally:
        shutil.rmtree(tmp_dir, ignore_errors=True)


def convert_file(input_path: str | Path, output_path: str | Path, *,
                 channel_map: ChannelMap | dict | None = None, group: str | None = None,
                 sample_rate_hz: float | None = None) -> Path:
    """Read one recording (any supported format) and write it as the project's HDF5 layout.

    ``channel_map`` is a manifest ``[channels]`` table (raw or resolved), ``group`` the group
    inside the input, ``sample_rate_hz`` [Hz] overrides the input's time base (see
    :func:`torquemod.io.recording.read_recording`). The output (``.h5``/``.hdf5``) is written
    whole or not at all and replaced if it exists. Returns the output path.
    """
    src, out = Path(input_path), Path(output_path)
    if out.suffix.lower() not in _H5_SUFFIXES:
        raise InputError(f"output must be an HDF5 file ({', '.join(_H5_SUFFIXES)})", path=out,
                         hint="name the output like recording.h5")
    if out.exists() and src.exists() and out.resolve() == src.resolve():
        raise InputError("output is the input file", path=out, hint="choose another --out")
    rec = read_recording(src, group=group, channel_map=channel_map,
                         sample_rate_hz=sample_rate_hz)
    _write_h5_atomic(out, rec, _attrs(src, group))
    return out


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
    """Convert every recording of an experiment to HDF5 in ``out_dir``, with a rewritten
    ``experiment.toml`` that lists them (same rig, test and recording keys; no
    ``[channels]``, ``group`` or ``sample_rate_hz``, which the HDF5 files no longer need).

    ``out_dir`` is built in a temporary folder and renamed into place at the end, so it is
    complete or absent; an existing non-empty ``out_dir`` is replaced only with ``force``.
    Returns the path of the new manifest.
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
    with atomic_dir(out, force=force) as tmp:
        for entry, raw in zip(exp.recordings, raw_recordings, strict=True):
            key = (entry.path, entry.group, entry.sample_rate_hz)
            if key not in written:
                rec = read_entry(exp, entry)
                name = _file_name(entry.path.stem, entry.group, used)
                _write_h5_atomic(tmp / name, rec, _attrs(entry.path, entry.group))
                written[key] = name
            new = {k: v for k, v in raw.items() if k not in _SOURCE_KEYS}
            new["file"] = written[key]
            new_recordings.append(new)
        extra = {k: v for k, v in doc.items() if k not in ("rig", "test", "recording",
                                                             "channels")}
        write_manifest(tmp / "experiment.toml", rig=doc["rig"], test=doc["test"],
                       recordings=new_recordings, extra=extra)
    return out / "experiment.toml"
