"""Format dispatch: read any supported recording into a
:class:`~torquemod.io.experiment.Recording`."""

from __future__ import annotations

import importlib
from pathlib import Path

from torquemod.errors import InputError
from torquemod.io.channels import ChannelMap, resolve_channel_map
from torquemod.io.experiment import Experiment, Recording, RecordingEntry
from torquemod.io.validate import check_channels

#: suffix -> (module of this package, its reader); a format's module (h5py, scipy.io,
#: pyarrow behind them) is imported when a file of that format is first read
_READERS = {
    ".csv": ("csv", "read_csv"),
    ".txt": ("csv", "read_csv"),
    ".h5": ("hdf5", "read_hdf5"),
    ".hdf5": ("hdf5", "read_hdf5"),
    ".tdms": ("tdms", "read_tdms"),
    ".mf4": ("mdf", "read_mdf"),
    ".mdf": ("mdf", "read_mdf"),
    ".mat": ("matlab", "read_mat"),
    ".parquet": ("parquet", "read_parquet"),
    ".pq": ("parquet", "read_parquet"),
}
_WRITERS = {
    "csv": ("csv", "write_csv"),
    "hdf5": ("hdf5", "write_hdf5"),
    "parquet": ("parquet", "write_parquet"),
    "mat": ("matlab", "write_mat"),
}


def _function(module: str, name: str):
    return getattr(importlib.import_module(f".{module}", __package__), name)


def supported_suffixes() -> list[str]:
    """File suffixes :func:`read_recording` can read.

    Returns
    -------
    list of str
        Lower-case suffixes with the dot, e.g. ".csv".
    """
    return sorted(_READERS)


def read_recording(path: str | Path, *, group: str | None = None,
                   channel_map: ChannelMap | dict | None = None,
                   sample_rate_hz: float | None = None) -> Recording:
    """Read one recording file; the format is chosen by the file's suffix.

    Parameters
    ----------
    path : str or pathlib.Path
        The file.
    group : str or None
        A group inside the file (meaning per format: HDF5 group, TDMS group, .mat struct, MDF
        channel-group index). Default None.
    channel_map : ChannelMap or dict or None
        The manifest's ``[channels]`` table (raw or resolved,
        :func:`~torquemod.io.channels.resolve_channel_map`); None reads the method's channel
        names (:data:`~torquemod.io.experiment.CHANNELS`) in SI units.
    sample_rate_hz : float or None
        Sample rate [Hz] that overrides the time base of the file and of the map (the
        per-recording manifest key). Default None.

    Returns
    -------
    Recording
        The channels in SI units on a uniform time base (NaN and inf are not checked here:
        the NaN policy is the pipeline's).

    Raises
    ------
    InputError
        The file is missing, a folder, of an unknown format or unreadable, or the format's
        reader refuses it; the message names the file and channel.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("recording file not found", path=path,
                         hint="check the 'file' entry in the manifest")
    if path.is_dir():
        raise InputError("is a folder, not a recording file", path=path)
    try:  # an unreadable file is named here, whatever library reads it later
        with open(path, "rb") as fh:
            fh.read(1)
    except OSError as exc:
        raise InputError(f"cannot read the recording ({exc.strerror})", path=path,
                         hint="check the file's permissions") from None
    reader = _READERS.get(path.suffix.lower())
    if reader is not None:
        reader = _function(*reader)
    if reader is None:
        known = ", ".join(sorted(_READERS))
        raise InputError(f"unknown recording format '{path.suffix}'", path=path,
                         hint=f"use one of {known}")
    cmap = resolve_channel_map(channel_map, path).with_sample_rate(sample_rate_hz, path=path)
    rec = reader(path, group=group, channel_map=cmap)
    check_channels(rec, path=path)
    return rec


def read_entry(experiment: Experiment, entry: RecordingEntry) -> Recording:
    """Read one ``[[recording]]`` of an experiment.

    Parameters
    ----------
    experiment : Experiment
        The experiment (its ``[channels]`` map).
    entry : RecordingEntry
        The entry (its file, group and own ``sample_rate_hz``).

    Returns
    -------
    Recording
        As :func:`read_recording` gives it.

    Raises
    ------
    InputError
        As :func:`read_recording`.
    """
    return read_recording(entry.path, group=entry.group, channel_map=experiment.channel_map,
                          sample_rate_hz=entry.sample_rate_hz)


def write_recording(path: str | Path, rec: Recording, *, fmt: str = "csv", **kwargs) -> Path:
    """Write a recording in one of the project's layouts (docs/format.md).

    Parameters
    ----------
    path : str or pathlib.Path
        The file to write.
    rec : Recording
        The recording.
    fmt : {"csv", "hdf5", "parquet", "mat"}
        The layout. Default "csv".
    **kwargs
        Passed to the layout's writer (e.g. ``group`` for HDF5).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        An unknown ``fmt``, or the file cannot be written.
    """
    try:
        writer = _function(*_WRITERS[fmt])
    except KeyError:
        raise InputError(f"unknown output format '{fmt}'",
                         hint=f"use one of {', '.join(_WRITERS)}") from None
    return writer(Path(path), rec, **kwargs)
