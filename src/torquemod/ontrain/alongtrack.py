"""The friction along the track summarised per stretch: per segment between the friction
changes the estimator detected, or per kilometre (pure functions over a track table).

Each stretch gets its position range, the windows it holds, μ where the estimator gave it
(median and the median 95 % interval over those windows), the lower bound where it did not,
the share of windows flagged ``low_adhesion`` and ``slip``, the adhesion the axle reached
(95th percentile of CoA) and, where μ is given, how deep that is into the friction (the
probe depth, adhesion reached / μ; left empty where the stretch is ``mixed``), and a guess
of the rail condition.

Summary rules (one definition wherever a stretch, a run or a fleet row is summarised):

* ``mu``: the median of μ over the windows where μ is determined only;
* ``mu_low_95``, ``mu_high_95``: the medians of those windows' interval ends;
* ``mu_lower_bound``: the 95th percentile of the windows' lower bounds (CoA less two standard
  errors) over the windows where μ is *not* determined. A high percentile keeps the deepest
  probing of a stretch; the maximum is not used because single windows straddling a friction
  change or a torque step reach above the friction of the stretch (on the train twin's
  4 km run the maximum exceeded the friction of the leaf-covered segment, the 95th
  percentile did not).

Condition guess
---------------
The available adhesion (the maximum of the adhesion-creepage curve) lies between the lower
bound (CoA cannot exceed it) and the upper end of μ's 95 % interval (the estimator's μ is the
available adhesion, and friction, were it that, is never below it); it is unbounded above
where μ is not determined. A stretch whose lower bound lies
above μ's interval spans different rails (a kilometre holding a friction change) and is
``mixed``. The guess names the service
classes that range overlaps, with class limits taken between the published service ranges of
rail adhesion -- dry 0.3-0.4 and more, wet 0.15-0.22, leaf layers below 0.05-0.10 (Lewis et al.,
Tribology International 185 (2023) 108529, and the literature reviewed there):
``dry`` from :data:`DRY_MIN`, ``wet`` from :data:`WET_MIN`, ``low adhesion`` below. A
stretch whose range covers all three classes is ``not probed``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd

__all__ = ["CONDITIONS", "DRY_MIN", "STRETCH_COLUMNS", "WET_MIN", "along_track",
           "guess_condition", "run_mu_summary", "stretch_bounds", "summarise"]

#: the class limit between wet and dry rail [-]: midway between the wet range's top (0.22)
#: and the dry range's bottom (0.30) of the service ranges (module docstring)
DRY_MIN = 0.26
#: the class limit between low adhesion (leaf layers) and wet rail [-]: midway between the
#: leaf range's top (0.10) and the wet range's bottom (0.15)
WET_MIN = 0.125
#: the classes, lowest first, with their lower limits [-]
CONDITIONS = (("low adhesion", 0.0), ("wet", WET_MIN), ("dry", DRY_MIN))
#: the columns of an along-track table, in order
STRETCH_COLUMNS = ("stretch", "start_m", "end_m", "windows", "condition", "mu", "mu_low_95",
                   "mu_high_95", "mu_given_share", "mu_lower_bound", "low_adhesion_share",
                   "slip_share", "coa_reached", "probe_depth")


def _class_of(level: float) -> int:
    k = 0
    for i, (_, low) in enumerate(CONDITIONS):
        if level >= low:
            k = i
    return k


def guess_condition(lower: float | None, upper: float | None) -> str:
    """The service classes the available adhesion may lie in, given bounds on it.

    Parameters
    ----------
    lower : float or None
        Lower bound of the available adhesion [-]; None or NaN: unknown (0).
    upper : float or None
        Upper bound [-]; None or NaN: unknown (unbounded).

    Returns
    -------
    str
        One class of :data:`CONDITIONS` or several joined by " or "; ``"mixed"`` when
        ``lower > upper`` (the stretch spans different rails); ``"not probed"`` when every
        class is possible.

    Notes
    -----
    Class limits lie midway between published service ranges of rail adhesion (dry
    0.3-0.4 and more, wet 0.15-0.22, leaf layers below 0.05-0.10) [1]_.

    References
    ----------
    .. [1] R. Lewis et al., review of rail adhesion in service, Tribology International 185
       (2023) 108529.

    Examples
    --------
    >>> guess_condition(0.30, 0.40)
    'dry'
    >>> guess_condition(0.15, 0.30)
    'wet or dry'
    >>> guess_condition(None, None)
    'not probed'
    """
    lo = 0.0 if lower is None or not math.isfinite(lower) else max(0.0, float(lower))
    hi = math.inf if upper is None or not math.isfinite(upper) else float(upper)
    if lo > hi:
        return "mixed"
    a, b = _class_of(lo), _class_of(hi)
    if a == 0 and b == len(CONDITIONS) - 1:
        return "not probed"
    names = [CONDITIONS[i][0] for i in range(a, b + 1)]
    return names[0] if len(names) == 1 else " or ".join(names)


def stretch_bounds(start_m: float, end_m: float, changes_m=()) -> list[tuple[float, float]]:
    """The stretches between two positions cut at the friction changes inside.

    Parameters
    ----------
    start_m : float
        Start [m].
    end_m : float
        End [m].
    changes_m : sequence of float
        Positions of detected friction changes [m]; those outside (start, end) are ignored.

    Returns
    -------
    list of tuple of float
        ``(a, b)`` pairs [m], half-open ``[a, b)`` but for the last, which includes ``end_m``.

    Examples
    --------
    >>> stretch_bounds(0.0, 100.0, [40.0, 150.0])
    [(0.0, 40.0), (40.0, 100.0)]
    """
    cuts = sorted(float(c) for c in changes_m if start_m < float(c) < end_m)
    edges = [float(start_m), *cuts, float(end_m)]
    return list(itertools.pairwise(edges))


def _median(x: pd.Series) -> float:
    x = x.dropna()
    return float(x.median()) if len(x) else math.nan


def summarise(part: pd.DataFrame) -> dict:
    """One stretch's summary from its windows (the rules of the module docstring).

    Parameters
    ----------
    part : pandas.DataFrame
        The stretch's track rows (``mu``, ``mu_low_95``, ``mu_high_95``, ``coa``,
        ``low_adhesion``, ``slip``).

    Returns
    -------
    dict
        ``windows``; ``condition`` (:func:`guess_condition`); ``mu``, ``mu_low_95``,
        ``mu_high_95`` and ``mu_lower_bound`` [-]; ``mu_given_share``,
        ``low_adhesion_share`` and ``slip_share`` [-]; ``coa_reached`` (95th percentile of
        CoA) [-]; ``probe_depth`` = coa_reached/mu [-] (NaN without mu or when ``mixed``).
    """
    given = part["mu"].notna()
    mu = _median(part.loc[given, "mu"])
    lows = part.loc[~given, "mu_low_95"].dropna()
    bound = float(np.percentile(lows, 95)) if len(lows) else math.nan
    coa = part["coa"].dropna()
    reached = float(np.percentile(coa, 95)) if len(coa) else math.nan
    high = _median(part.loc[given, "mu_high_95"])
    lower = bound if math.isfinite(bound) else _median(part.loc[given, "mu_low_95"])
    condition = guess_condition(lower, high) if len(part) else "no windows"
    return {"windows": len(part), "condition": condition, "mu": mu,
            "mu_low_95": _median(part.loc[given, "mu_low_95"]), "mu_high_95": high,
            "mu_given_share": float(given.mean()) if len(part) else 0.0,
            "mu_lower_bound": bound,
            "low_adhesion_share": float(part["low_adhesion"].astype(bool).mean())
            if len(part) else 0.0,
            "slip_share": float(part["slip"].astype(bool).mean()) if len(part) else 0.0,
            "coa_reached": reached,
            "probe_depth": reached / mu if math.isfinite(mu) and mu > 0
            and condition != "mixed" else math.nan}


def along_track(track: pd.DataFrame, *, changes_m=(), by: str = "segment",
                length_m: float = 1000.0) -> pd.DataFrame:
    """The along-track table of a track: one row per segment or per kilometre.

    Parameters
    ----------
    track : pandas.DataFrame
        A track (``track.parquet`` columns).
    changes_m : sequence of float
        Positions of the friction changes the estimator detected [m].
    by : {"segment", "km"}
        One row per segment between the changes, or per ``length_m`` of track counted from
        0. Default "segment".
    length_m : float
        Length of the ``by="km"`` stretches [m]. Default 1000.

    Returns
    -------
    pandas.DataFrame
        Columns :data:`STRETCH_COLUMNS`; ``start_m``/``end_m`` the stretch's limits [m]; a
        stretch without windows is left out.

    Raises
    ------
    ValueError
        ``by`` is neither "segment" nor "km".
    """
    if by not in ("segment", "km"):
        raise ValueError(f"by must be 'segment' or 'km', got {by!r}")
    if not len(track):
        return pd.DataFrame(columns=list(STRETCH_COLUMNS))
    x = track["position_m"].to_numpy(dtype=float)
    lo, hi = float(np.nanmin(x)), float(np.nanmax(x))
    if by == "segment":
        bounds = stretch_bounds(lo, hi, changes_m)
    else:
        first = math.floor(lo / length_m)
        bounds = [(k * length_m, (k + 1) * length_m)
                  for k in range(first, math.floor(hi / length_m) + 1)]
    rows = []
    for i, (a, b) in enumerate(bounds):
        last = i == len(bounds) - 1
        inside = (x >= a) & ((x <= b) if last else (x < b))
        if not inside.any():
            continue
        rows.append({"stretch": len(rows) + 1, "start_m": a, "end_m": b,
                     **summarise(track[inside])})
    return pd.DataFrame(rows, columns=list(STRETCH_COLUMNS))


def run_mu_summary(track: pd.DataFrame) -> tuple[float | None, float | None]:
    """A train run's ``mu`` and ``mu_lower_bound`` summary fields from its windows.

    ``mu`` is the median of mu over the windows where it is determined. ``mu_lower_bound``
    summarises the same windows: the median of their 95 % intervals' lower ends, so it never
    exceeds ``mu``; where mu is determined nowhere, the lower bound of the whole run, the 95th
    percentile of the windows' bounds (the maximum is reached by single windows straddling a
    friction change). A row mixing friction levels would otherwise set a mu from one stretch
    beside a bound from another.

    Parameters
    ----------
    track : pandas.DataFrame
        The run's track (``track.parquet`` columns).

    Returns
    -------
    mu : float or None
        [-]; None when mu is determined nowhere.
    mu_lower_bound : float or None
        [-]; None when unknown.
    """
    if not len(track):
        return None, None
    s = summarise(track)
    if math.isfinite(s["mu"]):
        low = s["mu_low_95"]
        return s["mu"], (low if math.isfinite(low) else None)
    bound = s["mu_lower_bound"]
    return None, (bound if math.isfinite(bound) else None)
