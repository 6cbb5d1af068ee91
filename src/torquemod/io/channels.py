"""Channel mapping and unit conversion shared by every recording reader.

The manifest's ``[channels]`` table says which channel of a file feeds which channel of the
method, in which unit, and where the time base comes from (docs/format.md)::

    [channels]
    torque = { name = "Torque", unit = "kN*m" }
    wheel_speed = { name = "Wheel/Speed", unit = "rpm" }
    platform_speed = "PlatformSpeed"          # name only: the method's unit (rad/s)
    time = { name = "t", unit = "ms" }        # or: sample_rate_hz = 1000.0

Everything here is a pure function of its arguments: :func:`resolve_channel_map` checks the raw
table once and returns a frozen :class:`ChannelMap`; :func:`convert_units` turns values in a
named unit into the method's SI unit; :func:`torquemod.io.timebase.assemble_recording` builds
a :class:`~torquemod.io.experiment.Recording` from whatever a format reader found in its file.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from torquemod.errors import InputError
from torquemod.io.checks import positive_number
from torquemod.io.experiment import CHANNEL_UNITS, CHANNELS

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

#: Accepted units per quantity: factor to the SI unit of the method (first entry of each).
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0, "h": 3600.0},
    "torque": {"N*m": 1.0, "kN*m": 1e3, "N*cm": 1e-2, "N*mm": 1e-3,
               "lbf*ft": 1.3558179483314004},
    "angular_speed": {"rad/s": 1.0, "rpm": 2.0 * math.pi / 60.0, "deg/s": math.pi / 180.0,
                      "rev/s": 2.0 * math.pi},
    "force": {"N": 1.0, "kN": 1e3, "daN": 10.0, "lbf": 4.4482216152605},
    "linear_speed": {"m/s": 1.0, "km/h": 1.0 / 3.6, "mm/s": 1e-3, "mph": 0.44704},
    "length": {"m": 1.0, "km": 1e3, "mm": 1e-3, "cm": 1e-2, "mi": 1609.344},
}
#: Linear (surface) speeds [-> m/s] accepted for the angular speed channels when the entry
#: gives the radius ``radius_m`` that turns them into an angular speed: omega = v / r.
LINEAR_SPEED_UNITS: dict[str, float] = UNITS["linear_speed"]

#: Other spellings of the units above (matched after removing spaces).
UNIT_ALIASES: dict[str, str] = {
    "sec": "s", "msec": "ms", "µs": "us", "μs": "us", "usec": "us",
    "Nm": "N*m", "N.m": "N*m", "N-m": "N*m", "N·m": "N*m", "N⋅m": "N*m",
    "kNm": "kN*m", "kN.m": "kN*m", "kN-m": "kN*m", "kN·m": "kN*m",
    "Ncm": "N*cm", "N.cm": "N*cm", "Nmm": "N*mm", "N.mm": "N*mm",
    "ft*lbf": "lbf*ft", "ftlbf": "lbf*ft", "lbfft": "lbf*ft", "ft-lbf": "lbf*ft",
    "lbf-ft": "lbf*ft",
    "rad/sec": "rad/s", "rad*s^-1": "rad/s", "1/min": "rpm", "r/min": "rpm", "rev/min": "rpm",
    "U/min": "rpm", "min^-1": "rpm", "°/s": "deg/s", "deg/sec": "deg/s", "rps": "rev/s",
    "r/s": "rev/s", "kph": "km/h", "kmh": "km/h", "km/hr": "km/h", "mps": "m/s",
}
_KNOWN_BY_LOWER: dict[str, tuple[str, str]] = {}
for _q, _table in (*UNITS.items(), ("linear_speed", LINEAR_SPEED_UNITS)):
    for _u in _table:
        _KNOWN_BY_LOWER[_u.lower()] = (_q, _u)
for _alias, _u in UNIT_ALIASES.items():
    _q = next(q for q, t in (*UNITS.items(), ("linear_speed", LINEAR_SPEED_UNITS)) if _u in t)
    _KNOWN_BY_LOWER.setdefault(_alias.lower(), (_q, _u))
del _q, _table, _u, _alias

_QUANTITY_WORDS = {"time": "a time", "torque": "a torque", "angular_speed": "an angular speed",
                   "force": "a force", "linear_speed": "a linear speed",
                   "length": "a length"}
_ENTRY_KEYS = ("name", "unit", "radius_m", "time")
_RATE_KEYS = ("sample_rate_hz", "t0_s")


def canonical_unit(unit: str) -> tuple[str, str] | None:
    """The quantity and canonical spelling of a unit string.

    Spaces are ignored; the exact spelling is tried first, then the spelling in lower case
    (no two accepted units differ by case only).

    Parameters
    ----------
    unit : str
        The unit as written, e.g. "kNm".

    Returns
    -------
    tuple of str or None
        ``(quantity, canonical unit)``, or None when the unit is not known.

    Examples
    --------
    >>> canonical_unit("kNm")
    ('torque', 'kN*m')
    >>> canonical_unit("furlong") is None
    True
    """
    text = "".join(str(unit).split())
    for table_q, table in UNITS.items():
        if text in table:
            return table_q, text
    if text in LINEAR_SPEED_UNITS:
        return "linear_speed", text
    if text in UNIT_ALIASES:
        return canonical_unit(UNIT_ALIASES[text])
    return _KNOWN_BY_LOWER.get(text.lower())


def accepted_units(quantity: str) -> list[str]:
    """Canonical units accepted for a quantity, the SI unit first.

    Parameters
    ----------
    quantity : str
        One of ``time``, ``torque``, ``angular_speed``, ``force``, ``linear_speed``,
        ``length``.

    Returns
    -------
    list of str
        The units.

    Examples
    --------
    >>> accepted_units("force")[0]
    'N'
    """
    units = list(UNITS[quantity])
    if quantity == "angular_speed":
        units += [f"{u} (with radius_m)" for u in LINEAR_SPEED_UNITS]
    return units


def unit_factor(unit: str, quantity: str, *, radius_m: float | None = None,
                path: object | None = None, channel: str | None = None) -> float:
    """Factor that turns values in a unit into the SI unit of a quantity.

    Parameters
    ----------
    unit : str
        The unit.
    quantity : str
        One of ``time``, ``torque``, ``angular_speed``, ``force``, ``linear_speed``,
        ``length``.
    radius_m : float or None
        Radius r [m]: with it a linear speed (m/s, km/h, mm/s) is accepted for
        ``angular_speed`` (the angular speed is v/r). Default None.
    path : object
        The file, named in messages only.
    channel : str or None
        The channel, named in messages only.

    Returns
    -------
    float
        The factor: SI value = factor * value.

    Raises
    ------
    InputError
        The unit is unknown, or measures another quantity (a linear speed without
        ``radius_m``); the message names the unit and lists the accepted ones.
    ValueError
        ``quantity`` is unknown (a programming error).

    Examples
    --------
    >>> unit_factor("kN", "force")
    1000.0
    >>> unit_factor("km/h", "angular_speed", radius_m=0.5) * 3.6
    2.0
    """
    if quantity not in UNITS:
        raise ValueError(f"unknown quantity {quantity!r}; use one of {', '.join(UNITS)}")
    found = canonical_unit(unit)
    accepted = ", ".join(accepted_units(quantity))
    if found is None:
        raise InputError(f"unknown unit '{unit}' for {_QUANTITY_WORDS[quantity]}", path=path,
                         channel=channel, hint=f"use one of {accepted}")
    unit_q, canon = found
    if unit_q == quantity:
        return UNITS[quantity][canon]
    if unit_q == "linear_speed" and quantity == "angular_speed":
        if radius_m is None:
            raise InputError(f"unit '{unit}' is a linear speed, the channel needs an angular "
                             "speed", path=path, channel=channel,
                             hint="add radius_m = <wheel or platform path radius> to the "
                                  f"channel's entry, or use one of {accepted}")
        return LINEAR_SPEED_UNITS[canon] / radius_m
    raise InputError(f"unit '{unit}' is {_QUANTITY_WORDS[unit_q]}, the channel needs "
                     f"{_QUANTITY_WORDS[quantity]}", path=path, channel=channel,
                     hint=f"map the right channel or use one of {accepted}")


def convert_units(values: object, unit: str | None, quantity: str, *,
                  radius_m: float | None = None, path: object | None = None,
                  channel: str | None = None) -> np.ndarray:
    """Values in a unit as a float64 array in the SI unit of a quantity.

    The input itself is returned when it is float64 in the SI unit already; it is never
    modified. Times given as ``datetime64``/``timedelta64`` become seconds since the first
    sample.

    Parameters
    ----------
    values : array_like
        The values.
    unit : str or None
        Their unit; None or empty: the SI unit already.
    quantity : str
        The quantity (:func:`unit_factor`).
    radius_m : float or None
        Radius [m] turning a linear speed into an angular one. Default None.
    path : object
        The file, named in messages only.
    channel : str or None
        The channel, named in messages only.

    Returns
    -------
    ndarray
        float64 values in the SI unit.

    Raises
    ------
    InputError
        Non-numeric values, a NaT time stamp, or a unit :func:`unit_factor` refuses.

    Examples
    --------
    >>> convert_units([60.0], "rpm", "angular_speed").round(4).tolist()
    [6.2832]
    """
    arr = np.asarray(values)
    if quantity == "time" and arr.dtype.kind in "mM":
        if arr.size == 0:
            return np.zeros(0)
        if arr.dtype.kind == "M" and np.isnat(arr).any():
            raise InputError("time stamp is not a time (NaT)", path=path, channel=channel)
        delta = (arr - arr.reshape(-1)[0]).astype("timedelta64[ns]")
        return delta.astype(np.int64).astype(np.float64) * 1e-9
    if arr.dtype.kind not in "biuf":
        raise InputError(f"values are not numeric (type {arr.dtype})", path=path,
                         channel=channel, hint="map a numeric channel")
    # no copy when the values are float64 in the SI unit already (a reader's fresh array,
    # so a recording never exists twice in memory); a scaled result is a new array
    out = arr.astype(np.float64, copy=False)
    if unit is None or not str(unit).strip():
        return out
    factor = unit_factor(unit, quantity, radius_m=radius_m, path=path, channel=channel)
    return out * factor if factor != 1.0 else out


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


def _entry(channel: str, key: str, value: object, path: object) -> ChannelSpec:
    if isinstance(value, str):
        value = {"name": value}
    if not isinstance(value, Mapping):
        raise InputError(f"[channels] '{key}' must be a channel name or a table like "
                         "{ name = \"Torque\", unit = \"N*m\" }", path=path, channel=channel)
    unknown = [k for k in value if k not in _ENTRY_KEYS]
    if unknown:
        raise InputError(f"[channels] '{key}' has unknown key(s) {', '.join(unknown)}",
                         path=path, channel=channel, hint=f"use {', '.join(_ENTRY_KEYS)}")
    name = value.get("name", channel)
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"[channels] '{key}': 'name' must be a non-empty string", path=path,
                         channel=channel)
    unit = value.get("unit")
    if unit is not None and not isinstance(unit, str):
        raise InputError(f"[channels] '{key}': 'unit' must be a string", path=path,
                         channel=channel)
    radius = value.get("radius_m")
    if radius is not None:
        if QUANTITY[channel] != "angular_speed":
            raise InputError(f"[channels] '{key}': radius_m only applies to the speed channels",
                             path=path, channel=channel)
        radius = _positive(radius, f"{key}.radius_m", path)
    if unit:
        # check now, so a mistake shows when the manifest is read, not file by file
        unit_factor(unit, QUANTITY[channel], radius_m=radius, path=path, channel=channel)
    time_name, time_unit = _own_time_entry(channel, key, value.get("time"), path)
    return ChannelSpec(channel, name.strip(), unit.strip() if unit else None, radius, True,
                       time_name, time_unit)


def _own_time_entry(channel: str, key: str, value: object, path: object
                    ) -> tuple[str | None, str | None]:
    """``(name, unit)`` of an entry's ``time`` key: the channel's own time vector."""
    if value is None:
        return None, None
    if channel == TIME:
        raise InputError(f"[channels] '{key}': 'time' only applies to the method channels",
                         path=path, channel=channel)
    if isinstance(value, str):
        value = {"name": value}
    if not isinstance(value, Mapping) or any(k not in ("name", "unit") for k in value):
        raise InputError(f"[channels] '{key}': 'time' must be the name of the channel's own "
                         "time vector or a table like { name = \"t_fx\", unit = \"ms\" }",
                         path=path, channel=channel)
    name, unit = value.get("name"), value.get("unit")
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"[channels] '{key}': the time vector's 'name' must be a non-empty "
                         "string", path=path, channel=channel)
    if unit is not None:
        if not isinstance(unit, str):
            raise InputError(f"[channels] '{key}': the time vector's 'unit' must be a string",
                             path=path, channel=channel)
        unit_factor(unit, "time", path=path, channel=channel)
    return name.strip(), unit.strip() if unit else None


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
        Not a table, an unknown key, a channel mapped twice, a file channel mapped to two
        channels, a bad unit, or a bad ``t0_s`` (or one without ``sample_rate_hz``).
    """
    if isinstance(raw, ChannelMap):
        return raw
    if raw is None:
        raw = {}
    if not isinstance(raw, Mapping):
        raise InputError("[channels] must be a table", path=path)
    specs = dict(default_channel_map().specs)
    given: dict[str, str] = {}
    for key, value in raw.items():
        if key in _RATE_KEYS:
            continue
        channel = SHORT_NAMES.get(key, key)
        if channel not in QUANTITY:
            keys = ", ".join([*SHORT_NAMES, *_RATE_KEYS])
            raise InputError(f"unknown key '{key}' in [channels]", path=path,
                             hint=f"use {keys} (or the full names like torque_nm)")
        if channel in given:
            raise InputError(f"[channels] maps '{channel}' twice ('{given[channel]}' and "
                             f"'{key}')", path=path, channel=channel, hint="keep one")
        given[channel] = key
        specs[channel] = _entry(channel, key, value, path)
    by_name: dict[str, str] = {}
    for channel in CHANNELS:
        name = specs[channel].name
        if name in by_name:
            raise InputError(f"file channel '{name}' is mapped to both {by_name[name]} and "
                             f"{channel}", path=path, channel=channel,
                             hint="each method channel needs its own file channel")
        by_name[name] = channel
    cmap = ChannelMap(specs, raw=dict(raw))
    if "t0_s" in raw:
        t0 = raw["t0_s"]
        if isinstance(t0, bool) or not isinstance(t0, int | float) or not math.isfinite(t0):
            raise InputError(f"'t0_s' must be a finite number, got {t0!r}", path=path)
        if "sample_rate_hz" not in raw:
            raise InputError("'t0_s' in [channels] needs 'sample_rate_hz'", path=path)
    if "sample_rate_hz" in raw:
        cmap = cmap.with_sample_rate(raw["sample_rate_hz"], float(raw.get("t0_s", 0.0)),
                                     path=path)
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
