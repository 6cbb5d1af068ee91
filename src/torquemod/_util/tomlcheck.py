"""One way to read a TOML table into a typed, frozen dataclass.

Every configuration a user writes by hand (the rig twin's config, the train twin's config,
run.toml's ``[onboard]``, sweep files and their bases) is read through :func:`read_table`:
the fields of the dataclass say which keys exist and of which type, a :class:`Check` per field
says which values make sense. Any mistake is one :class:`~torquemod.errors.InputError` that
names the file and the dotted key, what was found and what is expected:

* a key the dataclass does not have (with the nearest known key, :func:`unknown_keys`),
* a value of the wrong type (a string or ``true`` where a number belongs, a fraction where a
  whole number belongs; TOML's ``nan`` and ``inf`` are not numbers here),
* a value outside its range (sign, bounds, the allowed names),
* a frequency at or above the Nyquist frequency of a sample rate (:func:`below_nyquist`).

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Tyre:
...     radius_m: float = 0.46
...     teeth: int = 60
>>> read_table(Tyre, {"radius_m": 0.5}, section="wheel", path="car.toml")
Tyre(radius_m=0.5, teeth=60)
>>> try:
...     read_table(Tyre, {"radius": 0.5}, section="wheel", path="car.toml")
... except InputError as exc:
...     print(str(exc).split(";")[0] + "; " + exc.hint.split("?")[0] + "?")
car.toml: unknown key 'wheel.radius'; did you mean 'radius_m'?
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import types
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from torquemod.errors import InputError

__all__ = ["NON_NEGATIVE", "POSITIVE", "Check", "below_nyquist", "between", "checked_value",
           "default_checks", "one_of", "read_table", "unknown_keys"]


@dataclass(frozen=True)
class Check:
    """What a value must satisfy beyond its type: ``lo <= v <= hi`` (``lo_open``/``hi_open``
    make a bound strict; None: unbounded) or one of ``choices``; for a list, each item."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple = ()
    #: a list must have exactly this many items (None: any number, at least one)
    length: int | None = None

    def ok(self, v: object) -> bool:
        if self.choices:
            return v in self.choices
        if self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo):
            return False
        return not (self.hi is not None and (v >= self.hi if self.hi_open else v > self.hi))

    def text(self) -> str:
        """What the check asks for, as the error says it."""
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.lo == 0 and self.hi is None:
            return "> 0" if self.lo_open else ">= 0"
        if self.hi is None:
            return f"{'>' if self.lo_open else '>='} {self.lo:g}"
        if self.lo is None:
            return f"{'<' if self.hi_open else '<='} {self.hi:g}"
        return (f"in {'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}"
                f"{')' if self.hi_open else ']'}")


#: a finite number > 0
POSITIVE = Check(lo=0.0, lo_open=True)
#: a finite number >= 0
NON_NEGATIVE = Check(lo=0.0)


def between(lo: float | None, hi: float | None, *, lo_open: bool = False,
            hi_open: bool = False) -> Check:
    """``lo <= v <= hi`` (strict where asked)."""
    return Check(lo=lo, hi=hi, lo_open=lo_open, hi_open=hi_open)


def one_of(*choices) -> Check:
    """``v`` is one of ``choices``."""
    return Check(choices=tuple(choices))


def default_checks(cls, given: Mapping[str, Check | None], default: Check | None = POSITIVE
                   ) -> dict[str, Check | None]:
    """A check per field of the dataclass ``cls``: ``given[name]`` where listed (None: any
    value of the type), ``default`` (positive) for every other field."""
    return {f.name: given.get(f.name, default) for f in dataclasses.fields(cls)}


def unknown_keys(table: Mapping, allowed: Iterable, where: str, path: object, *,
                 takes: str = "known keys:", error: type[InputError] = InputError,
                 prefix: str = "") -> None:
    """Raise ``error`` naming the first key of ``table`` not in ``allowed`` (a typo such as
    'modulation_frequncy_hz' must not pass unnoticed), with the nearest allowed key;
    ``where`` ("" for none) and the key's ``prefix`` (its section, ``"test."``) name it."""
    allowed = tuple(allowed)
    for key in table:
        if key not in allowed:
            near = difflib.get_close_matches(str(key), allowed, n=1)
            text = f"unknown key '{prefix}{key}'"
            raise error(f"{where}: {text}" if where else text, path=path, hint=(
                f"did you mean '{near[0]}'? " if near else "") + f"{takes} "
                + ", ".join(allowed))


