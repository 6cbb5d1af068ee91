"""One way to read a TOML table into a typed, frozen dataclass.

Every configuration a user writes by hand (the ``[processing]`` table, experiment.toml and
run.toml with their ``[channels]`` maps, the rig and train twins' configs, run.toml's
``[onboard]``, sweep files and their bases) is read through :func:`read_table`: the fields
of the dataclass say which keys exist and of which type (a dataclass-typed field is a
sub-table, a tuple of dataclasses a list of tables), the :class:`Check` in each field's
metadata (:func:`checked`) says which values make sense, once for the file and for values
built in code (:func:`check_fields`). Any mistake is one
:class:`~torquemod.errors.InputError` that names the file and the dotted key, what was found
and what is expected:

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
import functools
import inspect
import math
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

from torquemod.errors import InputError

__all__ = ["NON_NEGATIVE", "POSITIVE", "Check", "below_nyquist", "between", "check_fields",
           "check_key", "checked", "checked_value", "default_checks", "defaults_from", "one_of",
           "prefixed", "read_table", "unknown_keys"]


@dataclass(frozen=True)
class Check:
    """What a value must satisfy beyond its type: ``lo <= v <= hi`` (``lo_open``/``hi_open``
    make a bound strict; None: unbounded) or one of ``choices``; for a list, each item.
    ``test`` is a last condition on the whole value (a list: the whole list), said as
    ``need`` when it fails (without a test, ``need`` replaces the text of the range);
    ``hint`` says what to do."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple = ()
    #: a list must have exactly this many items (None: any number, at least one)
    length: int | None = None
    #: a list may be empty
    allow_empty: bool = False
    test: Callable[[object], bool] | None = None
    need: str = ""
    hint: str | None = None

    def ok(self, v: object) -> bool:
        """Whether the item ``v`` is in range (or one of the choices); ``test`` aside."""
        if self.choices:
            return v in self.choices
        try:
            if self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo):
                return False
            return not (self.hi is not None and (v >= self.hi if self.hi_open else v > self.hi))
        except TypeError:  # a value of another type built in code
            return False

    def text(self) -> str:
        """What the check asks for, as the error says it."""
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.need and self.test is None:
            return self.need
        if self.lo is None and self.hi is None:
            return self.need or "a valid value"
        if self.lo == 0 and self.hi is None:
            return "a positive number (> 0)" if self.lo_open else "a number >= 0"
        if self.hi is None:
            return f"a number {'>' if self.lo_open else '>='} {self.lo:g}"
        if self.lo is None:
            return f"a number {'<' if self.hi_open else '<='} {self.hi:g}"
        return (f"a number in {'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}"
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
    """``float``, ``int``, ``bool``, ``str``, a dataclass (a sub-table) or ``(tuple, item
    type, length or None)`` of an annotation (``X | None`` is ``X``: TOML has no null)."""
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
        return error(f"'{key}' must be {need}, got {value!r}", path=path,
                     hint=None if check is None else check.hint)
    if isinstance(kind, tuple):
        _, item, length = kind
        empty_ok = check is not None and check.allow_empty and length is None
        if not isinstance(value, list | tuple) or (not value and not empty_ok) or (
                length is not None and len(value) != length):
            many = (f"a list of {length}" if length else "a list of" if empty_ok
                    else "a non-empty list of")
            raise bad(f"{many} {_name(item)}s")
        item_check = None if check is None else dataclasses.replace(
            check, test=None, need="" if check.test else check.need)
        out = tuple(checked_value(v, item, f"{key}[{i}]", path, item_check, error=error)
                    for i, v in enumerate(value))
        if check is not None and check.test is not None and not check.test(out):
            raise bad(check.need)
        return out
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
    if check is not None:
        if not check.ok(out):
            need = check.text()
            raise bad(need.replace(" number", " whole number", 1) if kind is int else need)
        if check.test is not None and not check.test(out):
            raise bad(check.need)
    return out


def _name(kind) -> str:
    return {float: "number", int: "whole number", bool: "true/false", str: "text"}.get(
        kind, getattr(kind, "__name__", str(kind)))


def checked(default: object = dataclasses.MISSING, check: Check | None = None, *,
            factory: Callable[[], object] | None = None) -> dataclasses.Field:
    """A dataclass field with its ``default`` (or ``factory``) and the :class:`Check` its
    value must pass (:func:`read_table`, :func:`check_fields`), declared in one place."""
    meta = {"check": check} if check is not None else {}
    if factory is not None:
        return dataclasses.field(default_factory=factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def defaults_from(table: Mapping):
    """Class decorator (under ``@dataclass``): every annotated field takes its default from
    ``table`` (lists become tuples), so that a TOML file is the one source of the defaults;
    a field missing from ``table`` is an error when the module loads."""
    def deco(cls):
        for name in inspect.get_annotations(cls):
            value = table[name]
            value = tuple(value) if isinstance(value, list) else value
            current = cls.__dict__.get(name)
            if isinstance(current, dataclasses.Field):
                current.default = value
            else:
                setattr(cls, name, value)
        return cls
    return deco


def prefixed(where: str, error: type[InputError] = InputError):
    """An ``error`` maker (for the ``error`` arguments here) whose messages start with
    ``where``, e.g. ``"recording #2"``."""
    def make(message: str, **kwargs) -> InputError:
        return error(f"{where}: {message}", **kwargs)
    return make


def _section_text(section: str) -> tuple[str, str]:
    """The key prefix and the 'takes' text of the table ``section`` ("" for the file)."""
    if not section:
        return "", "the file takes"
    return f"{section}.", f"[{section}] takes"


def read_table(cls, table: object, *, section: str, path: object,
               checks: Mapping[str, Check] | None = None, skip: Iterable[str] = (),
               given: Mapping | None = None, error: type[InputError] = InputError,
               base: object = None, extra: str | None = None, key_prefix: str | None = None):
    """An instance of the frozen dataclass ``cls`` from the TOML ``table`` ``[section]`` of
    the file ``path`` ("" for the whole file).

    Unknown keys are refused (with the nearest known one); every value is converted to its
    field's type and checked by ``checks[field]`` (or the field's ``metadata["check"]``).
    A field whose type is a dataclass is a sub-table (``[section.key]``, read the same way),
    a ``tuple[SomeDataclass, ...]`` a list of tables (``[[section.key]]``). Keys in ``skip``
    may be in the table but are not read (sub-tables the caller reads itself); ``given``
    supplies fields the caller built (not keys of the table); ``extra`` names a dict field
    that keeps the keys the dataclass does not have instead of refusing them; ``key_prefix``
    replaces ``"section."`` before the keys in messages. Missing keys keep the values of
    ``base`` (an instance of ``cls``) or the defaults; a field with neither is a missing key
    (with the given key it may be misspelt as)."""
    if table is None:
        table = {}
    prefix, takes = _section_text(section)
    prefix = prefix if key_prefix is None else key_prefix
    if not isinstance(table, Mapping):
        raise error(f"[{section}] must be a table, got {table!r}", path=path,
                    hint=f"write [{section}] with its keys")
    skip, given = tuple(skip), dict(given or {})
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    known = [*(n for n in fields if n not in given and n not in ("raw", extra)), *skip]
    if extra is None:
        unknown_keys(table, known, "", path, error=error, prefix=prefix, takes=takes)
    hints = _type_hints(cls)
    checks = dict(checks or {})
    kwargs = dict(given)
    for key, value in table.items():
        if key in skip or key not in known:
            continue
        f = fields[key]
        kind = _kind(hints[key])
        sub = None if base is None else getattr(base, key)
        if dataclasses.is_dataclass(kind):
            if not isinstance(value, Mapping):
                raise error(f"'{prefix}{key}' must be a table, got {value!r}", path=path,
                            hint=f"write [{prefix}{key}] with its keys")
            kwargs[key] = read_table(kind, value, section=f"{prefix}{key}", path=path,
                                     error=error, base=sub)
        elif isinstance(kind, tuple) and dataclasses.is_dataclass(kind[1]):
            if not isinstance(value, list) or not all(isinstance(v, Mapping) for v in value):
                raise error(f"'{prefix}{key}' must be tables [[{prefix}{key}]], got {value!r}",
                            path=path)
            kwargs[key] = tuple(read_table(kind[1], v, section=f"{prefix}{key}[{i + 1}]",
                                           path=path, error=error)
                                for i, v in enumerate(value))
        else:
            check = checks.get(key, f.metadata.get("check"))
            kwargs[key] = checked_value(value, kind, f"{prefix}{key}", path, check, error=error)
    if extra is not None:
        kwargs[extra] = {k: v for k, v in table.items() if k not in known}
    if base is not None:
        return dataclasses.replace(base, **kwargs)
    for name, f in fields.items():
        if (name not in kwargs and f.default is dataclasses.MISSING
                and f.default_factory is dataclasses.MISSING):
            near = difflib.get_close_matches(name, [str(k) for k in table], n=1)
            raise error(f"missing key '{prefix}{name}'", path=path, hint=(
                f"is '{near[0]}' meant to be '{name}'? " if near else "")
                + (f"add '{name} = <value>' under [{section}]" if section
                   else f"add '{name} = <value>'"))
    return cls(**kwargs)


@functools.cache
def _type_hints(cls) -> types.MappingProxyType:
    """``typing.get_type_hints(cls)``, read-only and resolved once per class (resolving the
    annotations' strings is most of a small table's reading: ~0.4 ms a channel map)."""
    return types.MappingProxyType(typing.get_type_hints(cls))


def check_key(cls, name: str, value: object, key: str, path: object, *,
              error: type[InputError] = InputError):
    """``value`` checked as :func:`read_table` checks the field ``name`` of the dataclass
    ``cls`` (its type and its ``metadata["check"]``), an error naming ``key``; converted."""
    f = {f.name: f for f in dataclasses.fields(cls)}[name]
    kind = _kind(_type_hints(cls)[name])
    return checked_value(value, kind, key, path, f.metadata.get("check"), error=error)


def check_fields(instance, section: str, *, path: object = None,
                 error: type[InputError] = InputError) -> None:
    """Check the values of a dataclass built in code against the :class:`Check` of each
    field (``metadata["check"]``), as :func:`read_table` checks a file's: ``error`` naming
    ``section.field`` and the value. Types are not checked (code may give an int for a
    float)."""
    for f in dataclasses.fields(instance):
        check = f.metadata.get("check")
        if check is None:
            continue
        value = getattr(instance, f.name)
        if isinstance(value, list | tuple):
            in_range = (bool(value) or check.allow_empty) and all(check.ok(v) for v in value)
        else:
            in_range = check.ok(value)
        if not in_range:
            need = check.text()
        elif check.test is not None and not check.test(value):
            need = check.need
        else:
            continue
        raise error(f"'{section}.{f.name}' must be {need}, got {value!r}", path=path,
                    hint=check.hint)


def below_nyquist(frequency_hz: float, sample_rate_hz: float, key: str, rate_key: str,
                  path: object, *, error: type[InputError] = InputError) -> None:
    """Refuse a frequency at or above half the sample rate (it cannot be recorded: it folds
    to another frequency, Shannon's sampling theorem), naming both keys."""
    if not frequency_hz < sample_rate_hz / 2:
        raise error(f"'{key}' = {frequency_hz:g} Hz is at or above the Nyquist frequency "
                    f"({sample_rate_hz / 2:g} Hz) of '{rate_key}' = {sample_rate_hz:g} Hz",
                    path=path, hint=f"lower {key} or raise {rate_key}")
