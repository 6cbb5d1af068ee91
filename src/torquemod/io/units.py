"""Units of the recorded quantities and their conversion to the method's SI units.

A manifest's ``[channels]`` table (:mod:`torquemod.io.channels`) may give each channel in
the unit the logger wrote (``kN*m``, ``rpm``, ``km/h``, ``ms``, ...): :func:`unit_factor`
says by how much such a value is multiplied to be in the SI unit of its quantity, and
:func:`convert_units` converts an array. Pure functions of their arguments.
"""

from __future__ import annotations

import math

import numpy as np

from torquemod.errors import InputError

__all__ = ["LINEAR_SPEED_UNITS", "UNITS", "UNIT_ALIASES", "accepted_units", "canonical_unit",
           "convert_units", "unit_factor"]

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
