"""The channel map shared by every recording reader.

The manifest's ``[channels]`` table says which channel of a file feeds which channel of the
method, in which unit, and where the time base comes from (docs/format.md)::

    [channels]
    torque = { name = "Torque", unit = "kN*m" }
    wheel_speed = { name = "Wheel/Speed", unit = "rpm" }
    platform_speed = "PlatformSpeed"          # name only: the method's unit (rad/s)
    time = { name = "t", unit = "ms" }        # or: sample_rate_hz = 1000.0

Everything here is a pure function of its arguments: :func:`resolve_channel_map` reads the
table once (each entry as a :class:`ChannelEntry`, by
:func:`torquemod._util.tomlcheck.read_table`) and returns a frozen :class:`ChannelMap`;
:func:`torquemod.io.units.convert_units` turns values in a named unit into the method's SI
unit; :func:`torquemod.io.timebase.assemble_recording` builds
a :class:`~torquemod.io.experiment.Recording` from whatever a format reader found in its file.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, make_dataclass, replace
from pathlib import Path

import numpy as np

from torquemod._util.tomlcheck import Check, checked, read_table
from torquemod.errors import InputError
from torquemod.io.checks import positive_number
from torquemod.io.experiment import CHANNEL_UNITS, CHANNELS
from torquemod.io.units import convert_units, unit_factor

TIME = "time_s"
TORQUE = CHANNELS[0]  # the channel whose sample times are the recording's

#: Short manifest keys of the method's channels (the full names are accepted too).
SHORT_NAMES: dict[str, str] = {
    "time": TIME,
    "torque": "torque_nm",
    "wheel_speed": "wheel_speed_rad_s",
    "platform_speed": "platform_speed_rad_s",
    "fx": "fx_n",
    "fy": "fy_n",
    "fz": "fz_n",
    "vehicle_speed": "vehicle_speed_m_s",
    "position": "position_m",
}
#: The physical quantity of every method channel (and of the time column).
QUANTITY: dict[str, str] = {
    TIME: "time",
    "torque_nm": "torque",
    "wheel_speed_rad_s": "angular_speed",
    "platform_speed_rad_s": "angular_speed",
    "fx_n": "force",
    "fy_n": "force",
    "fz_n": "force",
    "vehicle_speed_m_s": "linear_speed",
    "position_m": "length",
}

_RATE_KEYS = ("sample_rate_hz", "t0_s")


@dataclass(frozen=True)
class ChannelSpec:
    """Where one method channel is found in a file.

    Attributes
    ----------
    channel : str
        The method channel, e.g. ``torque_nm``.
    name : str
        Its name in the file.
    unit : str or None
        Its unit in the file; None: the unit the file declares, else the method's SI unit.
    radius_m : float or None
        Radius turning a linear speed into an angular one [m]. Default None.
    explicit : bool
        Named in the ``[channels]`` table (an optional channel named there must exist).
    time : str or None
        The channel's own time vector in the file when it is not sampled with the torque.
    time_unit : str or None
        That vector's unit; None: the unit the file declares, else s.
    """

    channel: str
    name: str
    unit: str | None = None
    radius_m: float | None = None
    explicit: bool = False  # named in the manifest (not the default)
    time: str | None = None
    time_unit: str | None = None

    @property
    def quantity(self) -> str:
        return QUANTITY[self.channel]


@dataclass(frozen=True)
class ChannelMap:
    """A checked ``[channels]`` table: one :class:`ChannelSpec` per method channel and time.

    Attributes
    ----------
    specs : Mapping of str to ChannelSpec
        By method channel (and ``time_s``).
    sample_rate_hz : float or None
        Sample rate [Hz]; when given it replaces any time column or time base of the file.
    t0_s : float
        Time of the first sample with ``sample_rate_hz`` [s]. Default 0.
    raw : Mapping
        The table as written.
    """

    specs: Mapping[str, ChannelSpec]
    sample_rate_hz: float | None = None
    t0_s: float = 0.0
    raw: Mapping = field(default_factory=dict, compare=False)

    def spec(self, channel: str) -> ChannelSpec:
        return self.specs[channel]

    @property
    def time(self) -> ChannelSpec:
        return self.specs[TIME]

    def names(self) -> list[str]:
        """File names of the method channels (not time), in :data:`CHANNELS` order."""
        return [self.specs[c].name for c in CHANNELS]

    def own_time_names(self) -> list[str]:
        """File names of the channels' own time vectors (the ``time`` key of an entry)."""
        return list(dict.fromkeys(self.specs[c].time for c in CHANNELS
                                  if self.specs[c].time))

    def with_sample_rate(self, sample_rate_hz: float | None, t0_s: float | None = None,
                         *, path: object | None = None) -> ChannelMap:
        """This map with the time base replaced by a sample rate (None: unchanged)."""
        if sample_rate_hz is None:
            return self
        fs = _positive(sample_rate_hz, "sample_rate_hz", path)
        if self.time.explicit:
            raise InputError(f"both a sample rate ({fs} Hz) and a time channel "
                             f"('{self.time.name}') are given", path=path, channel=TIME,
                             hint="keep one of them")
        own = [c for c in CHANNELS if self.specs[c].time]
        if own:
            raise InputError(f"both a sample rate ({fs} Hz) and the channel's own time vector "
                             f"('{self.specs[own[0]].time}') are given", path=path,
                             channel=own[0], hint="keep one of them")
        return replace(self, sample_rate_hz=fs, t0_s=self.t0_s if t0_s is None else t0_s)


