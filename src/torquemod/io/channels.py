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
named unit into the method's SI unit; :func:`assemble_recording` builds a
:class:`~torquemod.data.Recording` from whatever a format reader found in its file.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..data import CHANNELS, OPTIONAL_CHANNELS, Recording
from ..errors import InputError
from .validate import sample_rate_from_time

TIME = "time_s"

#: Short manifest keys of the method's channels (the full names are accepted too).
SHORT_NAMES: dict[str, str] = {
    "time": TIME,
    "torque": "torque_nm",
    "wheel_speed": "wheel_speed_rad_s",
    "platform_speed": "platform_speed_rad_s",
    "fx": "fx_n",
    "fy": "fy_n",
    "fz": "fz_n",
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
}

#: Accepted units per quantity: factor to the SI unit of the method (first entry of each).
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0, "h": 3600.0},
    "torque": {"N*m": 1.0, "kN*m": 1e3, "N*cm": 1e-2, "N*mm": 1e-3,
               "lbf*ft": 1.3558179483314004},
    "angular_speed": {"rad/s": 1.0, "rpm": 2.0 * math.pi / 60.0, "deg/s": math.pi / 180.0,
                      "rev/s": 2.0 * math.pi},
    "force": {"N": 1.0, "kN": 1e3, "daN": 10.0, "lbf": 4.4482216152605},
}
#: Linear (surface) speeds [-> m/s] accepted for the speed channels when the entry gives the
#: radius ``radius_m`` that turns them into an angular speed: omega = v / r.
LINEAR_SPEED_UNITS: dict[str, float] = {"m/s": 1.0, "km/h": 1.0 / 3.6, "mm/s": 1e-3}

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
                   "force": "a force", "linear_speed": "a linear speed"}
_ENTRY_KEYS = ("name", "unit", "radius_m")
_RATE_KEYS = ("sample_rate_hz", "t0_s")


