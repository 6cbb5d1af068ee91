"""mu from the creep-coefficient progression of a stretch of track: a tabulated profile fit
fast enough to be redone every few seconds of a live run.

Model (the Polach family of :mod:`torquemod.phasefit`, Polach 2005 Eq. 8 with ``x = kS*eps``,
``r = kA/kS``): at the utilisation ``u = CoA/mu`` the creep coefficient is ::

    k(CoA) = k0 * g(CoA/mu; r),   g(u; r) = h'(h^-1(u; r); r) / h'(0; r)

``h(x; r) = (2/pi)*(r*x/(1+(r*x)^2) + arctan(x))`` (:func:`torquemod.polachshape.polach_h`). The
on-board windows give k directly (with its standard error), so the fit is in k, not in the
phase: k0 enters linearly and is solved in closed form (weighted least squares), and g is
read from a table over (u, r) made once. The profile ``chi2_p(mu) = min_{r, k0} chi2`` is
evaluated on a grid of mu (log-spaced, from just above the largest CoA to ``mu_span`` times
it) and r (``ratio_bounds``); everything is one vectorised numpy pass (about a millisecond
for 8 points), where :func:`torquemod.phasefit.fit_mu_from_phase` searches adaptively
(tens of milliseconds) because it also handles the swing and an unknown C. Both fit the same
model; the tests check that they agree.

The family also holds, by default (``power=True``), the constant-friction saturating curves
``g(u) = 1 - u^p`` (p from 0.7 to 4: an exponential approach at p = 1, close to Burckhardt's
law, and ``mu*tanh(k0*xi/mu)`` at p = 2). Polach's curves alone fit the progression of those
laws as well, but at a mu up to twice the truth (measured on independent runs,
benchmarks/onboard_independent.py): without them a Burckhardt run at 90 % utilisation gave
a "determined" mu 30 % high whose interval missed the truth; with them the interval covers
it, and on Polach data (the twin) the results did not change.

The 95 % interval is the profile-likelihood range ``chi2_p <= min + 3.84*max(1,
chi2_min/dof)`` (Wilks, widened by the scatter, as phasefit does); mu is *determined* when the
range is closed inside the grid and its half width is at most ``max_rel_half_width`` of mu.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numba import njit

from ..phasefit import CHI2_95
from ..polachshape import polach_h, polach_h_slope


@dataclass(frozen=True)
class CreepFit:
    """One fit of the creep-coefficient progression (module docstring). ``mu`` [-]: the
    friction at the operating point ``coa_now`` (``mu0*phi``; mu0 itself is ``mu0``);
    ``mu_low``/``mu_high``: its 95 % profile interval (``mu_high`` NaN when open above);
    ``determined``: the interval is closed and narrow enough; the best shape (``law``
    "polach": ``ratio_ka_ks``, ``a_ratio``, ``beta``; "power": ``ratio_ka_ks`` holds p) and
    ``k0``; ``chi2``/``dof`` of the best fit."""

    mu: float
    mu_low: float
    mu_high: float
    determined: bool
    mu0: float
    ratio_ka_ks: float
    a_ratio: float
    beta: float
    k0: float
    chi2: float
    dof: int
    shape_u: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    shape_g: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    law: str = "polach"

    def creep_coefficient(self, coa) -> np.ndarray:
        """The fitted k at the CoA values [-] (NaN at or beyond the curve's peak)."""
        u = np.abs(np.asarray(coa, dtype=float)) / self.mu0
        return self.k0 * np.where(u < self.shape_u[-1],
                                  np.interp(u, self.shape_u, self.shape_g), np.nan)


@dataclass(frozen=True)
class _Shape:
    r: float
    a: float
    beta: float
    u: np.ndarray    # CoA/mu0 along the rising branch, increasing
    g: np.ndarray    # k/k0 there
    phi: np.ndarray  # mu/mu0 there
    law: str = "polach"


def shape_curve(r: float, a_ratio: float, beta: float, x: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, g, phi) at the reduced creepages x: ``u = phi*h(x/phi; r)``, ``g = (du/dx)/h'(0)``,
    ``phi = (1 - A)*exp(-beta*x) + A`` (Polach 2005 Eq. 9 with ``beta = B*V*mu0/K``)."""
    e = np.exp(-beta * x)
    phi = (1.0 - a_ratio) * e + a_ratio
    dphi = -(1.0 - a_ratio) * beta * e
    y = x / phi
    u = phi * polach_h(y, r)
    du = dphi * polach_h(y, r) + polach_h_slope(y, r) * (1.0 - x * dphi / phi)
    return u, du / polach_h_slope(0.0, r), phi


@lru_cache(maxsize=8)
def _shapes(r_lo: float, r_hi: float, power: bool = False) -> tuple[_Shape, ...]:
    """The family the fit searches: r on a log grid over the bounds; constant friction
    (A = 1) and falling friction with A in (0.4, 0.7) and beta in (0.03 .. 0.8); each
    curve cut at its first maximum (the rising branch, k > 0). With ``power``, also the
    saturating curves ``g(u) = 1 - u^p`` (constant friction, mu their asymptote or peak)
    for p on a log grid over :data:`POWER_BOUNDS`, as many as r values: p = 1 is an
    exponential approach (Burckhardt's law without its linear term), p = 2 is
    ``CoA = mu*tanh(k0*xi/mu)``; ``r`` then holds p."""
    rs = np.geomspace(r_lo, r_hi, N_R) if r_hi > r_lo else np.array([r_lo])
    x = np.concatenate([[0.0], np.geomspace(1e-5, 1e4, 5000)])
    out = []
    for a, beta in FALLING:
        for r in rs:
            u, g, phi = shape_curve(float(r), a, beta, x)
            stop = np.flatnonzero((np.diff(u) <= 0) | (g[1:] <= 0))
            n = stop[0] + 1 if stop.size else x.size
            out.append(_Shape(float(r), a, beta, u[:n], g[:n], phi[:n]))
    if power:
        uu = np.linspace(0.0, 1.0, 4001)[:-1]
        for p in np.geomspace(*POWER_BOUNDS, rs.size):
            out.append(_Shape(float(p), 1.0, 0.0, uu, 1.0 - uu ** p, np.ones_like(uu),
                              "power"))
    return tuple(out)


N_U = 4001  # points of the uniform utilisation grid of the lookup tables


@lru_cache(maxsize=8)
def _tables(r_lo: float, r_hi: float, power: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """g and phi of every shape of :func:`_shapes` on one uniform grid of u in [0, 1] (NaN
    beyond a shape's peak), so that one index computation serves all shapes."""
    ug = np.linspace(0.0, 1.0, N_U)
    shapes = _shapes(r_lo, r_hi, power)
    g = np.array([np.interp(ug, sh.u, sh.g, right=np.nan) for sh in shapes])
    phi = np.array([np.interp(ug, sh.u, sh.phi, right=np.nan) for sh in shapes])
    return g, phi


@njit(cache=True, nogil=True)
def _chi_table(g_tab: np.ndarray, u: np.ndarray, k: np.ndarray, w: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """For every shape s (rows of ``g_tab`` on the uniform u grid) and trial mu j (rows of
    ``u`` = CoA/mu): ``k0 = sum(w*g*k)/sum(w*g^2)`` (weighted least squares in closed form)
    and ``chi2 = sum(w*(k - k0*g)^2)`` with g linearly interpolated as :func:`_lookup` does;
    chi2 = inf where a point lies beyond the shape's peak (g NaN), u >= 1 or k0 <= 0. One
    compiled pass, no (shapes x mu x points) temporaries."""
    n_s, n_u = g_tab.shape
    n_m, n = u.shape
    chi = np.full((n_s, n_m), np.inf)
    k0s = np.full((n_s, n_m), np.nan)
    i0 = np.empty((n_m, n), np.int64)
    fr = np.empty((n_m, n))
    inside = np.ones(n_m, np.bool_)
    for j in range(n_m):
        for i in range(n):
            x = u[j, i]
            if not x < 1.0:
                inside[j] = False
            pos = min(max(x, 0.0), 1.0) * (n_u - 1)
            a = min(int(pos), n_u - 2)
            i0[j, i] = a
            fr[j, i] = pos - a
    g = np.empty(n)
    for s in range(n_s):
        row = g_tab[s]
        for j in range(n_m):
            if not inside[j]:
                continue
            swgk = 0.0
            swgg = 0.0
            for i in range(n):
                a = i0[j, i]
                gi = row[a] * (1.0 - fr[j, i]) + row[a + 1] * fr[j, i]
                g[i] = gi
                swgk += w[i] * gi * k[i]
                swgg += w[i] * gi * gi
            if not (swgg > 0.0):  # NaN (beyond the peak) or zero
                continue
            k0 = swgk / swgg
            k0s[s, j] = k0
            if not k0 > 0.0:
                continue
            c = 0.0
            for i in range(n):
                r = k[i] - k0 * g[i]
                c += w[i] * r * r
            if math.isfinite(c):
                chi[s, j] = c
    return chi, k0s


def _lookup(table: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Linear interpolation of every row of ``table`` (on the uniform u grid) at ``u``:
    shape ``table.shape[:1] + u.shape``; NaN for u >= 1."""
    pos = np.clip(u, 0.0, 1.0) * (N_U - 1)
    i0 = np.minimum(pos.astype(np.intp), N_U - 2)
    f = pos - i0
    out = table[:, i0] * (1.0 - f) + table[:, i0 + 1] * f
    return np.where(u < 1.0, out, np.nan)


#: (A, beta) pairs of the falling-friction part of the family; (1, 0) is constant friction.
FALLING = ((1.0, 0.0), *((a, b) for a in (0.4, 0.7) for b in (0.03, 0.07, 0.15, 0.3, 0.8)))
N_R = 31
#: range of the exponent p of the saturating family ``g(u) = 1 - u^p`` (``power=True``)
POWER_BOUNDS = (0.7, 4.0)


def _refine_over_r(chi: np.ndarray, n_fam: int) -> np.ndarray:
    """chi (shapes x mu, shapes ordered family-major with r innermost) with each value
    replaced by the minimum of the parabola through it and its r neighbours (in log r),
    when that minimum lies between them: the profile then does not step with the r grid
    (a grid point is at most half a step from the best r)."""
    n_r = chi.shape[0] // n_fam
    if n_r < 3:
        return chi
    c = chi.reshape(n_fam, n_r, -1)
    out = c.copy()
    a, b, d = c[:, :-2], c[:, 1:-1], c[:, 2:]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        curv = a - 2 * b + d
        t = 0.5 * (a - d) / curv
        low = b - 0.25 * (a - d) * t
        # never more than a quarter of the smaller rise to a neighbour below b (an exact
        # parabola with its vertex within 0.4 steps of b satisfies this): steep,
        # non-parabolic profiles must not invent a minimum, and chi2 stays >= 0
        low = np.maximum(low, np.maximum(b - 0.25 * np.minimum(a - b, d - b), 0.0))
    ok = np.isfinite(a) & np.isfinite(d) & np.isfinite(low) & (curv > 0) & (a >= b) & (d >= b)
    out[:, 1:-1] = np.where(ok, np.minimum(low, b), b)
    return out.reshape(chi.shape)


def _vertex_offset(profile: np.ndarray, j: int) -> float:
    """Offset [grid steps, within +-0.5] of the vertex of the parabola through
    ``profile[j-1:j+2]`` from j (0 at the ends of the grid or where the three points are
    not finite or not convex)."""
    if not 0 < j < profile.size - 1:
        return 0.0
    a, b, c = (float(v) for v in profile[j - 1:j + 2])
    curv = a - 2.0 * b + c
    if not (math.isfinite(curv) and curv > 0.0):
        return 0.0
    return min(0.5, max(-0.5, 0.5 * (a - c) / curv))


def slope_ratio(u, r: float) -> np.ndarray:
    """``g(u; r) = k/k0`` at the utilisations u = CoA/mu [-] of the constant-friction curve
    (NaN for u >= 1)."""
    x = np.concatenate([[0.0], np.geomspace(1e-5, 1e4, 5000)])
    ut, gt, _ = shape_curve(float(r), 1.0, 0.0, x)
    u = np.abs(np.asarray(u, dtype=float))
    return np.where(u < 1.0, np.interp(u, ut, gt), np.nan)


def fit_creep_progression(coa, k, k_se, *, coa_now: float | None = None,
                          ratio_bounds: tuple[float, float] = (1.0, 7.0),
                          mu_span: float = 6.0, n_mu: int = 128,
                          max_rel_half_width: float = 0.10,
                          power: bool = True) -> CreepFit | None:
    """Fit ``k_i = k0*g(CoA_i/mu0; shape)`` to creep coefficients ``k`` [-] with standard
    errors ``k_se`` at utilised adhesions ``coa`` [-] over the family of :func:`_shapes`
    (module docstring); mu is reported at the operating point ``coa_now`` [-] (default: the
    largest CoA). None when fewer than four usable points remain."""
    coa, k, k_se = (np.asarray(a, dtype=float) for a in (coa, k, k_se))
    ok = np.isfinite(coa) & np.isfinite(k) & np.isfinite(k_se) & (coa > 0) & (k > 0) & (k_se > 0)
    coa, k, w = coa[ok], k[ok], 1.0 / k_se[ok] ** 2
    if coa.size < 4:
        return None
    c_max = coa.max()
    c_now = c_max if coa_now is None or not math.isfinite(coa_now) else abs(coa_now)
    mus = c_max * np.geomspace(1.0 + 1e-4, mu_span, n_mu)
    shapes = _shapes(float(ratio_bounds[0]), float(ratio_bounds[1]), power)
    u = coa[None, :] / mus[:, None]  # (n_mu, n)
    u_now = c_now / mus
    g_tab, phi_tab = _tables(float(ratio_bounds[0]), float(ratio_bounds[1]), power)
    chi, k0s = _chi_table(g_tab, u, k, w)  # (shapes, n_mu) each
    mu_op = mus * _lookup(phi_tab, u_now)
    chi = _refine_over_r(chi, len(FALLING) + power)
    i_best, j_best = np.unravel_index(int(np.argmin(chi)), chi.shape)
    chi_min = float(chi[i_best, j_best])
    if not math.isfinite(chi_min):
        return None
    dof = coa.size - 3
    level = chi_min + CHI2_95 * max(1.0, chi_min / max(dof, 1))
    inside = chi <= level
    step = mus[1] / mus[0]  # the interval reaches one grid step beyond its last grid point
    lo = float(mu_op[inside].min()) / step
    open_high = bool(inside[:, -1].any())
    hi = math.nan if open_high else float(mu_op[inside].max()) * step
    # the best mu between grid points: the vertex of the parabola through the profile (the
    # minimum over shapes) at the best grid point and its neighbours, in log mu (at most half
    # a step away; the interval above already reaches a step beyond its grid points)
    shift = _vertex_offset(chi.min(axis=0), int(j_best))
    mu = float(mu_op[i_best, j_best]) * step ** shift
    open_low = bool(inside[:, 0].any())
    determined = (not open_high and not open_low
                  and max(mu - lo, hi - mu) <= max_rel_half_width * mu)
    sh = shapes[i_best]
    return CreepFit(mu, lo, hi, bool(determined), float(mus[j_best]) * step ** shift, sh.r,
                    sh.a, sh.beta,
                    float(k0s[i_best, j_best]), chi_min, dof, sh.u, sh.g, sh.law)