def default_channel_map() -> ChannelMap:
    """The map used without a ``[channels]`` table: the CSV names, SI units, ``time_s``.

    Returns
    -------
    ChannelMap
        The default map.
    """
    return ChannelMap({c: ChannelSpec(c, c) for c in (TIME, *CHANNELS)})


def _positive(value: object, key: str, path: object) -> float:
    return positive_number(value, key, path=path,
                           hint="give the value in SI units, e.g. sample_rate_hz = 1000.0")


_NAME = Check(test=lambda s: bool(s.strip()), need="a non-empty channel name",
              hint='write the name as the file has it, e.g. name = "Torque"')


@dataclass(frozen=True)
class TimeEntry:
    """An entry's ``time`` key as written: the channel's own time vector in the file.

    Attributes
    ----------
    name : str
        The time vector's name in the file.
    unit : str or None
        Its unit; None: the unit the file declares, else s.
    """

    name: str = checked(check=_NAME)
    unit: str | None = None


@dataclass(frozen=True)
class ChannelEntry:
    """One entry of the ``[channels]`` table as written (a bare name is ``{ name = ... }``).

    Attributes
    ----------
    name : str
        The channel's name in the file.
    unit : str or None
        Its unit in the file; None: the unit the file declares, else the method's SI unit.
    radius_m : float or None
        Radius turning a linear speed into an angular one [m] (speed channels only).
    time : TimeEntry or None
        The channel's own time vector (method channels only).
    """

    name: str = checked(check=_NAME)
    unit: str | None = None
    radius_m: float | None = checked(None, Check(lo=0.0, lo_open=True, hint=(
        "give the wheel or platform path radius in metres, e.g. radius_m = 0.0675")))
    time: TimeEntry | None = None


#: The ``[channels]`` table as written: one optional entry per method channel, by its short
#: and its full name (time included), and the time base as a sample rate and start time.
_ChannelsTable = make_dataclass("_ChannelsTable", [
    *((key, ChannelEntry | None, None) for key in (*SHORT_NAMES, *QUANTITY)),
    ("sample_rate_hz", float | None, checked(None, Check(lo=0.0, lo_open=True, hint=(
        "give the value in SI units, e.g. sample_rate_hz = 1000.0")))),
    ("t0_s", float | None, None)], frozen=True)


def _as_tables(raw: Mapping, path: object) -> dict:
    """``raw`` with every bare name written as the table ``{ name = ... }`` (an entry's and
    its ``time`` key's) and an entry without a name given the method channel's, so that
    :func:`read_table` reads one form."""
    out = {}
    for key, value in raw.items():
        if key in _RATE_KEYS or (key not in QUANTITY and key not in SHORT_NAMES):
            out[key] = value  # read_table checks the value or names the unknown key
            continue
        if isinstance(value, str):
            value = {"name": value}
        if not isinstance(value, Mapping):
            raise InputError(f"'channels.{key}' must be a channel name or a table like "
                             f"{{ name = \"Torque\", unit = \"N*m\" }}, got {value!r}",
                             path=path, hint=f'write {key} = "<the name in the file>"')
        value = {"name": SHORT_NAMES.get(key, key), **value}  # no name: the method's own
        if isinstance(value.get("time"), str):
            value["time"] = {"name": value["time"]}
        elif "time" in value and not isinstance(value["time"], Mapping):
            raise InputError(f"'channels.{key}.time' must be the name of the channel's own "
                             "time vector or a table like { name = \"t_fx\", unit = \"ms\" }, "
                             f"got {value['time']!r}", path=path)
        out[key] = value
    return out


