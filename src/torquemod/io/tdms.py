"""NI TDMS recordings (LabVIEW, NI DAQ), read with the optional package ``nptdms``.

Channels are found by the names of the manifest's ``[channels]`` table: ``"Group/Channel"``,
the TDMS path ``"/'Group'/'Channel'"``, or a bare channel name that is unique in the file (in
the recording's ``group`` when the manifest gives one). Units come from the manifest, else from
the channel's ``unit_string`` property. Without a time channel the sample rate is taken from
the waveform properties ``wf_increment`` [s] and ``wf_start_offset`` [s].
"""

from __future__ import annotations

import math
import re
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

_TDMS_PATH = re.compile(r"^/'(.+)'/'(.+)'$")
_HINT = "is the file complete and really TDMS?"


def _import_nptdms(path: Path):
    return import_optional("nptdms", what="TDMS", extra="tdms", path=path)


def _wf_rate(props: dict, path: Path, name: str) -> tuple[float | None, float]:
    """``(fs_hz, t0_s)`` from the waveform properties, ``(None, 0.0)`` when absent."""
    if "wf_increment" not in props:
        return None, 0.0
    try:
        dt = float(props["wf_increment"])
        t0 = float(props.get("wf_start_offset", 0.0))
    except (TypeError, ValueError):
        raise InputError(f"'{name}': wf_increment={props['wf_increment']!r} is not a number",
                         path=path) from None
    if not math.isfinite(dt) or dt <= 0:
        return None, 0.0  # no waveform timing (NI writes 0 for non-waveform channels)
    return 1.0 / dt, t0 if math.isfinite(t0) else 0.0


class _Index:
    """Group and channel names of an open TDMS file, and lookup by manifest name."""

    def __init__(self, tdms, path: Path, group: str | None) -> None:
        self.path, self.group = path, group
        try:
            self.groups = {g.name: {c.name: c for c in g.channels()} for g in tdms.groups()}
        except Exception as exc:  # nptdms on damaged metadata
            raise library_error(exc, path=path, what="cannot read the TDMS metadata",
                                hint=_HINT) from None
        if group is not None and group not in self.groups:
            raise InputError(f"no group '{group}' in the file (groups: "
                             f"{', '.join(self.groups) or 'none'})", path=path,
                             hint="check the 'group' entry in the manifest")

    def names(self) -> list[str]:
        return [f"{g}/{c}" for g, chans in self.groups.items() for c in chans]

    def find(self, name: str):
        m = _TDMS_PATH.match(name)
        if m and m.group(1) in self.groups:
            return self.groups[m.group(1)].get(m.group(2))
        for i, ch in enumerate(name):
            if ch == "/" and name[:i] in self.groups and name[i + 1:] in self.groups[name[:i]]:
                return self.groups[name[:i]][name[i + 1:]]
        if self.group is not None:
            return self.groups[self.group].get(name)
        hits = [g for g, chans in self.groups.items() if name in chans]
        if len(hits) > 1:
            raise InputError(f"channel '{name}' is in several groups ({', '.join(hits)})",
                             path=self.path, hint=f"map it as \"{hits[0]}/{name}\" in "
                             "[channels] or set the recording's 'group'")
        return self.groups[hits[0]][name] if hits else None

    def lookup(self, name: str) -> RawChannel | None:
        channel = self.find(name)
        if channel is None:
            return None
        try:
            values = np.asarray(channel[:])
            props = dict(channel.properties)
        except Exception as exc:  # nptdms on damaged data segments
            raise library_error(exc, path=self.path, what=f"cannot read channel '{name}'",
                                hint=_HINT) from None
        fs, t0 = _wf_rate(props, self.path, name)
        unit = props.get("unit_string")
        return RawChannel(values, unit if isinstance(unit, str) else None, fs_hz=fs, t0_s=t0)


def read_tdms(path: Path, *, group: str | None = None,
              channel_map: ChannelMap | dict | None = None) -> Recording:
    """Read a NI TDMS recording.

    Parameters
    ----------
    path : pathlib.Path
        The TDMS file.
    group : str or None
        The TDMS group searched for bare channel names; None: every group.
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
        The file cannot be opened or parsed as TDMS, or a channel is missing or ambiguous;
        the message names the file and, where one is at fault, the channel.
    """
    path = Path(path)
    cmap = resolve_channel_map(channel_map, path)
    nptdms = _import_nptdms(path)
    try:
        fh = open(path, "rb")  # ours to close: nptdms leaks its own handle when it fails
    except OSError as exc:
        raise InputError(f"cannot open ({exc.strerror})", path=path) from None
    with fh:
        try:
            tdms = nptdms.TdmsFile.open(fh)
        except Exception as exc:  # nptdms raises ValueError/struct.error/... on damage
            raise library_error(exc, path=path, what="cannot open as TDMS",
                                hint=_HINT) from None
        index = _Index(tdms, path, group)
        return assemble_recording(cmap, index.lookup, path=path,
                                  source=source_name(path, group), available=index.names)
