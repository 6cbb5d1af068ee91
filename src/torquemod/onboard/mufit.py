"""The available adhesion from the creep-coefficient progression of a stretch of track: the
on-board use of the one estimator, :func:`torquemod.friction.fit_available_adhesion`.

The on-board windows give the creep coefficient k directly (with its standard error), so the
fit is in k: ``k(CoA) = k0*s(CoA/P; theta)`` over the family of :mod:`torquemod.creeplaws`
(Polach with constant and falling friction, Burckhardt, saturating laws), P the **available
adhesion** (the maximum of the adhesion-creepage curve). ``mu`` in :class:`CreepFit` and in
track.parquet is that available adhesion; for a constant-friction law whose curve rises to
its friction it is the friction coefficient.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..friction import AdhesionFit, fit_available_adhesion

__all__ = ["SEGMENT_COLUMNS", "CreepFit", "SegmentFit", "fit_creep_progression", "fit_segment",
           "group_points"]


@dataclass(frozen=True)
class CreepFit:
    """One fit of the creep-coefficient progression. ``mu`` [-]: the available adhesion
    (best fit); ``mu_low``/``mu_high``: its 95 % interval (``mu_low`` the lower bound and
    ``mu_high`` NaN when the interval is open); ``determined``: closed and narrow enough;
    ``mu0``: the best law's friction coefficient (meaningful only when
    ``adhesion.mu0_identified``); ``k0`` the initial creep coefficient; ``law`` the best
    member; ``adhesion`` the full :class:`torquemod.friction.AdhesionFit`."""

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
    """Fit creep coefficients ``k`` [-] with standard errors ``k_se`` at utilised adhesions
    ``coa`` [-] (module docstring). ``ratio_bounds``: kA/kS of the Polach members;
    ``power``: also the non-Polach laws; ``mu_span``: the largest P tried, as a multiple of
    the largest CoA; ``probe``: also the probe depth that would determine P; ``speed_m_s``
    [m/s]: the rolling speed (bounds the friction's fall with the slip velocity). ``coa_now`` is
    accepted for compatibility (the available adhesion does not depend on the operating
    point). ``swing`` [-]: the creepage swing amplitude of the modulation per point (None:
    small-signal slopes; near the peak a swing of a few tenths of ``mu/k0`` changes the
    measured slope, the describing function of the curve over the swing). None when fewer
    than four usable points remain."""
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
    """The windows' creep coefficients ``k`` [-] (standard errors ``k_se``) at utilised
    adhesions ``coa`` [-] reduced to at most ``n_bins`` points, (n, 3) rows of (CoA, k, se).

    A probe holds the torque at a few levels, so the windows fall in clusters of CoA; each
    cluster (consecutive sorted CoA values less than 5 % apart) gives one point, so that no
    point mixes two levels (a mixed point sits between them with a standard error
    inflated by their difference). A cluster wider than 10 % of its mean CoA (a driver's
    varying demand) is cut into groups of equal count (``ceil(n/n_bins)``, at least 4
    windows each); when that gives more than ``n_bins`` groups, all windows are cut so.
    Each point: the inverse-variance mean of k; its standard error the larger of the
    windows' own (widened by ``overlap``, the windows each sample falls in) and the
    group's scatter, combined with ``model_rel_error`` times k (the windows' systematic
    error; a single window's group has no scatter). With ``swing`` (the windows' creepage
    swing amplitudes [-]) a fourth column: the group's mean swing. None when fewer than
    ``min_points`` points remain."""
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
    """The available adhesion of one stretch between detected friction changes, fitted
    once the stretch has ended from all its steady windows (not only those a live row
    had). Positions [m]; ``windows``: the windows fitted; ``coa_reached`` [-]: their
    largest CoA; ``fit``: the :class:`CreepFit` (None when too few points)."""

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
    """The :class:`SegmentFit` of a stretch ``[start_m, end_m]`` [m] from its steady
    windows' CoA, k and k's standard error [-] and creepage swing [-] (None: not
    modelled) (:func:`group_points`, then
    :func:`fit_creep_progression` with the probe depth); no fit when fewer than
    ``min_windows`` windows or a CoA range below ``min_coa_ratio``."""
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
