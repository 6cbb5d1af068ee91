"""Format dispatch: read any supported recording into a :class:`~torquemod.data.Recording`."""

from __future__ import annotations

from pathlib import Path

from ..data import Recording
from ..errors import InputError
from . import csv as csv_io
from . import hdf5 as hdf5_io
from .validate import check_channels

_READERS = {
    ".csv": csv_io.read_csv,
    ".txt": csv_io.read_csv,
    ".h5": hdf5_io.read_hdf5,
    ".hdf5": hdf5_io.read_hdf5,
}
_WRITERS = {
    "csv": csv_io.write_csv,
    "hdf5": hdf5_io.write_hdf5,
}


def register_reader(suffix: str, reader) -> None:
    """Make ``reader(path, *, group=None, channel_map=None) -> Recording`` handle ``suffix``."""
    _READERS[suffix.lower()] = reader


def read_recording(path: str | Path, *, group: str | None = None,
                   channel_map: dict | None = None) -> Recording:
    """Read one recording file; the format is chosen by the file's suffix.

    Raises :class:`~torquemod.errors.InputError` naming the file and channel on any problem.
    Finite values are *not* checked here (the NaN policy is the pipeline's).
    """
    path = Path(path)
    if not path.exists():
        raise InputError("recording file not found", path=path,
                         hint="check the 'file' entry in the manifest")
    reader = _READERS.get(path.suffix.lower())
    if reader is None:
        known = ", ".join(sorted(_READERS))
        raise InputError(f"unknown recording format '{path.suffix}'", path=path,
                         hint=f"use one of {known}")
    rec = reader(path, group=group, channel_map=channel_map)
    check_channels(rec, path=path)
    return rec


def write_recording(path: str | Path, rec: Recording, *, fmt: str = "csv", **kwargs) -> Path:
    """Write ``rec`` in the project's ``csv`` or ``hdf5`` layout (docs/format.md)."""
    try:
        writer = _WRITERS[fmt]
    except KeyError:
        raise InputError(f"unknown output format '{fmt}'", hint="use csv or hdf5") from None
    return writer(Path(path), rec, **kwargs)
