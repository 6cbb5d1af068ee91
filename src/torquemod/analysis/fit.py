"""Least-squares fit of Polach's creep-force model to measured creep-curve points.

The model is the lumped form of :func:`torquemod.analysis.contact.polach.adhesion_curve`
(Polach 2005, Eqs. 3 and 8, "P05" below)::

    CoA(xi) = mu * (2/pi) * [kA*eps/(1 + (kA*eps)^2) + arctan(kS*eps)],   eps = s*|xi|/mu

with ``s = pi*G*a*b*c11/(4*Q)`` [-] lumping the contact geometry. CoA is a magnitude (Eq. 4 of
the V-Track paper), so the model uses ``|xi|``.

Identifiability
---------------
``kA`` and ``kS`` enter only as the products ``kA*s`` and ``kS*s``; with ``s`` unknown only
``mu``, ``kA*s`` and ``kS*s`` are identifiable. :func:`fit_polach` therefore always fits
``(mu, kA*s, kS*s)``. When the caller knows ``s`` (``stiffness=``, e.g. from a Hertz/Kalker
calculation of the rig) the reported parameters are ``mu, k_a, k_s`` (products divided by
``s``, standard errors likewise); otherwise they are reported as ``k_a_stiffness`` and
``k_s_stiffness``. The initial slope ``2*(kA*s + kS*s)/pi`` is always identifiable.

When is mu determined?
----------------------
If the points lie on the near-linear part of the curve, the data fix the initial slope but not
the friction level: the optimiser drifts to the upper bound of ``mu`` or returns a value with a
huge standard error. ``mu_determined`` is True only when all of these hold (thresholds are
keyword options of :func:`fit_polach`):

* the optimiser converged and the covariance has full rank,
* ``mu`` is not at (within 1 % of) its upper bound,
* ``mu_stderr / mu <= max_rel_stderr`` (default 0.10),
* the largest measured CoA reaches ``min_saturation_fraction * mu`` (default 0.5),
* the fitted curve itself reaches ``min_peak_fraction * mu`` (default 0.9) for creepages up to
  ``creepage_limit`` (default 0.1). With ``kS << kA`` Polach's curve has a hump whose maximum
  lies well below ``mu``, or it creeps up to ``mu`` only at creepages no wheel reaches; ``mu``
  is then a shape parameter, not the saturation level the method needs (``Ts = mu*N*Rw``).
  This happens when the points bend more sharply than the constant-friction model can (e.g.
  friction falling with slip velocity). The curve's maximum over that range is always reported
  as ``curve_peak_coa``.

Otherwise ``mu`` is None, ``mu_lower_bound`` is the largest measured CoA (adhesion cannot
exceed friction) and a warning says so.

Modulation swing
--------------------------
The torque modulation swings each step's creepage sinusoidally, ``xi(t) = xi_m + a*cos(Omega*t)``
with amplitude ``a`` [-] (``steps.csv`` ``creepage_swing``, ``a = delta_omega*R/V``). Where the
curve bends, the step's mean CoA is the period average, not the static value::

    CoA_mean(xi_m, a) = (1/2pi) * integral_0^2pi f(xi_m + a*cos(theta)) dtheta
                      ~ f(xi_m) + (a^2/4)*f''(xi_m)                       (f'' < 0: below)

with ``f(x) = sign(x)*CoA(|x|)`` the signed static curve (a swing past zero creepage pulls
the mean towards zero). Assumptions: the creepage swings sinusoidally and the curve is
quasi-static (the contact follows the 2 Hz swing without memory). The static curve fitted to
these means misplaces mu by a few per cent (noise-free V-Track-like points, swings 3e-4 at
low torque to 5e-3 near saturation, tests/analysis/test_fit_swing.py: +2.6 % wet, +5.4 % dry).
With ``creepage_swing=`` :func:`fit_polach` fits ``CoA_mean``
(:func:`torquemod.analysis.contact.polach.swing_average`, 32-node trapezoidal rule) in every stage:
the starting points' costs, the effective-variance slope (``d CoA_mean/d xi_m``), the
profile likelihood of mu, the residuals, and the velocity-dependent model (slip velocity
``|xi_m + a*cos|*V``). Parameters, ``PolachFit.curve``/``slope`` and the saturation checks
(``curve_peak_coa``) stay those of the static curve, which is what mu describes;
``PolachFit.mean_curve(xi, swing)`` is the fitted model. With lateral CoA only the
longitudinal part is averaged: ``sqrt(CoA_mean^2 + lateral^2)``. NaN swing counts as 0; an
all-zero swing is exactly the plain fit. The swing used is in ``options`` and ``to_dict()``.

Weights
-------
Residuals are divided by the standard error of each point, ``sigma_i``. With creepage errors
the effective-variance method is used: ``sigma_i^2 = se_CoA^2 + (k_i*se_xi)^2`` with ``k_i``
the slope of a first unweighted-in-xi pass. Every sigma is floored at
``max(sigma_floor, 0.1*median(sigma))`` so that one lucky point with a tiny spread cannot
dominate. The covariance is ``(J^T J)^-1 * max(1, chi2_red)`` (conservative: scaled up when the
scatter exceeds the stated errors, never scaled down).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from torquemod.analysis.polachcurve import (
    _mean_slope,
    longitudinal_mean,
    polach_coa,
)
from torquemod.analysis.polachfitmodel import FitModel
from torquemod.analysis.polachfitresult import PolachFit
from torquemod.errors import InputError, ProcessingError

__all__ = ["MU_BOUNDS", "fit_polach"]

#: Bounds of the friction coefficient in the fit [-].
MU_BOUNDS: tuple[float, float] = (1e-3, 2.0)
#: Upper bound of B [s/m] in the velocity-dependent fit.
B_MAX_S_M = 50.0


def _clean(name, x, n=None):
    if x is None:
        return None
    arr = np.asarray(x, dtype=float).ravel()
    if n is not None and arr.size != n:
        raise InputError(f"{name} has {arr.size} values, expected {n}")
    return arr


def _fmt_interval(interval) -> str:
    lo, hi = interval
    return f"{'open' if lo is None else f'{lo:.4g}'} .. {'open' if hi is None else f'{hi:.4g}'}"


try:  # numpy's LAPACK solve without np.linalg.solve's checks (a singular system gives NaN)
    from numpy.linalg import _umath_linalg

    _SOLVE1 = _umath_linalg.solve1
except (ImportError, AttributeError):  # pragma: no cover - other numpy versions
    _SOLVE1 = None


def _solve(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """``np.linalg.solve(a, b)`` for a square float64 ``a`` and vector ``b`` (the same LAPACK
    gesv), NaN-filled instead of raising when ``a`` is singular; None where the fallback
    ``np.linalg.solve`` raises."""
    if _SOLVE1 is not None:
        with np.errstate(all="ignore"):
            return _SOLVE1(a, b, signature="dd->d")
    try:
        return np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        return None


def _lm_lower_bounded(resid, jac, x0, lo, *args, max_iter: int = 100,
                      rtol: float = 1e-12) -> tuple[np.ndarray, float] | None:
    """Minimise ``0.5*|resid(x, *args)|^2`` subject to ``x >= lo`` by Levenberg-Marquardt
    steps (Marquardt's diagonal scaling) on the parameters not held at their bound, a
    parameter being released when the gradient points inside (a projected active-set
    step). For the small profile problems of :func:`_profile_interval`, where scipy's
    general solver spends most of its time on its own bookkeeping. Returns ``(x, cost)``
    once the step's predicted decrease of the cost, or its actual one, is below ``rtol``
    of the cost (or no damped step lowers it: the minimum to rounding), or None when that
    does not happen within ``max_iter`` steps (the caller then uses scipy)."""
    x = np.maximum(np.asarray(x0, float), lo)
    r = resid(x, *args)
    cost = 0.5 * float(r @ r)
    lam = 1e-3
    for _ in range(max_iter):
        J = jac(x, *args)
        g = J.T @ r
        free = (x > lo) | (g < 0.0)
        if not free.any():
            return x, cost
        all_free = bool(free.all())
        Hf = J.T @ J if all_free else (J.T @ J)[np.ix_(free, free)]
        gf = g if all_free else g[free]
        d = Hf.diagonal().copy()
        d[d <= 0.0] = 1.0
        damping = np.diag(d)
        minus_gf = -gf
        for _retry in range(12):
            step = _solve(Hf + lam * damping, minus_gf)
            if step is None or not np.isfinite(step).all():
                lam *= 10.0
                continue
            if -(gf @ step) - 0.5 * (step @ Hf @ step) <= rtol * cost:
                return x, cost  # nothing left to gain (Gauss-Newton's prediction)
            if all_free:
                x_new = x + step
            else:
                x_new = x.copy()
                x_new[free] += step
            x_new = np.maximum(x_new, lo)
            r_new = resid(x_new, *args)
            cost_new = 0.5 * float(r_new @ r_new)
            if cost_new < cost:  # False for NaN
                lam = max(lam / 3.0, 1e-12)
                break
            lam *= 4.0
        else:  # no damped step lowers the cost: x is the minimum to rounding
            return x, cost
        gain = cost - cost_new
        x, r, cost = x_new, r_new, cost_new
        if gain <= rtol * cost:
            return x, cost
    return None


def _profile_interval(resid_at, theta, lo, hi, *, chi2_min: float, threshold: float,
                      mu_bounds: tuple[float, float], max_nfev: int, step: float = 0.03,
                      span: float = 0.92, jac_at="2-point") -> dict:
    """Profile likelihood of mu on a grid from exp(-span) to exp(span) times the optimum
    (0.4x to 2.5x), minimising chi2 over the other parameters at each grid value by
    continuation outwards from the optimum (``jac_at(rest, mu)``: the residuals' Jacobian
    in the other parameters, or finite differences). Returns the hulls of the sets where
    ``chi2 - chi2_min <= threshold * q`` for q = 1 (68 %) and q = 3.84 (95 %), each end None
    when the set reaches the scanned range or the bound (open), and the profile itself.
    The chi2 valley of the Polach fit is curved and can hold separate basins (mu trading
    against kS*s), which a Jacobian standard error or a walk to the first crossing misses."""
    mu_hat, rest0 = float(theta[0]), np.asarray(theta[1:], dtype=float)
    n = round(span / step)
    grid, delta = [mu_hat], [0.0]
    for direction in (-1.0, 1.0):
        rest = rest0.copy()
        for k in range(1, n + 1):
            mu_k = mu_hat * np.exp(direction * step * k)
            if not mu_bounds[0] < mu_k < mu_bounds[1]:
                break
            x0 = np.clip(rest, lo, np.where(np.isfinite(hi), hi, rest))
            got = None
            if callable(jac_at) and np.all(np.isinf(hi)):
                got = _lm_lower_bounded(resid_at, jac_at, x0, np.asarray(lo, float), mu_k)
            if got is None:  # not converged (or a bounded-above problem): scipy's trf
                r = least_squares(resid_at, x0, jac=jac_at, args=(mu_k,), bounds=(lo, hi),
                                  x_scale="jac", method="trf", max_nfev=max_nfev)
                got = r.x, float(r.cost)
            rest = got[0]
            grid.append(mu_k)
            delta.append(max(2.0 * got[1] - chi2_min, 0.0))
    order = np.argsort(grid)
    g, d = np.asarray(grid)[order], np.asarray(delta)[order]

    def crossing(i_in: int, i_out: int, level: float) -> float:
        """mu where the profile crosses ``level`` between grid points (linear)."""
        f = (level - d[i_in]) / max(d[i_out] - d[i_in], 1e-300)
        return float(g[i_in] + f * (g[i_out] - g[i_in]))

    def hull(q: float) -> list[float | None]:
        level = q * threshold
        inside = np.flatnonzero(d <= level)
        a, b = int(inside[0]), int(inside[-1])
        return [None if a == 0 else crossing(a, a - 1, level),
                None if b == g.size - 1 else crossing(b, b + 1, level)]

    return {"68": hull(1.0), "95": hull(3.84), "mu": g.tolist(), "delta_chi2": d.tolist()}


def _covariance(jac, scale):
    """``(J^T J)^-1 * scale`` via SVD; NaN-filled and ``full_rank=False`` if rank deficient."""
    _, s, vt = np.linalg.svd(jac, full_matrices=False)
    tol = np.finfo(float).eps * max(jac.shape) * (s[0] if s.size else 0.0)
    p = jac.shape[1]
    if s.size < p or np.any(s <= tol):
        return np.full((p, p), np.nan), False
    cov = (vt.T / s**2) @ vt * scale
    return cov, True


def _starts(xi, coa, n_starts, rng, velocity):
    """Deterministic grid of starting points plus random ones, internal parameters."""
    order = np.argsort(np.abs(xi))
    low = order[: max(1, len(order) // 2)]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.abs(coa[low]) / np.abs(xi[low])
    ratio = ratio[np.isfinite(ratio) & (ratio > 0)]
    k0 = float(np.median(ratio)) if ratio.size else 100.0
    sum_ks = np.pi * k0 / 2.0  # initial slope = 2*(a + s)/pi
    cmax = float(np.max(np.abs(coa)))
    grid = []
    for mf in (1.05, 1.25, 1.6, 2.5):
        for frac in (0.7, 0.4, 0.9):
            grid.append([min(mf * cmax, 0.9 * MU_BOUNDS[1]), frac * sum_ks,
                         (1 - frac) * sum_ks])
    while len(grid) < n_starts:
        frac = rng.uniform(0.05, 0.95)
        grid.append([min(cmax * rng.uniform(1.01, 3.0), 0.9 * MU_BOUNDS[1]),
                     frac * sum_ks * rng.uniform(0.5, 2.0),
                     (1 - frac) * sum_ks * rng.uniform(0.5, 2.0)])
    grid = np.array(grid[:n_starts], dtype=float)
    if velocity:
        grid = np.column_stack([grid, np.full(len(grid), 0.5), np.full(len(grid), 0.5)])
    return grid


def fit_polach(xi, coa, *, xi_std=None, coa_std=None, velocity_dependent: bool = False,
               speeds_m_s=None, stiffness: float | None = None, n_starts: int = 12,
               seed: int = 0, sigma_floor: float = 1e-4, max_rel_stderr: float = 0.10,
               min_saturation_fraction: float = 0.5, min_peak_fraction: float = 0.9,
               creepage_limit: float = 0.1, max_nfev: int = 2000,
               lateral_coa=None, creepage_swing=None) -> PolachFit:
    """Fit Polach's creep-force model to creep-curve points.

    Eqs. (3) and (8) of [1]_ (with Eq. (9) when velocity-dependent) in the lumped form of the
    module docstring, by weighted least squares from several starting points
    (``scipy.optimize.least_squares``, trust-region reflective); mu's 95 % interval from the
    profile likelihood [2]_.

    Parameters
    ----------
    xi : array_like
        Creepage per point (e.g. per torque step) [-].
    coa : array_like
        Coefficient of adhesion per point [-].
    xi_std : array_like or None
        Standard errors of ``xi`` [-] (e.g. cycle standard deviation / sqrt(n_cycles)); with
        them the effective-variance method weights the points. Default None.
    coa_std : array_like or None
        Standard errors of ``coa`` [-]; without them the fit is unweighted (sigma = 1).
        Default None.
    velocity_dependent : bool
        Also fit ``mu0, A, B`` of Eq. (9); needs ``speeds_m_s``. Default False, as in the
        V-Track paper [3]_ (low speed, low creepage).
    speeds_m_s : array_like or None
        Rolling speed V per point [m/s] (slip velocity ``|xi|*V``); needed with
        ``velocity_dependent``. Default None.
    stiffness : float or None
        Lumped contact stiffness ``s = pi*G*a*b*c11/(4*Q)`` [-]; when given, ``k_a`` and
        ``k_s`` are reported instead of the identifiable products. Default None.
    n_starts : int
        Starting points: a fixed grid, then random ones from ``seed`` [-]. Default 12.
    seed : int
        Seed of the random starting points. Default 0.
    sigma_floor : float
        Every sigma is floored at ``max(sigma_floor, 0.1*median(sigma))`` [-] so that one
        lucky point with a tiny spread cannot dominate. Default 1e-4.
    max_rel_stderr : float
        mu is determined only when ``mu_stderr/mu`` is at most this [-]. Default 0.10.
    min_saturation_fraction : float
        ... and the largest measured CoA reaches this share of mu [-]. Default 0.5.
    min_peak_fraction : float
        ... and the fitted curve reaches this share of mu for creepages up to
        ``creepage_limit`` [-]. Default 0.9.
    creepage_limit : float
        Creepage range of that check and of ``curve_peak_coa`` [-]. Default 0.1.
    max_nfev : int
        Largest number of function evaluations per start [-]. Default 2000.
    lateral_coa : array_like or None
        Measured ``|Fy|/Fz`` per point [-]. ``coa`` is then taken as Eq. (4) of [3]_,
        ``sqrt(Fx^2 + Fy^2)/Fz``, and modelled as ``sqrt(f(xi)^2 + lateral^2)`` with f the
        longitudinal Polach curve: at low torque the lateral force dominates the CoA and would
        otherwise be read as a steep creep curve. Default None.
    creepage_swing : array_like or None
        Amplitude of the sinusoidal creepage swing the torque modulation causes at each point
        [-] (``steps.csv`` ``creepage_swing``). The model is then the static curve averaged
        over the swing (:func:`torquemod.analysis.contact.polach.swing_average`), which is what
        the mean (creepage, CoA) of a modulated step measures; NaN counts as no swing.
        Default None.

    Returns
    -------
    PolachFit
        mu (None when not determined, with ``mu_lower_bound``), its standard error and 95 %
        interval, the reduction factors or their products with s, the covariance, chi2 and
        warnings.

    Raises
    ------
    InputError
        Too few points (4, or 6 velocity-dependent), non-finite values, arrays of different
        lengths, missing speeds, a stiffness that is not positive, or all CoA zero.
    ProcessingError
        No start converged.

    Notes
    -----
    ``CoA(xi) = mu*(2/pi)*[kA*eps/(1 + (kA*eps)^2) + arctan(kS*eps)]``, ``eps = s*|xi|/mu``
    [1]_; only ``mu``, ``kA*s`` and ``kS*s`` are identifiable without s. The covariance is
    ``(J^T J)^-1 * max(1, chi2_red)``.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (3), (8), (9).
    .. [2] S.S. Wilks, "The large-sample distribution of the likelihood ratio for testing
       composite hypotheses", Ann. Math. Statist. 9(1) (1938) 60-62.
    .. [3] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (4) and step 9 of
       Section 2.4.
    """
    xi = _clean("xi", xi)
    coa = _clean("coa", coa, xi.size)
    xi_std = _clean("xi_std", xi_std, xi.size)
    coa_std = _clean("coa_std", coa_std, xi.size)
    speeds = _clean("speeds_m_s", speeds_m_s, xi.size)
    lateral = _clean("lateral_coa", lateral_coa, xi.size)
    lateral = np.zeros(xi.size) if lateral is None else np.abs(np.nan_to_num(lateral))
    swing = _clean("creepage_swing", creepage_swing, xi.size)
    swing = None if swing is None or not np.any(np.nan_to_num(swing) > 0) \
        else np.abs(np.nan_to_num(swing))
    n_par = 5 if velocity_dependent else 3
    if xi.size < n_par + 1:
        raise InputError(f"the Polach fit needs at least {n_par + 1} points, got {xi.size}",
                         hint="measure more torque steps or fix parameters")
    if not (np.all(np.isfinite(xi)) and np.all(np.isfinite(coa))):
        raise InputError("creepage and CoA must be finite", hint="drop the failed steps first")
    if velocity_dependent and (speeds is None or not np.all(np.isfinite(speeds))):
        raise InputError("velocity_dependent=True needs finite speeds_m_s for every point")
    if stiffness is not None and not (stiffness > 0):
        raise InputError(f"stiffness must be positive, got {stiffness}")
    if np.max(np.abs(coa)) <= 0:
        raise InputError("all CoA values are zero; nothing to fit")

    weighted = coa_std is not None
    if weighted:
        sig_coa = np.where(np.isfinite(coa_std), np.abs(coa_std), np.nan)
        if np.all(np.isnan(sig_coa)):
            weighted = False
    sig_xi = None if xi_std is None else np.where(np.isfinite(xi_std), np.abs(xi_std), 0.0)
    spd = speeds if velocity_dependent else None

    def floor(sig):
        sig = np.where(np.isfinite(sig), sig, np.nanmedian(sig))
        return np.maximum(sig, max(sigma_floor, 0.1 * float(np.median(sig))))

    sigma = floor(np.where(np.isnan(sig_coa), np.nanmedian(sig_coa), sig_coa)) if weighted \
        else np.ones_like(coa)

    lo = [MU_BOUNDS[0], 0.0, 0.0] + ([0.0, 0.0] if velocity_dependent else [])
    hi = [MU_BOUNDS[1], np.inf, np.inf] + ([1.0, B_MAX_S_M] if velocity_dependent else [])

    # constant friction: the model and its closed-form Jacobian at the points (FitModel);
    # velocity-dependent: the curve with the last parameters' mean CoA kept
    fast = None if velocity_dependent else FitModel(xi, swing, lateral)
    last: list = [None, None]  # the last parameters and their longitudinal mean CoA

    def mean_at(th):
        """longitudinal_mean at th, kept for the next call: the solvers ask for the
        residuals and the Jacobian at the same parameters one after the other."""
        key = np.asarray(th, dtype=float).tobytes()
        if last[0] != key:
            last[0], last[1] = key, longitudinal_mean(xi, th, swing, spd)
        return last[1]

    def model(th):
        if fast is not None:
            return fast.model(th)
        return np.hypot(mean_at(th), lateral)

    def run(sig, starts):
        def resid(th):
            return (model(th) - coa) / sig

        def jac(th):  # constant friction only (velocity-dependent: finite differences)
            return fast.jacobian(th, sig)
        results = []
        for x0 in starts:
            x0 = np.clip(x0, lo, np.where(np.isfinite(hi), hi, x0))
            try:
                r = least_squares(resid, x0, jac="2-point" if velocity_dependent else jac,
                                  bounds=(lo, hi), x_scale="jac", method="trf",
                                  max_nfev=max_nfev, xtol=1e-12, ftol=1e-12, gtol=1e-12)
            except (ValueError, FloatingPointError) as exc:  # pragma: no cover - defensive
                results.append((np.inf, None, str(exc), x0))
                continue
            results.append((float(r.cost) if r.status > 0 else np.inf, r, r.message, x0))
        return results

    rng = np.random.default_rng(seed)
    starts = _starts(xi, coa, n_starts, rng, velocity_dependent)
    results = run(sigma, starts)
    best = min(results, key=lambda t: t[0])
    if best[1] is None or not np.isfinite(best[0]):
        raise ProcessingError(f"the Polach fit did not converge from any of {len(starts)} "
                              f"starting points (last message: {results[-1][2]})")
    if weighted and sig_xi is not None and np.any(sig_xi > 0):
        # effective variance with the slope of the first pass, then refit from its solution
        f = longitudinal_mean(xi, best[1].x, swing, spd)
        k = _mean_slope(xi, best[1].x, swing, spd) * np.abs(f) / np.maximum(
            np.hypot(f, lateral), 1e-300)
        sigma = floor(np.sqrt(sigma**2 + (k * sig_xi) ** 2))
        results2 = run(sigma, [best[1].x, *starts[:3]])
        best = min(results2, key=lambda t: t[0])
        results = results2 + results

    res = best[1]
    theta = res.x.copy()
    wres = res.fun
    n = xi.size
    dof = n - n_par
    chi2 = float(np.sum(wres**2))
    red = chi2 / dof if dof > 0 else np.nan
    scale = max(1.0, red) if weighted else (red if np.isfinite(red) else np.nan)
    cov_int, full_rank = _covariance(res.jac, scale)

    # reported parameters: products, or kA, kS when the stiffness is given
    names = ["mu", "k_a_stiffness", "k_s_stiffness"]
    conv = np.ones(n_par)
    if stiffness is not None:
        names = ["mu", "k_a", "k_s"]
        conv[1:3] = 1.0 / stiffness
    if velocity_dependent:
        names += ["a_ratio", "b_s_m"]
    values = theta * conv
    cov = cov_int * np.outer(conv, conv)
    se = np.sqrt(np.abs(np.diag(cov)))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)

    mu_est, mu_se = float(theta[0]), float(se[0])
    # profile likelihood of mu: the valley of chi2 is curved (mu trades against kS*s), so the
    # Jacobian's local standard error can be far too small; the interval where
    # chi2_profile - chi2_min <= scale is the honest 68 % interval (Wilks)
    def with_mu(rest, mu_fixed):
        th = np.empty(len(rest) + 1)  # np.r_[mu_fixed, rest] without its index machinery
        th[0] = mu_fixed
        th[1:] = rest
        return th

    def resid_at(rest, mu_fixed):
        return (model(with_mu(rest, mu_fixed)) - coa) / sigma

    def jac_at(rest, mu_fixed):
        return fast.jacobian(with_mu(rest, mu_fixed), sigma, full=False)
    profile = _profile_interval(resid_at, theta, lo[1:], hi[1:], chi2_min=chi2,
                                threshold=scale if np.isfinite(scale) else 1.0,
                                mu_bounds=MU_BOUNDS, max_nfev=max_nfev,
                                jac_at="2-point" if velocity_dependent else jac_at)
    interval, interval95 = tuple(profile["68"]), tuple(profile["95"])
    if None not in interval:
        mu_se = max(mu_se, 0.5 * (interval[1] - interval[0]))
    else:
        mu_se = float("inf")
    cmax = float(np.max(np.abs(coa)))
    warn = []
    reasons = []
    if not full_rank:
        reasons.append("the Jacobian is rank deficient")
    if mu_est >= 0.99 * MU_BOUNDS[1]:
        reasons.append(f"mu ran to its upper bound {MU_BOUNDS[1]}")
    # determined: values more than max_rel_stderr away are excluded at 95 % (the profile
    # can hold separate basins within a few units of chi2; a 68 % rule or the Jacobian let
    # fits 20-70 % off pass as determined in Monte Carlo with kA = kS curves to 86 %)
    half95 = (0.5 * (interval95[1] - interval95[0]) if None not in interval95
              else float("inf"))
    if not np.isfinite(mu_se) or not half95 <= max_rel_stderr * mu_est:
        reasons.append(f"its 95 % profile-likelihood range ({_fmt_interval(interval95)}) is "
                       f"open or wider than +-{max_rel_stderr:.0%}")
    if cmax < min_saturation_fraction * mu_est:
        reasons.append(f"the highest CoA is below {min_saturation_fraction:.0%} of the "
                       "fitted mu (points on the near-linear part of the curve)")
    grid = np.concatenate([[0.0], np.geomspace(1e-7, creepage_limit, 4000)])
    spd_grid = None if not velocity_dependent else np.full(grid.size, float(np.mean(speeds)))
    peak = float(np.max(polach_coa(grid, theta, speed_m_s=spd_grid)))
    if peak < min_peak_fraction * mu_est:
        reasons.append(f"the fitted curve reaches only CoA = {peak:.3g} for creepages up to "
                       f"{creepage_limit:g}, below {min_peak_fraction:.0%} of its mu = "
                       f"{mu_est:.3g}: mu is a shape parameter far beyond the points, not the "
                       "saturation level (the points bend more sharply than the "
                       "constant-friction model allows)")
    determined = bool(res.status > 0 and not reasons)
    if not determined:
        warn.append("the creep points do not determine the friction coefficient ("
                    + "; ".join(reasons) + f"); only a lower bound mu >= {cmax:.4g} is "
                    "reported. Measure closer to saturation.")
    if determined and np.isfinite(red) and weighted and red > 10:
        warn.append(f"reduced chi2 = {red:.3g}: the scatter exceeds the stated errors; "
                    "standard errors were scaled up accordingly")

    return PolachFit(
        model="polach_velocity" if velocity_dependent else "polach",
        param_names=tuple(names),
        params={k: float(v) for k, v in zip(names, values, strict=True)},
        stderr={k: float(v) for k, v in zip(names, se, strict=True)},
        covariance=cov, correlation=corr, theta=theta,
        residuals=model(theta) - coa, weighted_residuals=wres,
        sigma=sigma, xi=xi, coa=coa, speeds_m_s=speeds,
        converged=bool(res.status > 0), status=int(res.status), message=str(res.message),
        nfev=int(res.nfev), chi2=chi2, reduced_chi2=float(red), dof=int(dof),
        mu_estimate=mu_est, mu_stderr_estimate=mu_se, mu_determined=determined,
        mu_lower_bound=cmax, curve_peak_coa=peak, mu_interval_68=interval,
        mu_interval_95=interval95, mu_profile=profile,
        stiffness=stiffness, weighted=weighted,
        starts=[{"x0": [float(v) for v in t[3]], "cost": t[0] if np.isfinite(t[0]) else None}
                for t in results],
        warnings=warn, swing=swing,
        options={"velocity_dependent": velocity_dependent, "n_starts": n_starts, "seed": seed,
                 "sigma_floor": sigma_floor, "max_rel_stderr": max_rel_stderr,
                 "min_saturation_fraction": min_saturation_fraction,
                 "min_peak_fraction": min_peak_fraction, "creepage_limit": creepage_limit,
                 "max_nfev": max_nfev, "lateral_coa": bool(np.any(lateral > 0)),
                 "creepage_swing": None if swing is None else swing.tolist(),
                 "stiffness": stiffness, "mu_bounds": list(MU_BOUNDS),
                 "covariance_scale": "max(1, reduced chi2)" if weighted else "reduced chi2"},
    )