def _spec(channel: str, key: str, entry: ChannelEntry, path: object) -> ChannelSpec:
    """The :class:`ChannelSpec` of a read entry, after the rules between its keys."""
    if entry.radius_m is not None and QUANTITY[channel] != "angular_speed":
        raise InputError(f"'channels.{key}.radius_m': radius_m only applies to the speed "
                         "channels (wheel_speed, platform_speed)", path=path, channel=channel,
                         hint="remove it")
    if entry.unit:  # checked now, so a mistake shows when the manifest is read
        unit_factor(entry.unit, QUANTITY[channel], radius_m=entry.radius_m, path=path,
                    channel=channel)
    time = entry.time
    if time is not None:
        if channel == TIME:
            raise InputError(f"'channels.{key}.time': 'time' only applies to the method "
                             "channels", path=path, channel=channel, hint="remove it")
        if time.unit:
            unit_factor(time.unit, "time", path=path, channel=channel)
    return ChannelSpec(channel, entry.name.strip(), entry.unit.strip() if entry.unit else None,
                       entry.radius_m, True, None if time is None else time.name.strip(),
                       time.unit.strip() if time is not None and time.unit else None)


def resolve_channel_map(raw: Mapping | ChannelMap | None, path: object = None) -> ChannelMap:
    """Check a manifest ``[channels]`` table and return the :class:`ChannelMap`.

    Keys are the method channels, short (``torque``, ``wheel_speed``, ``platform_speed``,
    ``fx``, ``fy``, ``fz``, ``time``) or full (``torque_nm``, ..., ``time_s``), each a file
    channel name or a table ``{ name, unit, radius_m, time }`` (``time``: the channel's own
    time vector, a name or ``{ name, unit }``); plus ``sample_rate_hz`` [Hz] and ``t0_s``
    [s]. Channels left out keep their default (the CSV name, SI unit).

    Parameters
    ----------
    raw : Mapping or ChannelMap or None
        The table; a ChannelMap is returned as it is; empty or None gives
        :func:`default_channel_map`.
    path : object
        The manifest, named in messages only.

    Returns
    -------
    ChannelMap
        The checked map.

    Raises
    ------
    InputError
        Not a table, an unknown key (with the nearest known one), a value of the wrong type
        or out of range, a channel mapped twice, a file channel mapped to two channels, a bad
        unit, or ``t0_s`` without ``sample_rate_hz``.

    Examples
    --------
    >>> cmap = resolve_channel_map({"torque": {"name": "T", "unit": "kN*m"}, "fx": "Fx"})
    >>> cmap.spec("torque_nm").unit, cmap.spec("fx_n").name
    ('kN*m', 'Fx')
    >>> try:
    ...     resolve_channel_map({"torqe": "T"}, "experiment.toml")
    ... except InputError as exc:
    ...     print(str(exc).split("?")[0] + "?")
    experiment.toml: unknown key 'channels.torqe'; did you mean 'torque'?
    """
    if isinstance(raw, ChannelMap):
        return raw
    if raw is None:
        raw = {}
    if not isinstance(raw, Mapping):
        raise InputError("[channels] must be a table", path=path)
    table = read_table(_ChannelsTable, _as_tables(raw, path), section="channels", path=path)
    specs = dict(default_channel_map().specs)
    given: dict[str, str] = {}
    for key in raw:
        if key in _RATE_KEYS:
            continue
        channel = SHORT_NAMES.get(key, key)
        if channel in given:
            raise InputError(f"[channels] maps '{channel}' twice ('{given[channel]}' and "
                             f"'{key}')", path=path, channel=channel, hint="keep one")
        given[channel] = key
        specs[channel] = _spec(channel, key, getattr(table, key), path)
    by_name: dict[str, str] = {}
    for channel in CHANNELS:
        name = specs[channel].name
        if name in by_name:
            raise InputError(f"file channel '{name}' is mapped to both {by_name[name]} and "
                             f"{channel}", path=path, channel=channel,
                             hint="each method channel needs its own file channel")
        by_name[name] = channel
    cmap = ChannelMap(specs, raw=dict(raw))
    if table.t0_s is not None and table.sample_rate_hz is None:
        raise InputError("'t0_s' in [channels] needs 'sample_rate_hz'", path=path,
                         hint="give sample_rate_hz = <Hz> with it, or remove t0_s")
    if table.sample_rate_hz is not None:
        cmap = cmap.with_sample_rate(table.sample_rate_hz, table.t0_s or 0.0, path=path)
    return cmap


@dataclass
class RawChannel:
    """A channel as a reader found it, before units and time bases are applied.

    Attributes
    ----------
    values : ndarray
        The values, any numeric array.
    unit : str or None
        The unit the file declares; None if none.
    time_s : ndarray or None
        The channel's own time stamps [s], if the format has them.
    fs_hz : float or None
        The channel's own sample rate [Hz], if the format has one.
    t0_s : float
        Start of that time base [s]. Default 0.
    """

    values: np.ndarray
    unit: str | None = None
    time_s: np.ndarray | None = None
    fs_hz: float | None = None
    t0_s: float = 0.0


