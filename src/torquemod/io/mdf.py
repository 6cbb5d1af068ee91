"""ASAM MDF4 (and MDF3) recordings from data loggers, read with the optional package
``asammdf``.

Channels are found by the names of the manifest's ``[channels]`` table; a name that occurs in
several channel groups needs the recording's ``group`` (the channel-group index, ``"0"``,
``"1"``, ...). Units come from the manifest, else from the channel's own unit. Without a
mapped time channel the time base is the channel group's master channel (time stamps [s]).
"""

from __future__ import annotations

import functools
import gc
import sys
from pathlib import Path

import numpy as np

from torquemod.errors import InputError
from torquemod.io.channels import (
    ChannelMap,
    RawChannel,
    import_optional,
    library_error,
    resolve_channel_map,
    source_name,
)
from torquemod.io.experiment import Recording
from torquemod.io.timebase import assemble_recording

_HINT = "is the file complete and really MDF?"
#: Largest ratio of a group's data to the file size: deflate, MDF4's usual compression,
#: cannot expand by more than 1032:1. A larger claim is a damaged record count or size.
_MAX_EXPANSION = 1100
_VIRTUAL_TYPES = (3, 6)  # MDF4 virtual (master) channels: no bytes in the record


def _import_asammdf(path: Path):
    return import_optional("asammdf", what="MDF", extra="mdf", path=path)


def _group_index(group: str | None, n_groups: int, path: Path) -> int | None:
    if group is None:
        return None
    text = str(group).strip()
    if not text.isdigit() or int(text) >= n_groups:
        raise InputError(f"group '{group}' is not a channel-group index of this file "
                         f"(0 to {n_groups - 1})", path=path,
                         hint="for MDF files 'group' is the channel-group index, e.g. \"1\"")
    return int(text)


def _check_layout(mdf, path: Path) -> None:
    """Reject damaged record layouts before asammdf reads any data.

    asammdf's compiled record slicer trusts the channel's byte offset (a damaged offset makes
    it read past its buffer and crash the interpreter), and it loops over the claimed record
    count and size (a damaged count makes it run for minutes).
    """
    if not str(getattr(mdf, "version", "")).startswith("4"):
        return
    budget = _MAX_EXPANSION * path.stat().st_size + 2**20
    for g, grp in enumerate(mdf.groups):
        cg = grp.channel_group
        record = int(cg.samples_byte_nr) + int(cg.invalidation_bytes_nr)
        if record * int(cg.cycles_nr) > budget:
            raise InputError(f"channel group {g} claims {cg.cycles_nr} records of {record} "
                             "bytes, more data than the file can hold", path=path, hint=_HINT)
        for ch in grp.channels:
            if ch.channel_type in _VIRTUAL_TYPES:
                continue
            n_bytes = -(-(int(ch.bit_offset) + int(ch.bit_count)) // 8)
            if ch.bit_count <= 0 or ch.byte_offset < 0 or ch.byte_offset + n_bytes > record:
                raise InputError(f"channel '{ch.name}' of channel group {g} lies outside its "
                                 f"record (byte {ch.byte_offset} + {n_bytes} of {record})",
                                 path=path, hint=_HINT)


class _Index:
    def __init__(self, mdf, path: Path, group: str | None) -> None:
        self.mdf, self.path = mdf, path
        try:
            self.db = {name: [tuple(o) for o in occ] for name, occ in mdf.channels_db.items()}
            n_groups = len(mdf.groups)
        except Exception as exc:  # asammdf on damaged blocks
            raise library_error(exc, path=path, what="cannot read the MDF channel list",
                                hint=_HINT) from None
        _check_layout(mdf, path)
        self.group = _group_index(group, n_groups, path)

    def names(self) -> list[str]:
        return [n for n, occ in self.db.items()
                if self.group is None or any(g == self.group for g, _ in occ)]

    def lookup(self, name: str) -> RawChannel | None:
        occ = [o for o in self.db.get(name, []) if self.group is None or o[0] == self.group]
        if not occ:
            return None
        if len({g for g, _ in occ}) > 1:
            groups = ", ".join(str(g) for g, _ in occ)
            raise InputError(f"channel '{name}' is in several channel groups ({groups})",
                             path=self.path,
                             hint="set the recording's 'group' to the channel-group index")
        g, i = occ[0]
        try:
            sig = self.mdf.get(name, group=g, index=i)
            values, times, unit = np.asarray(sig.samples), np.asarray(sig.timestamps), sig.unit
        except Exception as exc:  # asammdf on damaged data blocks
            raise library_error(exc, path=self.path, what=f"cannot read channel '{name}'",
                                hint=_HINT) from None
        return RawChannel(values, unit if isinstance(unit, str) else None, time_s=times)


def _drop_asammdf_finalizer_errors(unraisable, previous=None) -> None:
    """``sys.unraisablehook`` that hides errors of asammdf finalizers (``__del__`` of an
    object whose constructor failed on a damaged file) and passes on everything else."""
    obj = unraisable.object
    if getattr(obj, "__name__", "") == "__del__" and \
            str(getattr(obj, "__module__", "")).startswith("asammdf"):
        return
    (previous or sys.__unraisablehook__)(unraisable)


def _open(asammdf, path: Path):
    """``(MDF, None)`` or ``(None, InputError)``.

    When asammdf fails half way, its half-built object's ``__del__`` fails too and would
    print a traceback of asammdf internals; that object is released here, with those
    finalizer errors hidden, so the user sees only the InputError.
    """
    error = None
    previous = sys.unraisablehook
    sys.unraisablehook = functools.partial(_drop_asammdf_finalizer_errors, previous=previous)
    try:
        try:
            return asammdf.MDF(path), None
        except Exception as exc:  # asammdf raises MdfException/struct.error/... on damage
            error = library_error(exc, path=path, what="cannot open as MDF", hint=_HINT)
        gc.collect()  # the half-built object is in a reference cycle
    finally:
        sys.unraisablehook = previous
    return None, error


def read_mdf(path: Path, *, group: str | None = None,
             channel_map: ChannelMap | dict | None = None) -> Recording:
    """Read an MDF (ASAM MDF 3/4) recording.

    Parameters
    ----------
    path : pathlib.Path
        The MDF file.
    group : str or None
        A channel-group index (as text); None: channels searched in every group.
    channel_map : ChannelMap or dict or None
        The manifest's ``[channels]`` table (raw or resolved,
        :func:`~torquemod.io.channels.resolve_channel_map`); None reads the method's channel
        names (:data:`~torquemod.io.experiment.CHANNELS`) in SI units.

    Returns
    -------
    Recording
        The channels in SI units on a uniform time base (NaN and inf are not checked here:
        the NaN policy is the pipeline's).

    Raises
    ------
    InputError
        The file cannot be opened as MDF, or a channel is missing, ambiguous or on another
        time base; the message names the file and, where one is at fault, the channel.
    """
    path = Path(path)
    cmap = resolve_channel_map(channel_map, path)
    asammdf = _import_asammdf(path)
    mdf, error = _open(asammdf, path)
    if error is not None:
        raise error
    try:
        index = _Index(mdf, path, group)
        return assemble_recording(cmap, index.lookup, path=path,
                                  source=source_name(path, group), available=index.names)
    finally:
        try:
            mdf.close()
        except Exception:  # closing a damaged file; the reading result stands
            pass
