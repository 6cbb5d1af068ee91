"""The available adhesion from the creep-coefficient progression of a stretch of track: the
on-board use of the one estimator, :func:`torquemod.analysis.friction.fit_available_adhesion`.

The on-board windows give the creep coefficient k directly (with its standard error), so the
fit is in k: ``k(CoA) = k0*s(CoA/P; theta)`` over the family of :mod:`torquemod.analysis.creeplaws`
(Polach with constant and falling friction, Burckhardt, saturating laws), P the **available
adhesion** (the maximum of the adhesion-creepage curve). ``mu`` in :class:`CreepFit` and in
track.parquet is that available adhesion; for a constant-friction law whose curve rises to
its friction it is the friction coefficient.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from torquemod.analysis.friction import AdhesionFit, fit_available_adhesion

__all__ = ["SEGMENT_COLUMNS", "CreepFit", "SegmentFit", "fit_creep_progression", "fit_segment",
           "group_points"]


@dataclass(frozen=True)
class CreepFit:
    """One fit of the creep-coefficient progression of a stretch of track.

    Attributes
    ----------
    mu : float
        The available adhesion P, best fit [-] (the maximum of the adhesion-creepage curve).
    mu_low : float
        Lower end of its 95 % interval [-]; the lower bound when the interval is open.
    mu_high : float
        Upper end of its 95 % interval [-]; NaN when the interval is open.
    determined : bool
        The interval is closed and narrow enough (``max_rel_half_width``).
    mu0 : float
        The best law's friction coefficient [-]; meaningful only when
        ``adhesion.mu0_identified``.
    k0 : float
        The fitted initial creep coefficient (slope at zero creepage) [-].
    chi2 : float
        Chi-square of the best fit [-].
    dof : int
        Its degrees of freedom [-].
    law : str
        Name of the best member of the family (:mod:`torquemod.analysis.creeplaws`).
    adhesion : torquemod.analysis.friction.AdhesionFit
        The full fit.
    """

    mu: float
    mu_low: float
    mu_high: float
    determined: bool
    mu0: float
    k0: float
    chi2: float
    dof: int
    law: str
    adhesion: AdhesionFit

    def creep_coefficient(self, coa) -> np.ndarray:
        """The fitted k at the CoA values [-] (NaN at or beyond the curve's peak)."""
        return self.k0 * self.adhesion.creep_ratio(coa)


def fit_creep_progression(coa, k, k_se, *, coa_now: float | None = None,
                          ratio_bounds: tuple[float, float] = (0.3, 7.0),
                          mu_span: float = 6.0, max_rel_half_width: float = 0.10,
                          power: bool = True, probe: bool = False,
                          speed_m_s: float | None = None, swing=None) -> CreepFit | None:
    """Fit the available adhesion to creep coefficients measured at utilised adhesions.

    The on-board use of :func:`torquemod.analysis.friction.fit_available_adhesion`: the
    observations are creep coefficients (``constant`` 1).

    Parameters
    ----------
    coa : array_like
        Utilised adhesion (CoA) of each point [-].
    k : array_like
        Creep coefficient dCoA/dxi of each point [-].
    k_se : array_like
        Standard errors of ``k`` [-].
    coa_now : float or None
        Accepted for compatibility and ignored [-] (the available adhesion does not depend on
        the operating point).
    ratio_bounds : tuple of float
        Range of kA/kS of the Polach members [-]. Default (0.3, 7.0).
    mu_span : float
        Largest P tried, as a multiple of the largest CoA [-]. Default 6.
    max_rel_half_width : float
        Widest relative half interval that counts as determined [-]. Default 0.10.
    power : bool
        Also the non-Polach members (Burckhardt, saturating laws). Default True.
    probe : bool
        Also the probe depth that would determine P. Default False.
    speed_m_s : float or None
        Rolling speed V [m/s]: bounds the friction's fall with slip velocity. Default None.
    swing : array_like or None
        Creepage swing amplitude of the modulation per point [-]; None: small-signal slopes
        (near the peak a swing of a few tenths of ``mu/k0`` changes the measured slope: the
        describing function of the curve over the swing).

    Returns
    -------
    CreepFit or None
        The fit; None when fewer than four usable points remain.

    Notes
    -----
    ``k(CoA) = k0*s(CoA/P; theta)`` over the family of creep laws, with the 95 % profile
    likelihood interval of P [1]_ over the whole family; the Polach members follow [2]_.

    References
    ----------
    .. [1] S.S. Wilks, "The large-sample distribution of the likelihood ratio for testing
       composite hypotheses", Ann. Math. Statist. 9(1) (1938) 60-62.
    .. [2] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
    """
    del coa_now
    fit = fit_available_adhesion(coa, k, k_se, max_rel_half_width=max_rel_half_width,
                                 p_span=mu_span, probe=probe, ratio_bounds=ratio_bounds,
                                 other_laws=power, speed_m_s=speed_m_s, swing=swing)
    if fit is None:
        return None
    high = fit.high if fit.closed else math.nan
    low = fit.low if fit.closed else fit.lower_bound
    return CreepFit(fit.estimate, low, high, fit.determined, fit.mu0, fit.k0, fit.chi2,
                    fit.dof, fit.law, fit)


def group_points(coa, k, k_se, *, overlap: float = 1.0, n_bins: int = 12,
                 model_rel_error: float = 0.0, min_points: int = 4,
                 swing=None) -> np.ndarray | None:
    """Reduce windows' creep coefficients to at most ``n_bins`` points.

    A probe holds the torque at a few levels, so the windows fall in clusters of CoA; each
    cluster (consecutive sorted CoA values less than 5 % apart) gives one point, so that no
    point mixes two levels (a mixed point sits between them with a standard error inflated
    by their difference). A cluster wider than 10 % of its mean CoA (a driver's varying
    demand) is cut into groups of equal count (``ceil(n/n_bins)``, at least 4 windows each);
    when that gives more than ``n_bins`` groups, all windows are cut so.

    Parameters
    ----------
    coa : array_like
        Utilised adhesion of each window [-].
    k : array_like
        Creep coefficient of each window [-].
    k_se : array_like
        Standard errors of ``k`` [-].
    overlap : float
        How many windows each sample falls in [-]; widens the windows' own errors.
        Default 1.
    n_bins : int
        Largest number of points [-]. Default 12.
    model_rel_error : float
        Relative systematic error of each window's k [-], added in quadrature. Default 0.
    min_points : int
        Fewest points for a result [-]. Default 4.
    swing : array_like or None
        Creepage swing amplitude of each window [-]; when given, a fourth column.

    Returns
    -------
    ndarray or None
        (n, 3) rows of (CoA [-], k [-], se [-]), or (n, 4) with the group's mean swing [-];
        None when fewer than ``min_points`` points remain.

    Notes
    -----
    Each point: the inverse-variance mean ``k_b = sum(w*k)/sum(w)``, ``w = 1/k_se^2``; its
    standard error ``hypot(max(sqrt(overlap/sum(w)), scatter), model_rel_error*k_b)`` with
    ``scatter = std(k)/sqrt(n/overlap)`` (a single window's group has no scatter).

    Examples
    --------
    >>> pts = group_points([0.05, 0.05, 0.10, 0.10, 0.15, 0.15, 0.20, 0.20],
    ...                    [100.0, 100.0, 90.0, 90.0, 70.0, 70.0, 40.0, 40.0], [5.0] * 8)
    >>> pts[:, :2].tolist()
    [[0.05, 100.0], [0.1, 90.0], [0.15, 70.0], [0.2, 40.0]]
    """
    coa, k, k_se = (np.asarray(a, dtype=float) for a in (coa, k, k_se))
    if coa.size == 0:
        return None
    order = np.argsort(coa, kind="stable")
    cs = coa[order]
    size = max(4, -(-coa.size // n_bins))  # ceil: at most n_bins groups of equal count
    cuts = np.flatnonzero(np.diff(cs) > 0.05 * cs[1:]) + 1
    groups = []
    for grp in np.split(order, cuts):
        wide = coa[grp[-1]] - coa[grp[0]] > 0.1 * coa[grp].mean()
        groups += np.array_split(grp, max(1, grp.size // size)) if wide else [grp]
    if len(groups) > n_bins:
        groups = np.array_split(order, max(1, coa.size // size))
    pts = []
    for grp in groups:
        wgt = 1.0 / k_se[grp] ** 2
        k_b = float(np.sum(wgt * k[grp]) / wgt.sum())
        se_b = math.sqrt(overlap / wgt.sum())
        scatter = (float(np.std(k[grp], ddof=1)) / math.sqrt(grp.size / overlap)
                   if grp.size > 1 else 0.0)
        se = math.hypot(max(se_b, scatter), model_rel_error * k_b)
        row = (float(coa[grp].mean()), k_b, se)
        if swing is not None:
            row += (float(np.mean(np.asarray(swing, dtype=float)[grp])),)
        pts.append(row)
    return np.array(pts) if len(pts) >= min_points else None


#: the columns of the per-segment table (``segments.csv``), in order
SEGMENT_COLUMNS = ("segment", "start_m", "end_m", "windows", "coa_reached",
                   "adhesion_available", "adhesion_available_best_fit",
                   "adhesion_available_low_95", "adhesion_available_high_95",
                   "adhesion_available_lower_bound", "determined", "best_law",
                   "probe_depth_needed")


@dataclass(frozen=True)
class SegmentFit:
    """The available adhesion of one stretch between detected friction changes.

    Fitted once the stretch has ended, from all its steady windows (not only those a live
    row had).

    Attributes
    ----------
    start_m : float
        Start of the stretch along the track [m].
    end_m : float
        End of the stretch [m].
    windows : int
        Steady windows fitted [-].
    coa_reached : float
        Their largest CoA [-].
    fit : CreepFit or None
        The fit; None when too few windows or points.
    """

    start_m: float
    end_m: float
    windows: int
    coa_reached: float
    fit: CreepFit | None

    def to_dict(self, segment: int) -> dict:
        """One row of :data:`SEGMENT_COLUMNS` (NaN where unknown): ``adhesion_available``
        only when determined, ``adhesion_available_best_fit`` always (the best-fitting
        value, an estimate only as good as its interval), the 95 % interval (high NaN
        when open above) and the lower bound (never below ``coa_reached``)."""
        a = None if self.fit is None else self.fit.adhesion
        nan = math.nan
        return {"segment": segment, "start_m": self.start_m, "end_m": self.end_m,
                "windows": self.windows, "coa_reached": self.coa_reached,
                "adhesion_available": a.estimate if a is not None and a.determined else nan,
                "adhesion_available_best_fit": nan if a is None else a.estimate,
                "adhesion_available_low_95": nan if a is None else a.low,
                "adhesion_available_high_95": nan if a is None or not a.closed else a.high,
                "adhesion_available_lower_bound": self.coa_reached if a is None
                else a.lower_bound,
                "determined": bool(a is not None and a.determined),
                "best_law": "" if a is None else a.law,
                "probe_depth_needed": nan if a is None else a.probe_depth}


def fit_segment(coa, k, k_se, start_m: float, end_m: float, *, swing=None,
                overlap: float = 1.0,
                n_bins: int = 12, model_rel_error: float = 0.0, min_windows: int = 12,
                min_coa_ratio: float = 2.0, ratio_bounds: tuple[float, float] = (0.3, 7.0),
                power: bool = True, max_rel_half_width: float = 0.10,
                speed_m_s: float | None = None) -> SegmentFit:
    """The :class:`SegmentFit` of a stretch from its steady windows.

    The windows are grouped (:func:`group_points`) and fitted
    (:func:`fit_creep_progression`, with the probe depth).

    Parameters
    ----------
    coa : array_like
        Utilised adhesion of each window [-].
    k : array_like
        Creep coefficient of each window [-].
    k_se : array_like
        Standard errors of ``k`` [-].
    start_m : float
        Start of the stretch [m].
    end_m : float
        End of the stretch [m].
    swing : array_like or None
        Creepage swing amplitude of each window [-]; None: not modelled.
    overlap : float
        How many windows each sample falls in [-]. Default 1.
    n_bins : int
        Largest number of grouped points [-]. Default 12.
    model_rel_error : float
        Relative systematic error of each window's k [-]. Default 0.
    min_windows : int
        Fewest usable windows for a fit [-]. Default 12.
    min_coa_ratio : float
        Smallest ratio of the largest to the smallest CoA for a fit [-]. Default 2.
    ratio_bounds : tuple of float
        Range of kA/kS of the Polach members [-]. Default (0.3, 7.0).
    power : bool
        Also the non-Polach members. Default True.
    max_rel_half_width : float
        Widest relative half interval that counts as determined [-]. Default 0.10.
    speed_m_s : float or None
        Rolling speed [m/s]. Default None.

    Returns
    -------
    SegmentFit
        With ``fit`` None when fewer than ``min_windows`` usable windows, a CoA range below
        ``min_coa_ratio`` or too few grouped points.
    """
    coa, k, k_se = (np.asarray(a, dtype=float) for a in (coa, k, k_se))
    ok = (coa > 0) & np.isfinite(k) & (k > 0) & np.isfinite(k_se) & (k_se > 0)
    coa, k, k_se = coa[ok], k[ok], k_se[ok]
    if swing is not None:
        swing = np.nan_to_num(np.asarray(swing, dtype=float)[ok])
    reached = float(coa.max()) if coa.size else math.nan
    fit = None
    if coa.size >= min_windows and coa.max() >= min_coa_ratio * coa.min():
        pts = group_points(coa, k, k_se, overlap=overlap, n_bins=n_bins,
                           model_rel_error=model_rel_error, swing=swing)
        if pts is not None:
            fit = fit_creep_progression(*pts[:, :3].T, ratio_bounds=ratio_bounds,
                                        power=power, max_rel_half_width=max_rel_half_width,
                                        probe=True, speed_m_s=speed_m_s,
                                        swing=pts[:, 3] if swing is not None else None)
    return SegmentFit(float(start_m), float(end_m), int(coa.size), reached, fit)