def as_vector(values: object, *, path: object, channel: str) -> np.ndarray:
    """Values as a 1-D array; a row or column matrix (MATLAB's n-by-1) is flattened.

    Parameters
    ----------
    values : array_like
        The values.
    path : object
        The file, named in messages only.
    channel : str
        The channel, named in messages only.

    Returns
    -------
    ndarray
        1-D.

    Raises
    ------
    InputError
        The values are not a vector.
    """
    arr = np.asarray(values)
    if arr.ndim == 1:
        return arr
    if arr.ndim == 0 or sum(d > 1 for d in arr.shape) > 1:
        raise InputError(f"expected a 1-D signal, got shape {arr.shape}", path=path,
                         channel=channel, hint="map a vector (one value per sample)")
    return arr.reshape(-1)


def _unit_of(spec: ChannelSpec, raw: RawChannel) -> str | None:
    if spec.unit:
        return spec.unit
    if raw.unit is not None and str(raw.unit).strip():
        return str(raw.unit).strip()
    return None


def _converted(spec: ChannelSpec, raw: RawChannel, path: object,
               notes: list[str] | None = None) -> np.ndarray:
    unit = _unit_of(spec, raw)
    values = as_vector(raw.values, path=path, channel=spec.channel)
    if notes is not None and values.dtype.kind in "iu" and values.dtype.itemsize <= 2:
        notes.append(f"channel '{spec.channel}' is stored as {values.dtype} without a scale "
                     f"in the file: its integers are taken as values in "
                     f"{unit or CHANNEL_UNITS[spec.channel]}")
    try:
        return convert_units(values, unit, spec.quantity, radius_m=spec.radius_m, path=path,
                             channel=spec.channel)
    except InputError as exc:
        if spec.unit or unit is None:
            raise
        raise InputError(f"the file declares unit '{unit}' for '{spec.name}', which cannot "
                         f"be used ({exc})", path=path, channel=spec.channel,
                         hint="give the right unit in the manifest's [channels] table") from None


def _missing(spec: ChannelSpec, path: object, available: Callable[[], list[str]] | None
             ) -> InputError:
    what = f"no channel '{spec.name}' in the file"
    if spec.explicit:
        what += " (mapped in [channels])"
    return InputError(what + _available_text(available), path=path, channel=spec.channel,
                      hint="map it in the manifest's [channels] table (docs/format.md)")


def _available_text(available: Callable[[], list[str]] | None) -> str:
    if available is None:
        return ""
    names = [n.decode("utf-8", "replace") if isinstance(n, bytes) else str(n)
             for n in available()]
    shown = ", ".join(names[:12]) + (", ..." if len(names) > 12 else "")
    return f"; the file has {shown}" if names else "; the file has no channels"


def source_name(path: Path, group: str | None) -> str:
    """The ``Recording.source`` text.

    Parameters
    ----------
    path : pathlib.Path
        The file.
    group : str or None
        The group chosen inside it.

    Returns
    -------
    str
        The path, and ``:group`` when one was chosen.
    """
    return f"{path}" + (f":{group}" if group else "")


def library_error(exc: BaseException, *, path: object, what: str, hint: str) -> InputError:
    """An :class:`InputError` for an exception a third-party reader raised on a bad file.

    Readers catch ``Exception`` around the library call only (never around their own code)
    and ``raise library_error(...) from None``.

    Parameters
    ----------
    exc : BaseException
        The library's exception.
    path : object
        The file.
    what : str
        What failed, e.g. "cannot open as HDF5".
    hint : str
        What to do.

    Returns
    -------
    InputError
        The error to raise.
    """
    text = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else ""
    detail = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return InputError(f"{what} ({detail})", path=path, hint=hint)


def import_optional(module: str, *, what: str, extra: str, path: object):
    """Import an optional library a reader needs.

    Parameters
    ----------
    module : str
        The module's name.
    what : str
        The file kind, for the message.
    extra : str
        The extra that installs it (``pip install torquemod[extra]``).
    path : object
        The file, named in the message.

    Returns
    -------
    module
        The imported module.

    Raises
    ------
    InputError
        The library is not installed; the message names the extra.
    """
    try:
        return importlib.import_module(module)
    except ImportError:
        raise InputError(f"reading {what} files needs the optional package {module}",
                         path=path, hint=f"install torquemod[{extra}]") from None