def canonical_unit(unit: str) -> tuple[str, str] | None:
    """``(quantity, canonical unit)`` of a unit string, or None when it is not known.

    Spaces are ignored; the exact spelling is tried first, then the spelling in lower case
    (no two accepted units differ by case only). ``canonical_unit("kNm") == ("torque", "kN*m")``.
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
    """Canonical units accepted for ``quantity``, the SI unit first."""
    units = list(UNITS[quantity])
    if quantity == "angular_speed":
        units += [f"{u} (with radius_m)" for u in LINEAR_SPEED_UNITS]
    return units


def unit_factor(unit: str, quantity: str, *, radius_m: float | None = None,
                path: object | None = None, channel: str | None = None) -> float:
    """Factor that turns values in ``unit`` into the SI unit of ``quantity``.

    ``quantity`` is one of ``time``, ``torque``, ``angular_speed``, ``force``. A linear speed
    (m/s, km/h, mm/s) is accepted for ``angular_speed`` when ``radius_m`` [m] is given (the
    angular speed is v / r). Raises :class:`InputError` naming the unit and listing the
    accepted ones when the unit is unknown or measures another quantity.
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
    """``values`` given in ``unit`` as a float64 array in the SI unit of ``quantity`` (the
    input itself when it is float64 in the SI unit already).

    ``unit`` None or empty means the values are in the SI unit already. Times given as
    ``datetime64``/``timedelta64`` become seconds since the first sample. The input is never
    modified. ``convert_units([60.0], "rpm", "angular_speed")`` is ``[6.2831...]`` [rad/s].
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
    """Where one method channel is found: ``name`` in the file, in ``unit`` (None: the unit
    the file declares, else the method's SI unit), ``radius_m`` [m] for linear speeds."""

    channel: str
    name: str
    unit: str | None = None
    radius_m: float | None = None
    explicit: bool = False  # named in the manifest (not the default)

    @property
    def quantity(self) -> str:
        return QUANTITY[self.channel]


@dataclass(frozen=True)
class ChannelMap:
    """A checked ``[channels]`` table: one :class:`ChannelSpec` per method channel and time.

    ``sample_rate_hz`` [Hz] (with ``t0_s`` [s]) replaces any time column or time base of
    the file when given.
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
        return replace(self, sample_rate_hz=fs, t0_s=self.t0_s if t0_s is None else t0_s)


def default_channel_map() -> ChannelMap:
    """The map used without a ``[channels]`` table: the CSV names, SI units, ``time_s``."""
    return ChannelMap({c: ChannelSpec(c, c) for c in (TIME, *CHANNELS)})


def _positive(value: object, key: str, path: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(value) or value <= 0:
        raise InputError(f"'{key}' must be a positive number, got {value!r}", path=path,
                         hint="give the value in SI units, e.g. sample_rate_hz = 1000.0")
    return float(value)


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
    return ChannelSpec(channel, name.strip(), unit.strip() if unit else None, radius, True)


def resolve_channel_map(raw: Mapping | ChannelMap | None, path: object = None) -> ChannelMap:
    """Check a manifest ``[channels]`` table and return the :class:`ChannelMap`.

    Keys are the method channels, short (``torque``, ``wheel_speed``, ``platform_speed``,
    ``fx``, ``fy``, ``fz``, ``time``) or full (``torque_nm``, ..., ``time_s``), each a file
    channel name or a table ``{ name, unit, radius_m }``; plus ``sample_rate_hz`` [Hz] and
    ``t0_s`` [s]. Channels left out keep their default (the CSV name, SI unit). ``path`` is
    only used in messages. An empty or None table gives :func:`default_channel_map`.
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
    """A channel as a reader found it: ``values`` (any numeric array), the ``unit`` the file
    declares (None if none), and the channel's own time base if the format has one: time
    stamps ``time_s`` [s] or a sample rate ``fs_hz`` [Hz] with start ``t0_s`` [s]."""

    values: np.ndarray
    unit: str | None = None
    time_s: np.ndarray | None = None
    fs_hz: float | None = None
    t0_s: float = 0.0


def as_vector(values: object, *, path: object, channel: str) -> np.ndarray:
    """``values`` as a 1-D array; a row or column matrix (MATLAB's n-by-1) is flattened."""
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


def _converted(spec: ChannelSpec, raw: RawChannel, path: object) -> np.ndarray:
    unit = _unit_of(spec, raw)
    values = as_vector(raw.values, path=path, channel=spec.channel)
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
    have = ""
    if available is not None:
        names = [n.decode("utf-8", "replace") if isinstance(n, bytes) else str(n)
                 for n in available()]
        shown = ", ".join(names[:12]) + (", ..." if len(names) > 12 else "")
        have = f"; the file has {shown}" if names else "; the file has no channels"
    return InputError(what + have, path=path, channel=spec.channel,
                      hint="map it in the manifest's [channels] table (docs/format.md)")


def _time_base(cmap: ChannelMap, lookup: Callable[[str], RawChannel | None],
               found: dict[str, RawChannel], native_rate: tuple[float, float] | None,
               path: object) -> tuple[float, float, np.ndarray | None]:
    """``(fs_hz, t0_s, time_s or None)`` by precedence: the map's sample rate, the time
    channel, the channels' own time base, the file's sample rate."""
    if cmap.sample_rate_hz is not None:
        return cmap.sample_rate_hz, cmap.t0_s, None
    spec = cmap.time
    raw = lookup(spec.name)
    if raw is None and spec.explicit:
        raise _missing(spec, path, None)
    if raw is not None:
        t = _converted(spec, raw, path)
        fs, t0 = sample_rate_from_time(t, path=path)
        return fs, t0, t
    first = found[CHANNELS[0]]
    if first.time_s is not None:
        t = np.asarray(first.time_s, dtype=np.float64).reshape(-1)
        fs, t0 = sample_rate_from_time(t, path=path)
        return fs, t0, t
    if first.fs_hz is not None:
        return first.fs_hz, first.t0_s, None
    if native_rate is not None:
        return native_rate[0], native_rate[1], None
    raise InputError(f"no time base: no time channel '{spec.name}' and no sample rate in the "
                     "file", path=path, channel=TIME,
                     hint="map 'time' or set sample_rate_hz in [channels] or in the "
                          "[[recording]] (docs/format.md)")


def _own_times(raw: RawChannel, n: int) -> np.ndarray | None:
    """A channel's own sample times [s] (stamps, or a rate and start), None if it has none."""
    if raw.time_s is not None:
        return np.asarray(raw.time_s, dtype=np.float64).reshape(-1)
    if raw.fs_hz is not None:
        return raw.t0_s + np.arange(n) / raw.fs_hz
    return None


def _common_time_base(found: dict[str, RawChannel], channels: dict[str, np.ndarray],
                      path: object) -> tuple[dict[str, np.ndarray], RawChannel, list[str]]:
    """Put every channel on the torque channel's sample times (logger realities, issue 8).

    A channel on its own time base (a TDMS ``wf_start_offset``, an MDF channel group with its
    own master channel or rate) is interpolated linearly onto the torque's times; for the
    chain's signals (< 30 Hz) sampled at >= 10 kHz that errs by < (2*pi*f/fs)^2/8 = 2e-4 of
    the amplitude, less after the chain's resampling. All channels are cut to the span they
    share; a channel that covers less than 90 % of the torque's span is refused. Returns the
    channels, the torque's (trimmed) raw time base and notes for provenance."""
    first_name = CHANNELS[0]
    first = found[first_name]
    n = channels[first_name].size
    ref = _own_times(first, n)
    notes: list[str] = []
    if n < 2:  # refused later ("fewer than two samples")
        return channels, first, notes
    if ref is None:
        for name, raw in found.items():
            if _own_times(raw, channels[name].size) is not None:
                raise InputError(f"has its own time base but {first_name} has none",
                                 path=path, channel=name,
                                 hint="map a common 'time' channel in [channels]")
        return channels, first, notes
    span = ref[-1] - ref[0]
    lo, hi = ref[0], ref[-1]
    timed: dict[str, np.ndarray] = {}
    for name, raw in found.items():
        if name == first_name:
            continue
        t = _own_times(raw, channels[name].size)
        if t is None:
            if channels[name].size != n:
                raise InputError(f"has {channels[name].size} samples, {first_name} has {n}",
                                 path=path, channel=name,
                                 hint="all channels must be sampled together")
            continue
        if t.size != channels[name].size:
            raise InputError(f"has {channels[name].size} samples but {t.size} time stamps",
                             path=path, channel=name)
        if t.shape == ref.shape and np.max(np.abs(t - ref)) <= 1e-3 * span / max(n - 1, 1):
            continue  # the same samples (within a thousandth of a period)
        if t.size < 2 or np.any(np.diff(t) <= 0):
            raise InputError("time stamps are not strictly increasing", path=path,
                             channel=name)
        timed[name] = t
        lo, hi = max(lo, t[0]), min(hi, t[-1])
    if not timed:
        return channels, first, notes
    if hi - lo < 0.9 * span:
        worst = min(timed, key=lambda k: min(timed[k][-1], ref[-1]) - max(timed[k][0], ref[0]))
        t = timed[worst]
        raise InputError(f"covers {t[0] - ref[0]:+.4f} s to {t[-1] - ref[0]:+.4f} s of "
                         f"{first_name}'s {span:.4f} s (less than 90 % of it)", path=path,
                         channel=worst, hint="export the channels over a common time span")
    keep = (ref >= lo - 1e-12) & (ref <= hi + 1e-12)
    out = {k: (v[keep] if k not in timed else v) for k, v in channels.items()}
    for name, t in timed.items():
        offset = t[0] - ref[0]
        rate = (t.size - 1) / (t[-1] - t[0])
        out[name] = np.interp(ref[keep], t, channels[name])
        notes.append(f"channel '{name}' on its own time base (start {offset * 1e3:+.3f} ms "
                     f"from {first_name}, {rate:.6g} Hz): interpolated linearly onto "
                     f"{first_name}'s sample times")
    if not keep.all():
        notes.append(f"cut to the span all channels share: {int((~keep).sum())} of {n} samples "
                     f"of {first_name} dropped")
    kept = ref[keep]
    trimmed = replace(first, time_s=kept if first.time_s is not None else None,
                      t0_s=float(kept[0]) if first.time_s is None else first.t0_s)
    return out, trimmed, notes


def assemble_recording(cmap: ChannelMap, lookup: Callable[[str], RawChannel | None], *,
                       path: object, source: str,
                       native_rate: tuple[float, float] | None = None,
                       available: Callable[[], list[str]] | None = None) -> Recording:
    """Build a :class:`Recording` from a reader's ``lookup(name) -> RawChannel | None``.

    Every method channel is looked up by its mapped name and converted to SI; the time base
    comes from (in order) the map's ``sample_rate_hz``, the time channel (``time_s`` unless
    mapped), the channels' own time base (``RawChannel.time_s``/``fs_hz``), then
    ``native_rate = (fs_hz, t0_s)`` of the file. ``available()`` lists the file's channel
    names for the message when a channel is missing.
    """
    found: dict[str, RawChannel] = {}
    for channel in CHANNELS:
        spec = cmap.spec(channel)
        raw = lookup(spec.name)
        if raw is None:
            if channel in OPTIONAL_CHANNELS and not spec.explicit:
                continue  # an optional channel the file does not hold
            raise _missing(spec, path, available)
        found[channel] = raw
    forces = [c for c in ("fx_n", "fz_n") if c in found]
    if len(forces) == 1 or ("fy_n" in found and not forces):
        lacking = "fz_n" if "fx_n" in found else "fx_n"
        raise _missing(cmap.spec(lacking), path, available) from None
    channels = {c: _converted(cmap.spec(c), raw, path) for c, raw in found.items()}
    notes: list[str] = []
    if cmap.sample_rate_hz is None:
        channels, found[CHANNELS[0]], notes = _common_time_base(found, channels, path)
    fs, t0, t = _time_base(cmap, lookup, found, native_rate, path)
    n = channels[CHANNELS[0]].size
    if t is not None and t.size != n:
        raise InputError(f"has {t.size} samples, the channels have {n}", path=path,
                         channel=TIME)
    if n < 2:
        raise InputError(f"fewer than two samples ({n})", path=path, channel=CHANNELS[0])
    if not math.isfinite(fs) or fs <= 0:
        raise InputError(f"sample rate {fs} Hz is not a positive number", path=path,
                         channel=TIME)
    if not math.isfinite(t0):
        raise InputError(f"start time {t0} s is not finite", path=path, channel=TIME)
    if "fx_n" in channels and "fy_n" not in channels:
        notes.append("no lateral force channel: CoA = |Fx|/Fz")
    return Recording(channels, float(fs), float(t0), source, notes)


def unit_table() -> list[tuple[str, str, float]]:
    """``(quantity, unit, factor to SI)`` for every accepted unit, for docs and messages."""
    rows = [(q, u, f) for q, table in UNITS.items() for u, f in table.items()]
    rows += [("linear_speed", u, f) for u, f in LINEAR_SPEED_UNITS.items()]
    return rows


def source_name(path: Path, group: str | None) -> str:
    """The ``Recording.source`` text: the path, and ``:group`` when one was chosen."""
    return f"{path}" + (f":{group}" if group else "")


def library_error(exc: BaseException, *, path: object, what: str, hint: str) -> InputError:
    """An :class:`InputError` for an exception a third-party reader raised on a bad file.

    Readers catch ``Exception`` around the library call only (never around their own code)
    and ``raise library_error(...) from None``.
    """
    text = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else ""
    detail = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return InputError(f"{what} ({detail})", path=path, hint=hint)


def import_optional(module: str, *, what: str, extra: str, path: object):
    """Import the optional library ``module`` a reader needs, or raise :class:`InputError`
    naming the extra that installs it (``pip install torquemod[extra]``)."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise InputError(f"reading {what} files needs the optional package {module}",
                         path=path, hint=f"install torquemod[{extra}]") from None
