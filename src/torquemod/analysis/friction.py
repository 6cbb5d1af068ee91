"""The available adhesion from a progression of creep coefficients: one estimator for the rig
(phases), the train (creep coefficients) and the sweep.

Estimand
--------
The **available adhesion** ``P``: the maximum of the adhesion-creepage curve at the operating
speed, what limits traction and braking, defined for every creep law. Written in its
utilisation ``u = CoA/P`` every law of :mod:`torquemod.analysis.creeplaws` gives the creep
coefficient
on its rising branch as ``k(CoA) = k0*s(CoA/P; theta)`` with ``s(0) = 1``, ``s(1) = 0``. The
law's own friction coefficient ``mu0`` (``P/F_pk``) is secondary: reported only where the
fits that the data allow agree on it.

Observations
------------
* train: ``k_i`` with standard errors, directly (:func:`fit_available_adhesion`);
* rig: the phase of the wheel speed behind the torque, ``tan(phi_i) = C/k_i`` (rigid wheel,
  V-Track paper Eq. 1 with ``C = Omega*J*V/(R^2*N)``), so ``y_i = cot(phi_i) = k_i/C`` with
  standard error ``se_phi/sin^2(phi)``; C need not be known, ``k0/C`` is fitted
  (:func:`fit_available_adhesion_from_phase`).

Large modulations swing the creepage by ``a_i``; the wheel then sees the describing-function
slope about the mean point (tables in :mod:`torquemod.analysis.creeplaws`), whose size in reduced
units
``a_i*k0/mu0`` needs k0: from ``C`` times the fitted ``k0/C`` when C is given, else profiled
over a grid of k0.

Fit and interval
----------------
For every member ``theta`` and every trial ``P`` on a grid of ``log(P/max CoA)`` (steps of
0.3 % up to twice the largest CoA, 2 % beyond, up to ``p_span`` times it), k0 is solved in
closed form (weighted least squares) and ``chi2(P, theta) = sum((y_i - k0*s_i)^2/v_i)`` with

    v_i = se_i^2 + (model_rel*y_i)^2 + (k0*s'(u_i)/P*se_CoA_i)^2,

the middle term the model's own uncertainty: a relative floor on every point, calibrated so
that noise-free records of laws outside the family do not give narrow intervals that miss
(``benchmarks/friction_coverage.py``; the value is :data:`MODEL_REL_ERROR`). The 95 % interval
of P is the union over the whole family of the profile-likelihood range,
``{P : min_theta chi2(P, theta) <= chi2_min + 3.84*max(1, chi2_min/dof)}`` (Wilks 1938;
widened when the points scatter more than their errors, never narrowed), each end one grid
step outward, its hull taken as the interval. The members no rail law needs (knee, p = 1
tail) may only widen it: unless they beat the others by ``NEW_MEMBER_MARGIN`` in chi2, the
others' minimum is ``chi2_min`` and gives the estimate (``frictiongrid.reference_chi2``).
P is *determined* when that hull is closed inside the grid and its half width
``(high - low)/2`` is at most ``max_rel_half_width`` of the estimate; otherwise the lower
bound (the set's lowest point, never below the largest CoA: adhesion cannot exceed what is
available) is what is known, with the interval when it is closed, and the probe depth (the
deepest utilisation of a further point on the best-fitting curve) that would determine it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from torquemod.analysis.creeplaws import (
    N_U,
    R_GRID,
    R_GRID_FALLING,
    family_tables,
    neighbour_pairs,
)
from torquemod.analysis.frictiongrid import (
    CHI2_95,
    _coarse_to_fine,
    new_pairs,
    reference_chi2,
    row_minima,
)
from torquemod.errors import InputError

__all__ = ["CHI2_95", "MAX_REL_HALF_WIDTH", "MODEL_REL_ERROR", "AdhesionFit",
           "fit_available_adhesion", "fit_available_adhesion_from_phase"]

#: chi-square quantile of two degrees of freedom at 95 %
CHI2_95_2 = 5.991464547107979
#: relative model error per point (the family is not every rail): calibrated by cross-fitting
#: laws outside the family (``benchmarks/friction_coverage.py``, docs/friction.md)
MODEL_REL_ERROR = 0.01
#: relative model error of each point's utilisation (the curves of real rails may sit a
#: little left or right of every member: an error in u, weighted by the slope ds/du, which
#: grows near the peak where a law's shape is least certain); calibrated with
#: MODEL_REL_ERROR
MODEL_REL_COA = 0.01
#: the largest B of Polach's falling friction [s/m] (Polach 2005: 0.2 wet, 0.6 dry; a fit
#: to the Engel-Beck-Alders locomotive curve: 0.8)
B_MAX_S_M = 1.0
#: the widest half interval, as a fraction of the estimate, that counts as determined (the
#: trade-off against the share determined and the error: ``benchmarks/friction_coverage.py``)
MAX_REL_HALF_WIDTH = 0.10
#: the probe depths (utilisation of the deepest point) tried when P is not determined
PROBE_DEPTHS = (0.7, 0.8, 0.86, 0.9, 0.95)


def _p_grid(c_max: float, p_span: float, dz: float = 0.015, z_fine: float = 0.02,
            n_near: int = 40) -> np.ndarray:
    """Trial P on a grid uniform in ``z = ln(P/c_max - 1)`` from ``z_fine`` to
    ``p_span - 1``: the relative step ``(1 - c_max/P)*dz`` follows how sharply the points
    near the peak fix P (the slope there changes by ~dz/(1 - u) per step); below
    ``z_fine`` (the top point within 2 % of the peak) ``n_near`` steps, geometric in
    ``P/c_max - 1`` down to 1e-4, keep the relative step under 0.3 %."""
    near = np.geomspace(1e-4, z_fine, n_near + 1)[:-1]
    z = np.arange(np.log(z_fine), np.log(max(p_span, 1.5) - 1.0) + dz, dz)
    return c_max * (1.0 + np.r_[near, np.exp(z)])


@dataclass(frozen=True)
class AdhesionFit:
    """The available adhesion from one progression of creep coefficients (or phases).

    All CoA-like values are dimensionless.

    Attributes
    ----------
    estimate : float
        The best-fitting available adhesion P [-] (reported as the value only when
        ``determined``).
    low : float
        Lower end of its 95 % interval [-] (the lower bound when the interval is open).
    high : float
        Upper end of its 95 % interval [-]; NaN when open above.
    lower_bound : float
        What is known for certain: the interval's lowest point, never below the largest CoA
        [-] (adhesion cannot exceed what is available).
    determined : bool
        The interval is closed and its half width is at most ``max_rel_half_width`` of P.
    closed : bool
        The interval is one closed interval inside the grid.
    mu0 : float
        The best law's friction coefficient P/F_pk [-].
    mu0_low, mu0_high : float
        Its range over the fits within the level [-].
    mu0_identified : bool
        That range is closed and as narrow as P's rule asks.
    probe_depth : float
        Utilisation a further point must reach to determine P [-]; NaN when determined or
        when even 95 % would not.
    law : str
        The best member's law (:data:`~torquemod.analysis.creeplaws.FAMILY`).
    params : tuple of float
        Its parameters [-] (:class:`~torquemod.analysis.creeplaws.Member`).
    k0 : float
        The fitted initial creep coefficient in the units of the observations [-] (``k0/C``
        from phases without C).
    chi2 : float
        Chi-square of the best fit [-] (of the rail members' when the widen-only rule applies:
        :func:`~torquemod.analysis.frictiongrid.reference_chi2`).
    dof : int
        Its degrees of freedom [-].
    chi2_scale : float
        ``max(1, chi2/dof)`` [-] when the interval is widened by the scatter, else 1.
    max_rel_half_width : float
        The rule of ``determined`` [-].
    model_rel_error : float
        The relative model error used [-].
    c_max : float
        The largest CoA of the points [-].
    p_grid : ndarray
        The trial values of P [-].
    profile : ndarray
        ``min_theta chi2(P, theta)`` on ``p_grid`` [-].
    level : float
        Its 95 % threshold ``chi2_min + 3.84*chi2_scale`` [-].
    best_s : ndarray
        The best member's s(u) = k/k0 on the tables' utilisation grid [-].

    References
    ----------
    .. [1] S.S. Wilks, "The large-sample distribution of the likelihood ratio for testing
       composite hypotheses", Ann. Math. Statist. 9(1) (1938) 60-62.
    """

    estimate: float
    low: float
    high: float
    lower_bound: float
    determined: bool
    closed: bool
    mu0: float
    mu0_low: float
    mu0_high: float
    mu0_identified: bool
    probe_depth: float
    law: str
    params: tuple
    k0: float
    chi2: float
    dof: int
    chi2_scale: float
    max_rel_half_width: float
    model_rel_error: float
    c_max: float
    p_grid: np.ndarray = field(repr=False)
    profile: np.ndarray = field(repr=False)
    level: float = math.nan
    best_s: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))

    @property
    def value(self) -> float | None:
        """The available adhesion when determined, else None."""
        return self.estimate if self.determined else None

    def creep_ratio(self, coa) -> np.ndarray:
        """``k/k0`` of the best fit at the CoA values (small-signal; NaN at or beyond P)."""
        u = np.abs(np.asarray(coa, dtype=float)) / self.estimate
        ug = np.linspace(0.0, 1.0, N_U)
        return np.where(u < 1.0, np.interp(u, ug, self.best_s), np.nan)

    def to_dict(self) -> dict:
        """The named quantities (JSON-ready, NaN as None)."""
        def f(x):
            return None if x is None or not math.isfinite(x) else float(x)
        return {
            "estimand": "available adhesion: maximum of the adhesion-creepage curve",
            "adhesion_available": f(self.value),
            "adhesion_available_estimate": f(self.estimate),
            "adhesion_available_low": f(self.low), "adhesion_available_high": f(self.high),
            "adhesion_available_lower_bound": f(self.lower_bound),
            "adhesion_available_determined": bool(self.determined),
            "adhesion_available_closed": bool(self.closed),
            "mu0": f(self.mu0) if self.mu0_identified else None,
            "mu0_low": f(self.mu0_low), "mu0_high": f(self.mu0_high),
            "mu0_identified": bool(self.mu0_identified),
            "probe_depth_needed": f(self.probe_depth),
            "best_law": self.law, "best_law_params": [float(v) for v in self.params],
            "model_rel_error": self.model_rel_error,
            "max_rel_half_width": self.max_rel_half_width,
        }


def _pairs(ratio_bounds, other_laws: bool, knee: bool = True) -> np.ndarray:
    """The neighbour pairs (:func:`torquemod.analysis.creeplaws.neighbour_pairs`) whose Polach
    members
    have kA/kS within ``ratio_bounds`` (widened to the grid values that bracket it, so that
    the pairs' mixtures cover it), and, without ``other_laws``, Polach members only."""
    pairs = neighbour_pairs()
    members = family_tables().members
    lo, hi = (float(b) for b in ratio_bounds)
    if lo <= R_GRID[0] and hi >= R_GRID[-1] and other_laws and knee:
        return pairs
    lo_g = R_GRID[max(np.searchsorted(R_GRID, lo * (1 + 1e-9), side="right") - 1, 0)]
    hi_g = R_GRID[min(np.searchsorted(R_GRID, hi * (1 - 1e-9)), R_GRID.size - 1)]

    def keep(m):
        if m.law in ("polach", "polach_falling"):
            r = m.params[0]
            lo_m = lo_g if m.law == "polach" else R_GRID_FALLING[max(np.searchsorted(
                R_GRID_FALLING, lo * (1 + 1e-9), side="right") - 1, 0)]
            hi_m = hi_g if m.law == "polach" else R_GRID_FALLING[min(np.searchsorted(
                R_GRID_FALLING, hi * (1 - 1e-9)), R_GRID_FALLING.size - 1)]
            return lo_m * (1 - 1e-9) <= r <= hi_m * (1 + 1e-9)
        if m.law == "knee":
            return other_laws and knee
        return other_laws

    ok = np.array([keep(m) for m in members])
    return pairs[ok[pairs[:, 0]] & ok[pairs[:, 1]]]


def _as_points(name: str, x, n: int | None) -> np.ndarray:
    arr = np.asarray(x, dtype=float).ravel()
    if n is not None and arr.size != n:
        raise InputError(f"{name} has {arr.size} values, expected {n} (one per point)",
                         hint="give one value per torque step")
    return arr


def fit_available_adhesion(coa, k, k_se, *, coa_se=None, swing=None, constant=1.0,
                           model_rel_error: float = MODEL_REL_ERROR,
                           model_rel_coa: float = MODEL_REL_COA,
                           max_rel_half_width: float = MAX_REL_HALF_WIDTH, p_span: float = 20.0,
                           scale_by_chi2: bool = True, probe: bool = True,
                           min_points: int = 4, ratio_bounds: tuple = (0.3, 7.0),
                           other_laws: bool = True, speed_m_s: float | None = None,
                           knee: bool = True, constant_rel_se: float = 0.0
                           ) -> AdhesionFit | None:
    """The available adhesion P from creep coefficients measured at utilised adhesions.

    The one estimator for the rig (phases, :func:`fit_available_adhesion_from_phase`), the
    train and the sweep (module docstring).

    Parameters
    ----------
    coa : array_like
        Utilised adhesion CoA of each point [-].
    k : array_like
        Creep coefficient dCoA/dxi of each point [-], or any fixed multiple of it (the phase
        fit passes ``cot(phi) = k/C``).
    k_se : array_like
        Standard errors of ``k`` [-].
    swing : array_like or None
        Creepage swing amplitude of the modulation per point [-]; None: small-signal slopes.
    constant : float or None
        The factor C with ``k = C*(observation)`` [-]: 1 for creep coefficients; None when
        unknown (k0 is then profiled, used only to size a swing). Default 1.
    coa_se : array_like or None
        Standard errors of ``coa`` [-]; None: 0 (a relative floor ``model_rel_coa`` is added).
    model_rel_error : float
        Relative model error per point [-], calibrated by cross-fitting laws outside the
        family (``benchmarks/friction_coverage.py``). Default :data:`MODEL_REL_ERROR`.
    model_rel_coa : float
        Relative error of each point's utilisation [-]. Default :data:`MODEL_REL_COA`.
    max_rel_half_width : float
        Widest half interval, relative to P, that counts as determined [-]. Default
        :data:`MAX_REL_HALF_WIDTH`.
    p_span : float
        Largest P tried, as a multiple of the largest CoA [-]. Default 20.
    scale_by_chi2 : bool
        Widen the interval by ``chi2/dof`` when it exceeds 1. Default True.
    probe : bool
        Also find the probe depth that would determine P when it is not. Default True.
    min_points : int
        Fewest usable points [-]. Default 4.
    ratio_bounds : tuple of float
        Range of kA/kS of the Polach members [-]. Default (0.3, 7.0).
    other_laws : bool
        Also the non-Polach members (Burckhardt, saturating laws). Default True.
    speed_m_s : float or None
        Rolling speed V [m/s]; with it (and k0 in absolute units) a falling-friction member
        counts only where its fall ``exp(-B*xi*V)`` needs B <= :data:`B_MAX_S_M` (at a rig's
        few km/h the slip velocity stays far too small for friction to fall much).
    knee : bool
        Also the members linear up to a knee (Dugoff's law, kappa 0.3-0.7). Default True;
        False leaves them out (the family of earlier versions, less the p = 1 tail).
    constant_rel_se : float
        Relative standard error of ``constant`` when it was measured rather than known (C
        from the amplitudes) [-]: the bound on falling friction is then applied at C's lower
        95 % end (a smaller k0 asks a smaller B, so no member that a C within its uncertainty
        allows is left out). Default 0.

    Returns
    -------
    AdhesionFit or None
        The fit; None when fewer than ``min_points`` usable points remain.

    Raises
    ------
    InputError
        Arrays of different lengths.

    Notes
    -----
    For every member theta and trial P, ``k(CoA) = k0*s(CoA/P; theta)`` with k0 in closed
    form and ``chi2(P, theta) = sum((y_i - k0*s_i)^2/v_i)``,
    ``v_i = se_i^2 + (model_rel*y_i)^2 + (k0*s'(u_i)/P*se_CoA_i)^2``. The 95 % interval is
    the profile-likelihood set ``{P : min_theta chi2 <= chi2_min + 3.84*max(1, chi2_min/dof)}``
    [1]_ over the whole family (Polach [2]_, Burckhardt [3]_, saturating laws).

    References
    ----------
    .. [1] S.S. Wilks, "The large-sample distribution of the likelihood ratio for testing
       composite hypotheses", Ann. Math. Statist. 9(1) (1938) 60-62.
    .. [2] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (8), (9).
    .. [3] M. Burckhardt, "Fahrwerktechnik: Radschlupf-Regelsysteme", Vogel, Würzburg 1993.
    """
    coa = np.abs(_as_points("coa", coa, None))
    n = coa.size
    y = _as_points("k", k, n)
    se = np.abs(_as_points("k_se", k_se, n))
    c_se = np.zeros(n) if coa_se is None else np.abs(_as_points("coa_se", coa_se, n))
    amp = np.zeros(n) if swing is None else np.abs(_as_points("swing", swing, n))
    c_se = np.where(np.isfinite(c_se), c_se, 0.0)
    amp = np.where(np.isfinite(amp), amp, 0.0)
    ok = np.isfinite(coa) & (coa > 0) & np.isfinite(y) & (y > 0) & np.isfinite(se) & (se > 0)
    if ok.sum() < min_points:
        return None
    coa, y, se, c_se, amp = coa[ok], y[ok], se[ok], c_se[ok], amp[ok]
    c_se = np.hypot(c_se, model_rel_coa * coa)
    c_max = float(coa.max())
    tabs = family_tables(bool(np.any(amp > 0)))
    pairs = _pairs(ratio_bounds, other_laws, knee)
    p_grid = _p_grid(c_max, p_span)
    rail = ~new_pairs(tabs, pairs)
    with np.errstate(over="ignore", invalid="ignore"):
        bmax_v = _b_bound(speed_m_s, constant_rel_se)
        cols, (chi, amps, fracs) = _coarse_to_fine(tabs, pairs, coa, y, se, c_se, amp,
                                                   p_grid, constant, model_rel_error, bmax_v,
                                                   rail=rail)
    p_grid = p_grid[cols]
    return _summarise(tabs, pairs, rail, chi, amps, fracs, p_grid, coa, y, se, c_max,
                      model_rel_error, max_rel_half_width, scale_by_chi2, probe, c_se, amp,
                      constant, p_span, ratio_bounds, other_laws, speed_m_s, knee,
                      constant_rel_se)


def _b_bound(speed_m_s, constant_rel_se: float = 0.0) -> float:
    """``B_max*V`` [-] passed to the kernel (0: no bound): with a measured C of relative
    standard error ``constant_rel_se`` the bound is taken at C's lower 95 % end, i.e. the
    allowed ``B*V`` grows by ``1/(1 - 1.96*rel_se)`` (no bound once that reaches 2)."""
    if not speed_m_s:
        return 0.0
    shrink = 1.0 - 1.96 * max(float(constant_rel_se), 0.0)
    if shrink <= 0.5:
        return 0.0
    return B_MAX_S_M * float(speed_m_s) / shrink


def _vertex(profile: np.ndarray, j: int) -> float:
    """Offset [grid steps, within +-0.5] of the parabola's vertex through profile[j-1:j+2]."""
    if not 0 < j < profile.size - 1:
        return 0.0
    a, b, c = (float(v) for v in profile[j - 1:j + 2])
    curv = a - 2.0 * b + c
    if not (math.isfinite(curv) and curv > 0.0):
        return 0.0
    return min(0.5, max(-0.5, 0.5 * (a - c) / curv))


def _summarise(tabs, pairs, rail, chi, amps, fracs, p_grid, coa, y, se, c_max, model_rel,
               max_rel, scale_by_chi2, probe, c_se, amp, constant, p_span, ratio_bounds,
               other_laws, speed_m_s, knee=True, constant_rel_se=0.0) -> AdhesionFit | None:
    # the grids trial-P-major (rows: trial P; C-contiguous as _coarse_to_fine returns them),
    # each rule on the rows it needs; the values are those of the (K, m) grids
    chi_t = chi.T
    prof = chi_t.min(axis=1)
    if not np.isfinite(prof).any():
        return None
    # the widen-only rule (frictiongrid.reference_chi2): unless the members no rail law needs
    # beat the others by NEW_MEMBER_MARGIN, the others alone give the level and the estimate
    prof_rail = row_minima(chi_t, rail)
    chi_min, rail_only = reference_chi2(float(np.nanmin(prof)), float(np.nanmin(prof_rail)))
    in_set = rail if rail_only else np.ones(rail.size, bool)
    prof_set = prof_rail if rail_only else prof
    j = int(np.nanargmin(prof_set))
    i = int(np.argmin(np.where(in_set, chi_t[j], np.inf)))
    dof = max(coa.size - 3, 1)
    scale = max(1.0, chi_min / dof) if scale_by_chi2 else 1.0
    # the estimate: the constant-friction laws are nested in the falling-friction ones (two
    # more parameters, A and B); unless the fall improves chi2 by more than the 95 % point
    # of chi2 with two degrees of freedom (the likelihood-ratio test), the best
    # constant-friction fit gives the estimate. The interval is the whole family's.
    falling = tabs.falling[pairs[:, 0]] | tabs.falling[pairs[:, 1]]
    keep_c = in_set & ~falling
    prof_c = row_minima(chi_t, keep_c)
    if np.isfinite(prof_c).any() and float(prof_c.min()) <= chi_min + CHI2_95_2 * scale:
        j = int(np.argmin(prof_c))
        i = int(np.argmin(np.where(keep_c, chi_t[j], np.inf)))
        est_prof = prof_c
    else:
        est_prof = prof_set
    level = chi_min + CHI2_95 * scale
    inside_cells = chi_t <= level
    inside = inside_cells.any(axis=1)
    idx = np.flatnonzero(inside)
    lo_i, hi_i = int(idx[0]), int(idx[-1])
    open_low = lo_i == 0
    open_high = hi_i == p_grid.size - 1
    low = c_max if open_low else float(p_grid[lo_i - 1])
    high = math.nan if open_high else float(p_grid[hi_i + 1])
    step = float(p_grid[min(j + 1, p_grid.size - 1)] / p_grid[j])
    est = float(p_grid[j]) * step ** _vertex(est_prof, j)
    # the interval is the hull of the set: gaps inside it come from the family's grid (a
    # smaller set would claim a precision that the grid, not the data, produced)
    closed = not open_low and not open_high
    determined = bool(closed and 0.5 * (high - low) <= max_rel * est)
    lower = max(c_max, low)
    # mu0 over the cells within the level: P/F_pk of each (mixed) member
    inv_pk = 1.0 / tabs.f_peak
    ia, ib = pairs[:, 0], pairs[:, 1]
    rows, cells = np.nonzero(inside_cells)
    mix = np.nan_to_num(fracs.T[rows, cells])
    m0_in = p_grid[rows] * ((1.0 - mix) * inv_pk[ia[cells]] + mix * inv_pk[ib[cells]])
    mu0_low, mu0_high = float(m0_in.min()), float(m0_in.max())
    f_ij = float(np.nan_to_num(fracs[i, j]))
    mu0 = est * ((1.0 - f_ij) * inv_pk[ia[i]] + f_ij * inv_pk[ib[i]])
    mu0_ok = bool(closed and 0.5 * (mu0_high - mu0_low) <= max_rel * mu0)
    ma, mb = tabs.members[ia[i]], tabs.members[ib[i]]
    params = tuple((1.0 - f_ij) * va + f_ij * vb for va, vb in zip(ma.params, mb.params,
                                                                    strict=True))
    best_s = (1.0 - f_ij) * tabs.s[ia[i]] + f_ij * tabs.s[ib[i]]
    k0 = float(amps[i, j])
    depth = math.nan
    if probe and not determined:
        depth = _probe_depth(best_s, est, k0, coa, y, se, c_se, amp, constant, model_rel,
                             max_rel, p_span, ratio_bounds, other_laws, speed_m_s, knee,
                             constant_rel_se)
    return AdhesionFit(
        estimate=est, low=low, high=high, lower_bound=lower, determined=determined,
        closed=closed, mu0=mu0, mu0_low=mu0_low, mu0_high=mu0_high, mu0_identified=mu0_ok,
        probe_depth=depth, law=ma.law, params=params, k0=k0, chi2=chi_min,
        dof=dof, chi2_scale=scale, max_rel_half_width=max_rel, model_rel_error=model_rel,
        c_max=c_max, p_grid=p_grid, profile=prof, level=level, best_s=best_s)


def _probe_depth(best_s, est, k0, coa, y, se, c_se, amp, constant, model_rel, max_rel,
                 p_span, ratio_bounds, other_laws, speed_m_s, knee=True,
                 constant_rel_se=0.0) -> float:
    """The smallest of :data:`PROBE_DEPTHS` beyond the present one at which one more point on
    the best-fitting curve (its relative error the median of the present points') makes P
    determined; NaN when none does."""
    ug = np.linspace(0.0, 1.0, N_U)
    rel = float(np.median(se / y))
    for d in PROBE_DEPTHS:
        if d * est <= coa.max() * 1.001:
            continue
        yd = k0 * float(np.interp(d, ug, best_s))
        if not yd > 0:
            continue
        c2 = np.append(coa, d * est)
        fit = fit_available_adhesion(
            c2, np.append(y, yd), np.append(se, rel * yd), coa_se=np.append(c_se, 0.0),
            swing=np.append(amp, 0.0) if np.any(amp > 0) else None, constant=constant,
            model_rel_error=model_rel, model_rel_coa=0.0,
            max_rel_half_width=max_rel, p_span=p_span, probe=False,
            ratio_bounds=ratio_bounds, other_laws=other_laws, speed_m_s=speed_m_s,
            knee=knee, constant_rel_se=constant_rel_se)
        if fit is not None and fit.determined:
            return float(d)
    return math.nan


def fit_available_adhesion_from_phase(coa, phase_deg, phase_se_deg, *, constant=None,
                                      creepage_swing=None, coa_se=None,
                                      model_rel_error: float = MODEL_REL_ERROR,
                                      model_rel_coa: float = MODEL_REL_COA,
                                      max_rel_half_width: float = MAX_REL_HALF_WIDTH,
                                      scale_by_chi2: bool = True, probe: bool = True,
                                      ratio_bounds: tuple = (0.3, 7.0),
                                      speed_m_s: float | None = None, knee: bool = True,
                                      constant_rel_se: float = 0.0) -> AdhesionFit | None:
    """P from the phases of the wheel speed behind the torque.

    ``tan(phi) = C/k`` (V-Track paper Eq. 1): :func:`fit_available_adhesion` on
    ``y = cot(phi) = k/C`` with standard error ``se_phi/sin^2(phi)``. Steps with a phase
    outside (0, 90) deg are left out.

    Parameters
    ----------
    coa : array_like
        Utilised adhesion CoA per step [-].
    phase_deg : array_like
        Lag of the wheel speed behind the torque per step [deg].
    phase_se_deg : array_like
        Standard errors of ``phase_deg`` [deg].
    constant : float or None
        C = Omega*J*V/(R^2*N) [-] when known (needed only to size the creepage swing and to
        bound falling friction; without it k0 is profiled). Default None.
    creepage_swing : array_like or None
        Creepage swing amplitude per step [-]. Default None.
    coa_se : array_like or None
        Standard errors of ``coa`` [-]; None: 0 (a relative floor ``model_rel_coa`` is added).
    model_rel_error : float
        Relative model error per point [-], calibrated by cross-fitting laws outside the
        family (``benchmarks/friction_coverage.py``). Default :data:`MODEL_REL_ERROR`.
    model_rel_coa : float
        Relative error of each point's utilisation [-]. Default :data:`MODEL_REL_COA`.
    max_rel_half_width : float
        Widest half interval, relative to P, that counts as determined [-]. Default
        :data:`MAX_REL_HALF_WIDTH`.
    scale_by_chi2 : bool
        Widen the interval by ``chi2/dof`` when it exceeds 1. Default True.
    probe : bool
        Also the probe depth that would determine P. Default True.
    ratio_bounds : tuple of float
        Range of kA/kS of the Polach members [-]. Default (0.3, 7.0).
    speed_m_s : float or None
        Rolling speed [m/s]. Default None.
    knee : bool
        Also the knee members. Default True.
    constant_rel_se : float
        Relative standard error of a measured C [-] (e.g. from the amplitudes,
        :func:`torquemod.analysis.phasefit.constant_from_amplitudes`); the falling-friction
        bound is applied at its lower 95 % end. Default 0.

    Returns
    -------
    AdhesionFit or None
        The fit (``k0`` is k0/C without C); None when fewer than four usable steps remain.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    .. [2] S.S. Wilks, "The large-sample distribution of the likelihood ratio for testing
       composite hypotheses", Ann. Math. Statist. 9(1) (1938) 60-62.
    """
    ph = np.radians(np.asarray(phase_deg, dtype=float).ravel())
    se = np.radians(np.abs(np.asarray(phase_se_deg, dtype=float).ravel()))
    with np.errstate(invalid="ignore", divide="ignore"):
        y = np.where((ph > 0) & (ph < 0.5 * np.pi), 1.0 / np.tan(ph), np.nan)
        y_se = se / np.sin(ph) ** 2
    return fit_available_adhesion(coa, y, y_se, coa_se=coa_se, swing=creepage_swing,
                                  constant=constant, model_rel_error=model_rel_error,
                                  model_rel_coa=model_rel_coa,
                                  max_rel_half_width=max_rel_half_width,
                                  scale_by_chi2=scale_by_chi2, probe=probe,
                                  ratio_bounds=ratio_bounds, speed_m_s=speed_m_s,
                                  knee=knee, constant_rel_se=constant_rel_se)
