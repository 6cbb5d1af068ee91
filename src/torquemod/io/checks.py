"""The one check of a positive number from a user's file (manifest, [channels], twin config):
the message names the key, the value and the file the same way everywhere."""

from __future__ import annotations

import math

from torquemod.errors import InputError


def positive_number(value: object, key: str, *, path: object = None, allow_zero: bool = False,
                    error: type[InputError] = InputError, hint: str | None = None) -> float:
    """A manifest value as a float when it is a finite number > 0.

    Booleans and strings are refused (TOML's ``true`` is not a number).

    Parameters
    ----------
    value : object
        The value as read.
    key : str
        Its key, e.g. 'test.normal_load_n', named in the message.
    path : object
        The file, named in the message. Default None.
    allow_zero : bool
        Accept 0 too. Default False.
    error : type
        The :class:`InputError` subclass to raise. Default InputError.
    hint : str or None
        What to do, for the message. Default None.

    Returns
    -------
    float
        The value, in whatever unit its key names.

    Raises
    ------
    InputError
        (``error``) not a finite number > 0 (>= 0 with ``allow_zero``).

    Examples
    --------
    >>> positive_number(3, "test.normal_load_n")
    3.0
    """
    need = "a non-negative" if allow_zero else "a positive"
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise error(f"'{key}' must be {need} number, got {value!r}", path=path, hint=hint)
    v = float(value)
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise error(f"'{key}' must be {need} finite number, got {value!r}", path=path,
                    hint=hint)
    return v