def _is_number(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _kind(tp) -> tuple[type, int | None] | type:
    """``float``, ``int``, ``bool``, ``str`` or ``(tuple, item type, length or None)`` of an
    annotation (``X | None`` is ``X``: TOML has no null)."""
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return _kind(args[0])
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return (tuple, args[0], None)
        return (tuple, args[0] if args else float, len(args) or None)
    return tp


def checked_value(value: object, kind, key: str, path: object, check: Check | None = None, *,
                  error: type[InputError] = InputError):
    """``value`` converted to ``kind`` (float, int, bool, str, or ``(tuple, item, n)``) and
    checked by ``check``; else ``error`` naming ``key`` [e.g. 'vehicle.mass_share_kg'], the
    value and ``path``."""
    def bad(need: str) -> InputError:
        return error(f"'{key}' must be {need}, got {value!r}", path=path)
    if isinstance(kind, tuple):
        _, item, length = kind
        if not isinstance(value, list | tuple) or not value or (
                length is not None and len(value) != length):
            many = f"a list of {length}" if length else "a non-empty list of"
            raise bad(f"{many} {_name(item)}s")
        return tuple(checked_value(v, item, f"{key}[{i}]", path, check, error=error)
                     for i, v in enumerate(value))
    if kind is bool:
        if not isinstance(value, bool):
            raise bad("true or false")
        out = value
    elif kind is int:
        if not _is_number(value) or not isinstance(value, int):
            raise bad("a whole number")
        out = value
    elif kind is float:
        if not _is_number(value) or not math.isfinite(value):
            raise bad("a finite number")
        out = float(value)
    elif kind is str:
        if not isinstance(value, str):
            raise bad("a text in quotes")
        out = value
    else:
        out = value
    if check is not None and not check.ok(out):
        need = check.text()
        raise bad(need if check.choices else f"a number {need}")
    return out


def _name(kind) -> str:
    return {float: "number", int: "whole number", bool: "true/false", str: "text"}.get(
        kind, getattr(kind, "__name__", str(kind)))


def read_table(cls, table: object, *, section: str, path: object,
               checks: Mapping[str, Check] | None = None, skip: Iterable[str] = (),
               given: Mapping | None = None, error: type[InputError] = InputError):
    """An instance of the frozen dataclass ``cls`` from the TOML ``table`` ``[section]`` of
    the file ``path``: unknown keys refused (with the nearest known one), every value
    converted to its field's type and checked by ``checks[field]`` (or the field's
    ``metadata["check"]``); keys in ``skip`` may be in the table but are not read (sub-tables
    the caller reads itself) and ``given`` supplies fields the caller built (not keys of
    the table). Missing keys keep
    their defaults."""
    if table is None:
        table = {}
    if not isinstance(table, Mapping):
        raise error(f"[{section}] must be a table, got {table!r}", path=path)
    skip, given = tuple(skip), dict(given or {})
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown_keys(table, [*(n for n in fields if n not in given and n != "raw"), *skip],
                 "", path, error=error, prefix=f"{section}.", takes=f"[{section}] takes")
    hints = typing.get_type_hints(cls)
    checks = dict(checks or {})
    kwargs = dict(given)
    for key, value in table.items():
        if key in skip:
            continue
        f = fields[key]
        check = checks.get(key, f.metadata.get("check"))
        kwargs[key] = checked_value(value, _kind(hints[key]), f"{section}.{key}", path, check,
                                    error=error)
    return cls(**kwargs)


def below_nyquist(frequency_hz: float, sample_rate_hz: float, key: str, rate_key: str,
                  path: object, *, error: type[InputError] = InputError) -> None:
    """Refuse a frequency at or above half the sample rate (it cannot be recorded: it folds
    to another frequency, Shannon's sampling theorem), naming both keys."""
    if not frequency_hz < sample_rate_hz / 2:
        raise error(f"'{key}' = {frequency_hz:g} Hz is at or above the Nyquist frequency "
                    f"({sample_rate_hz / 2:g} Hz) of '{rate_key}' = {sample_rate_hz:g} Hz",
                    path=path, hint=f"lower {key} or raise {rate_key}")
