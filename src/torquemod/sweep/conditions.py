"""The conditions of a rig sweep and their short labels.

A *condition* is one distinct combination of the swept parameters other than the
modulation setting (``modulation.frequency_hz``, ``modulation.amplitude_nm``): a named
friction condition, an explicit creep curve (``contact.mu0``, ``a_ratio``, ``b_s_m``,
``k_a``, ``k_s``), a speed, a normal load, a noise level, or any combination of them. The
report draws one panel per condition and compares the modulation settings within each.

Labels name only the parameters that differ between the conditions, with short names
(``mu0``, ``A``, ``B``, ``kA``, ``kS`` of Polach (2005) Eqs. 8-9; ``V``; ``N``), so that a
sweep over four Polach curves reads ``μ0=0.3, A=1, B=0, kA=0.3, kS=0.1`` and not as
five separate parameters.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from torquemod.analysis.contact.presets import POLACH_PRESETS, PolachParameters

__all__ = ["CONDITION_COLUMN", "SETTING_KEYS", "condition_keys", "condition_labels", "conditions",
           "short_name"]

#: the swept keys that make a modulation setting (what the recommendation chooses)
SETTING_KEYS = ("modulation.frequency_hz", "modulation.amplitude_nm")
#: the column :func:`condition_labels` results are stored under in the summaries
CONDITION_COLUMN = "condition"

_SHORT = {"contact.condition": "", "contact.mu0": "μ0", "contact.a_ratio": "A",
          "contact.b_s_m": "B", "contact.k_a": "kA", "contact.k_s": "kS",
          "rig.speed_km_h": "V", "rig.normal_load_n": "N",
          "modulation.frequency_hz": "f", "modulation.amplitude_nm": "A_mod"}
_UNITS = {"rig.speed_km_h": " km/h", "rig.normal_load_n": " N",
          "modulation.frequency_hz": " Hz", "modulation.amplitude_nm": " N*m"}


def short_name(key: str) -> str:
    """The short name of a swept key in labels.

    Parameters
    ----------
    key : str
        A swept key, e.g. ``contact.k_a``.

    Returns
    -------
    str
        ``mu0``, ``A``, ``B``, ``kA``, ``kS`` (Polach 2005, Eqs. 8-9), ``V``, ``N``, ...;
        unknown keys: their last part.

    Examples
    --------
    >>> short_name("contact.k_a")
    'kA'
    >>> short_name("sensors.torque_noise_nm")
    'torque_noise_nm'
    """
    return _SHORT.get(key, key.rsplit(".", 1)[-1])


def condition_keys(swept) -> list[str]:
    """The swept keys that make a condition: all but the modulation setting.

    Parameters
    ----------
    swept : iterable of str
        The swept keys.

    Returns
    -------
    list of str
        Those other than ``modulation.frequency_hz`` and ``modulation.amplitude_nm``.

    Examples
    --------
    >>> condition_keys(["modulation.frequency_hz", "contact.mu0"])
    ['contact.mu0']
    """
    return [k for k in swept if k not in SETTING_KEYS]


def _text(value) -> str:
    """A parameter value as label text: numbers to 4 significant digits, lists as JSON-like
    text, a missing value (the key not given at that point) as the empty string."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, bool | np.bool_):
        return str(bool(value)).lower()
    if isinstance(value, int | float | np.integer | np.floating):
        return f"{float(value):.4g}"
    if isinstance(value, list | tuple | np.ndarray):
        return "[" + ", ".join(_text(v) for v in value) + "]"
    return str(value)


def condition_labels(table: pd.DataFrame, swept) -> pd.Series:
    """Per row of a table the label of its condition.

    The label joins ``name=value`` for each condition key whose value differs between the
    conditions (a named condition by its name alone); a key a point does not set is left out
    of that point's label. Labels are unique per condition (a ``#n`` suffix otherwise).

    Parameters
    ----------
    table : pandas.DataFrame
        Rows with the swept keys as columns.
    swept : iterable of str
        The swept keys.

    Returns
    -------
    pandas.Series of str
        Same index; ``""`` for every row when the sweep has a single condition.
    """
    keys = [k for k in condition_keys(swept) if k in table]
    if not keys or table.empty:
        return pd.Series("", index=table.index, dtype=object)
    texts = pd.DataFrame({k: table[k].map(_text) for k in keys}, index=table.index)
    varying = [k for k in keys if texts[k].nunique() > 1]
    if not varying:
        return pd.Series("", index=table.index, dtype=object)

    def label(row) -> str:
        parts = []
        for k in varying:
            v = row[k]
            if v == "":
                continue
            name = short_name(k)
            parts.append(f"{name}={v}{_UNITS.get(k, '')}" if name else v)
        return ", ".join(parts) or "base"

    tuples = texts[varying].apply(tuple, axis=1)
    names: dict = {}
    used: dict[str, int] = {}
    for tup, (_, row) in zip(tuples, texts[varying].iterrows(), strict=True):
        if tup in names:
            continue
        text = label(row)
        used[text] = used.get(text, 0) + 1
        names[tup] = text if used[text] == 1 else f"{text} #{used[text]}"
    return tuples.map(names).astype(object)


def conditions() -> dict[str, PolachParameters]:
    """Named friction conditions a sweep can set with ``contact.condition``.

    The rig's presets (:data:`~torquemod.analysis.contact.presets.POLACH_PRESETS`: vtrack,
    dry, wet) and the train twin's track conditions (leaves, friction_modifier), each with
    its source.

    Returns
    -------
    dict of str to PolachParameters
        By name.
    """
    out = dict(POLACH_PRESETS)
    try:
        from torquemod.twins.train.params import CONDITIONS
        out.update({k: v for k, v in CONDITIONS.items() if k not in out})
    except ImportError:  # pragma: no cover - the train twin ships with the package
        pass
    return out
