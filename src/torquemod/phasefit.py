"""The coefficient of friction from the phase alone (issue 8): what a train, which carries no
force dynamometer, can measure.

Model
-----
The rigid-wheel relation (Eq. 1 of the V-Track paper with its constant, FACTS §1)::

    tan(phi_i) = C / k_i,      C = Omega*J*V/(R^2*N)

with ``k_i = dCoA/dxi`` the creep coefficient at step i on a Polach curve (Polach 2005, Eqs. 3
and 8, lumped as in :mod:`torquemod.fit`)::

    CoA(xi) = mu * h(K*xi/mu; r),   h(x; r) = (2/pi)*[r*x/(1 + (r*x)^2) + arctan(x)]

``K = kS*s`` [-] is the slope scale (s the lumped contact stiffness; only products with s are
identifiable) and ``r = kA/kS``. r is bounded to [1, 7]: for r >= 1 the curve never exceeds
mu (for r < 1 it overshoots mu), and up to r = 7.5 h rises monotonically (measured), so mu is
the saturation level the method needs. Polach's published dry and wet sets have r = 2.5 and
3 (FACTS §2); that Polach requires kS <= kA is recalled, not verified here. The small-signal
creep coefficient is ``k = K*h'(x)`` at ``x = h^-1(CoA/mu; r)``; with the initial slope
``k0 = K*h'(0; r)``, ``h'(0; r) = 2(r + 1)/pi``::

    tan(phi_i) = L * h'(0; r) / h'(h^-1(CoA_i/mu; r); r),      L = C/k0 = tan(phi at CoA = 0)

The fall of ``k/k0`` with the utilisation ``CoA/mu`` depends on mu and r only: without the
swing the phases fix mu whether or not C is known (C known adds nothing then); the level L is
fitted in every case.

The modulation swings the creepage by ``a_i`` [-] (``creepage_swing``); the wheel then sees the
describing-function slope (:func:`torquemod.contact.polach.swing_slope`) about the mean
creepage whose swing-averaged CoA (:func:`torquemod.contact.polach.swing_average`) is the
measured CoA_i, the swing being ``a_i*K/mu`` in units of x. The swing brings K in on its own:
with C given ``K = C/(L*h'(0; r))``; without C, k0 is a fourth parameter, fixed only by the
swing's effect (sharply near the truth, but with far basins: a costlier search), and
``C = L*k0`` is reported. Fitting swing-affected phases without the swing gives mu wrong by
up to a few per cent with a misfit (tests).

Search
------
The profile ``chi2_p(mu)`` (minimum over the other parameters) is evaluated on a grid of
``log(mu/max CoA)`` (dense near saturation, 2 % steps over utilisations 0.37-0.96, sparse up
to 50x max CoA), each point from a grid in r (and k0) with L by Gauss-Newton, then
Levenberg-Marquardt; every point is re-solved from its neighbours' solutions. Local minima
are located by the sign change of ``d chi2_p/d log mu`` (envelope theorem), because a basin
can be narrower than the grid (+-0.2 % at 86 % utilisation), and zoomed; the level crossings
are refined by batches. Everything is vectorised over mu: one batch costs about one scalar
fit.

Uncertainty and the honesty rule
--------------------------------
Residuals ``(phi_model - phi_i)/sigma_i``, ``sigma_i^2 = se_phi^2 + (dphi/dCoA*se_CoA)^2``
(effective variance with the small-signal slope of the phase curve). The 95 % interval of mu
is the profile-likelihood range ``chi2_p(mu) <= chi2_min + 3.84*max(1, chi2_min/dof)`` (Wilks;
scaled up when the phases scatter more than their standard errors, never down). mu is
*determined* only when that range is closed, no separate basin lies within the level and its
half width is at most ``max_rel_half_width`` (10 %) of the estimate; otherwise ``mu = None``
and the lower bound is where the lowest part of the range starts, never below the largest
CoA (adhesion cannot exceed friction). Coverage measured in Monte Carlo: tests and
``benchmarks/mu_from_phase.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .contact.polach import swing_average, swing_slope
from .errors import InputError
from .phasefitresult import PhaseMuFit
from .polachshape import inverse_polach_h, polach_h, polach_h_curvature, polach_h_slope

__all__ = ["CHI2_95", "K0_BOUNDS", "R_BOUNDS", "PhaseMuFit", "fit_mu_from_phase", "polach_h",
           "polach_h_curvature", "polach_h_slope"]

#: chi-square quantile of one degree of freedom at 95 %
CHI2_95 = 3.841458820694124
_Z975 = 1.959963984540054
#: bounds of r = kA/kS (Polach: kS <= kA; h is monotone, rising to 1, for r up to 7.5)
R_BOUNDS = (1.0, 7.0)
#: bounds of the initial creep coefficient k0 = K*h'(0) [-] when the swing makes K free
K0_BOUNDS = (3.0, 3000.0)


# ------------------------------------------------------------------------------------------
# the problem: data, weights and the model, vectorised over a batch of parameter sets
# ------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Data:
    coa: np.ndarray           # [-]
    phase_rad: np.ndarray     # [rad]
    se_rad: np.ndarray        # [rad]
    coa_se: np.ndarray        # [-]
    swing: np.ndarray | None  # creepage swing amplitude [-]
    constant: float | None    # C [-]


def _inverse_near(u, r, x):
    """x >= 0 with h(x; r) = u by Newton from a nearby start; bisection where that fails."""
    for _ in range(5):
        x = np.maximum(x - (polach_h(x, r) - u) / polach_h_slope(x, r), 0.0)
    bad = ~(np.abs(polach_h(x, r) - u) <= 1e-12)
    if np.any(bad & (u < 1.0)):
        x = np.where(bad, inverse_polach_h(u, r), x)
    return np.where(u < 1.0, x, np.nan)


class _Engine:
    """Profile chi2 of the phase model over a batch of mu values: starts from a grid in
    r = kA/kS (and k0), then Levenberg-Marquardt over p = (log r, log L[, log k0]). Modes:
    "small" (no swing), "tied" (swing, C given: k0 = C/L), "free" (swing, k0 fitted).
    Parameters have shape (B, 1) or (B, n_par), per-step arrays (B, n)."""

    def __init__(self, d: _Data, *, n_nodes: int = 16, n_ratio: int = 17, n_lm: int = 8,
                 ratio_bounds: tuple[float, float] = R_BOUNDS):
        self.d = d
        self.mode = ("small" if d.swing is None else
                     "tied" if d.constant is not None else "free")
        self.n_nodes, self.n_lm = n_nodes, n_lm
        lr0, lr1 = np.log(ratio_bounds[0]), np.log(ratio_bounds[1])
        self.log_r = np.linspace(lr0, lr1, n_ratio if lr1 - lr0 > 0.5 else 9)
        self.lo = np.array([lr0, -15.0, np.log(K0_BOUNDS[0])])
        self.hi = np.array([lr1, 5.0, np.log(K0_BOUNDS[1])])
        self.n_par = 3 if self.mode == "free" else 2

    # -- model ---------------------------------------------------------------------------
    def ratio(self, mu, r, x, k0, n_nodes: int | None = None):
        """``h'(0)/(k/K)`` per step: the small-signal ``h'(0)/h'(x)`` or, with the swing, the
        library's describing-function slope (:func:`torquemod.contact.polach.swing_slope`)
        about the mean point whose swing average (:func:`torquemod.contact.polach.
        swing_average`) of h is CoA/mu, the swing being ``a*k0/(h'(0)*mu)`` in units of x."""
        hp0 = 2.0 * (r + 1.0) / np.pi
        if self.mode == "small":
            return hp0 / polach_h_slope(x, r)
        a = self.d.swing * (k0 / hp0) / mu
        rn = r[..., None]
        n = n_nodes or self.n_nodes

        def curve(z):
            return polach_h(z, rn)

        def slope(z):
            return polach_h_slope(z, rn)

        u = self.d.coa / mu
        # Newton from the second-order estimate <h(x0 + a cos)> ~ h(x0) + a^2/4 h''(x0)
        x0 = x + np.minimum(-0.25 * a * a * polach_h_curvature(x, r) / polach_h_slope(x, r), a)
        for _ in range(12):
            f = swing_average(curve, x0, a, n_nodes=n) - u
            x0 = x0 - f / swing_average(slope, x0, a, n_nodes=n)
            if np.all(np.abs(f) < 1e-13):
                break
        k = swing_slope(curve, x0, a, n_nodes=n, slope=lambda z: polach_h_slope(z, r))
        return hp0 / k

    def sigma(self, x, mu, r, lev):
        """Effective standard error [rad] ``sqrt(se^2 + (dphi/dCoA*se_CoA)^2)``, the
        small-signal ``dphi/dCoA = -T/(1+T^2)*h''/(h'^2*mu)``, ``T = L*h'(0)/h'(x)``."""
        d = self.d
        if not np.any(d.coa_se > 0):
            return d.se_rad
        hp = polach_h_slope(x, r)
        t = lev * 2.0 * (r + 1.0) / np.pi / hp
        dphi = -(t / (1.0 + t * t)) * polach_h_curvature(x, r) / (hp * hp * mu)
        return np.sqrt(d.se_rad ** 2 + (dphi * d.coa_se) ** 2)

    def k0_of(self, lev, log_k):
        """The initial creep coefficient k0 [-] (None without a swing)."""
        if self.mode == "small":
            return None
        return self.d.constant / lev if self.mode == "tied" else np.exp(log_k)

    def residuals(self, mu, p, x_near):
        """Weighted residuals (B, n) at parameters p (B, n_par) = (log r, log L[, log k0])
        and the small-signal x; ``x_near`` a start for the inverse."""
        r = np.exp(p[:, :1])
        lev = np.exp(p[:, 1:2])
        x = _inverse_near(self.d.coa / mu, r, x_near)
        k0 = self.k0_of(lev, p[:, 2:3] if self.mode == "free" else None)
        rho = self.ratio(mu, r, x, k0)
        res = (np.arctan(lev * rho) - self.d.phase_rad) / self.sigma(x, mu, r, lev)
        return np.where(np.isfinite(res), res, 1e4), x

    # -- stages --------------------------------------------------------------------------
    def coarse(self, mu):
        """Starts for the least squares at each mu (m,): chi2 on a grid of r (and, when C
        is free, of k0) with L fitted by Gauss-Newton on the small-signal model (the lowest
        step, which fixes L, hardly feels the swing), then the swing model evaluated once
        (12-node rule). Returns two starts per mu: the best node and the best node at least
        two nodes away from it, each as (p (m, n_par), x (m, n))."""
        d = self.d
        m = mu.size
        free = self.mode == "free"
        log_r = self.log_r if not free else np.linspace(self.log_r[0], self.log_r[-1], 9)
        log_k = np.log(np.geomspace(*K0_BOUNDS, 25)) if free else np.zeros(1)
        q, nk = log_r.size, log_k.size
        mu_b = mu[:, None, None, None]
        r_b = np.exp(log_r)[None, :, None, None]
        x = inverse_polach_h(d.coa / mu_b, r_b)  # (m, q, 1, n)
        rs = 2.0 * (r_b + 1.0) / np.pi / polach_h_slope(x, r_b)
        j0 = int(np.argmin(d.coa))
        log_l = np.log(np.tan(d.phase_rad[j0]) / rs[..., j0:j0 + 1])
        for _ in range(6):
            lev = np.exp(log_l)
            sig = self.sigma(x, mu_b, r_b, lev)
            t = lev * rs
            res = (np.arctan(t) - d.phase_rad) / sig
            jl = t / ((1.0 + t * t) * sig)
            step = -np.sum(jl * res, -1, keepdims=True) / np.sum(jl * jl, -1, keepdims=True)
            log_l = log_l + np.clip(np.nan_to_num(step), -2.0, 2.0)
        lev = np.exp(log_l)
        rho = rs
        if self.mode != "small":
            k0 = self.k0_of(lev, log_k[None, None, :, None])
            rho = self.ratio(mu_b, r_b, x, k0, n_nodes=8)
        res = (np.arctan(lev * rho) - d.phase_rad) / self.sigma(x, mu_b, r_b, lev)
        chi = np.sum(res * res, -1).reshape(m, q * nk)
        chi = np.where(np.isfinite(chi), chi, np.inf)
        iq, ik = np.divmod(np.arange(q * nk), nk)
        best = np.argmin(chi, axis=1)
        far = ((np.abs(iq[None, :] - iq[best][:, None]) >= 2)
               | (np.abs(ik[None, :] - ik[best][:, None]) >= 2))
        second = np.argmin(np.where(far, chi, np.inf), axis=1)
        starts = []
        rows = np.arange(m)
        for cell in (best, second):
            cols = [log_r[iq[cell]], log_l[rows, iq[cell], 0, 0]]
            if free:
                cols.append(log_k[ik[cell]])
            starts.append((np.stack(cols, axis=1), x[rows, iq[cell], 0]))
        return starts

    def lm(self, mu, p, x):
        """Levenberg-Marquardt from p (B, n_par) at fixed mu (B, 1), bounds by clipping;
        returns (chi2 (B,), p, x)."""
        lo, hi = self.lo[:self.n_par], self.hi[:self.n_par]
        p = np.clip(p, lo, hi)
        res, x = self.residuals(mu, p, x)
        chi = np.sum(res * res, -1)
        lam = np.full(chi.shape, 1e-3)
        h = 1e-6
        for _ in range(self.n_lm):
            jac = np.empty((*res.shape, self.n_par))
            for i in range(self.n_par):
                pp = p.copy()
                pp[:, i] += h
                jac[..., i] = (self.residuals(mu, pp, x)[0] - res) / h
            jtj = np.einsum("bni,bnj->bij", jac, jac)
            g = np.einsum("bni,bn->bi", jac, res)
            a = jtj + lam[:, None, None] * (np.eye(self.n_par) * np.maximum(
                np.diagonal(jtj, axis1=1, axis2=2)[:, :, None], 1e-12))
            step = -np.linalg.solve(a, g[..., None])[..., 0]
            step = np.clip(np.nan_to_num(step), -1.0, 1.0)
            trial = np.clip(p + step, lo, hi)
            res_t, x_t = self.residuals(mu, trial, x)
            chi_t = np.sum(res_t * res_t, -1)
            ok = chi_t < chi
            p = np.where(ok[:, None], trial, p)
            res = np.where(ok[:, None], res_t, res)
            x = np.where(ok[:, None], x_t, x)
            chi = np.where(ok, chi_t, chi)
            lam = np.where(ok, lam * 0.2, lam * 10.0)
        return chi, p, x

    def profile(self, mu, starts=None):
        """Profile chi2 at each mu (m,), from ``starts`` (a list of (p (m, n_par), x (m, n)))
        or from the grid's (:meth:`coarse`). Returns a dict: chi2 (m,), its slope dchi2
        = d chi2/d log mu (envelope theorem: at the optimum of the others), p, x."""
        mu = np.asarray(mu, dtype=float).ravel()
        m = mu.size
        starts = self.coarse(mu) if starts is None else starts
        n_s = len(starts)
        rows = np.tile(np.arange(m), n_s)
        chi, p, x = self.lm(mu[rows][:, None], np.concatenate([q for q, _ in starts]),
                            np.concatenate([z for _, z in starts]))
        best = np.argmin(chi.reshape(n_s, m), axis=0) * m + np.arange(m)
        chi, p, x = chi[best], p[best], x[best]
        h = 1e-6
        res_h, _ = self.residuals(mu[:, None] * np.exp(h), p, x)
        return {"chi2": chi, "dchi2": (np.sum(res_h * res_h, -1) - chi) / h, "p": p, "x": x}


# ------------------------------------------------------------------------------------------
# result
# ------------------------------------------------------------------------------------------

# ------------------------------------------------------------------------------------------
# the fit
# ------------------------------------------------------------------------------------------

def _clean(name: str, x, n: int | None = None) -> np.ndarray:
    arr = np.asarray(x, dtype=float).ravel()
    if n is not None and arr.size != n:
        raise InputError(f"{name} has {arr.size} values, expected {n} (one per step)",
                         hint="give one value per torque step")
    return arr


class _Points:
    """Every profile evaluation of one fit, kept sorted by mu (chi2, its slope in log mu,
    the parameters p and the small-signal x of each)."""

    def __init__(self, engine: _Engine):
        self.engine = engine
        self.mu = np.empty(0)
        self.data: dict[str, np.ndarray] = {}

    def _neighbour_starts(self, mus):
        """Starts at new mu values: the solutions of the nearest evaluated points."""
        j = np.searchsorted(self.mu, mus)
        lo = np.clip(j - 1, 0, self.mu.size - 1)
        hi = np.clip(j, 0, self.mu.size - 1)
        return [(self.data["p"][k], self.data["x"][k]) for k in (lo, hi)]

    def add(self, mus, *, search: bool = False) -> None:
        """Evaluate the profile at ``mus`` (global starts when ``search`` or when nothing is
        known yet, else the neighbours' solutions) and merge."""
        mus = np.setdiff1d(np.asarray(mus, dtype=float), self.mu)
        if mus.size == 0:
            return
        starts = None if search or self.mu.size == 0 else self._neighbour_starts(mus)
        p = self.engine.profile(mus, starts)
        mu = np.concatenate([self.mu, mus])
        order = np.argsort(mu)
        self.mu = mu[order]
        self.data = {k: np.concatenate([self.data[k], v])[order] if self.data else v
                     for k, v in p.items()}

    def sweep(self, *, max_sweeps: int = 3) -> None:
        """Re-solve every point from its neighbours' solutions, keeping improvements (a
        good solution found at one mu spreads along the profile)."""
        for _ in range(max_sweeps):
            n = self.mu.size
            lo, hi = np.maximum(np.arange(n) - 1, 0), np.minimum(np.arange(n) + 1, n - 1)
            starts = [(self.data["p"][k], self.data["x"][k]) for k in (lo, hi)]
            p = self.engine.profile(self.mu, starts)
            better = p["chi2"] < self.data["chi2"] - 1e-9
            if not better.any():
                return
            for k, v in p.items():
                self.data[k] = np.where(better.reshape((-1,) + (1,) * (v.ndim - 1)), v,
                                        self.data[k])

    @property
    def chi(self) -> np.ndarray:
        return self.data["chi2"]

    def brackets(self, floor_mu: float):
        """(lo, hi, estimate) around every local minimum the values and slopes show: a slope
        turning from falling to rising between neighbours (a basin may be narrower than
        their spacing), or rising from the first point (towards the floor). The estimate is
        the minimum of the cubic Hermite interpolant in log mu."""
        v, c, s = np.log(self.mu), self.chi, self.data["dchi2"]
        out = []
        if s[0] > 0:
            out.append((floor_mu, float(self.mu[0]), float(c[0])))
        t = np.linspace(0.0, 1.0, 41)
        h00, h10 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t
        h01, h11 = -2 * t**3 + 3 * t**2, t**3 - t**2
        for i in np.flatnonzero((s[:-1] < 0) & (s[1:] > 0)):
            dv = v[i + 1] - v[i]
            est = h00 * c[i] + h10 * dv * s[i] + h01 * c[i + 1] + h11 * dv * s[i + 1]
            out.append((float(self.mu[i]), float(self.mu[i + 1]), float(est.min())))
        return out


def _zoom_minima(pts: _Points, floor_mu: float, *, rounds: int = 3, n_points: int = 8,
                 max_brackets: int = 8, margin: float = 25.0) -> None:
    """Refine every local minimum that may matter: each round evaluates ``n_points``
    interior points in the best ``max_brackets`` brackets (all in one batch)."""
    for _ in range(rounds):
        br = pts.brackets(floor_mu)
        if not br:
            return
        best = min(min(e for _, _, e in br), float(pts.chi.min()))
        br = sorted((b for b in br if b[2] <= best + margin), key=lambda b: b[2])
        new = [np.geomspace(lo, hi, n_points + 2)[1:-1] for lo, hi, _ in br[:max_brackets]]
        if not new:  # no bracket within the margin of the best point
            return
        pts.add(np.concatenate(new))


def _polish_best(pts: _Points, *, rounds: int = 4, n_points: int = 4,
                 rel_tol: float = 1e-5) -> None:
    """Fill the intervals on both sides of the lowest evaluated point, a few rounds: a
    basin narrower than the grid whose slopes were misjudged (LM not converged at a
    neighbour) is still found, because the lowest point always lies next to it."""
    for _ in range(rounds):
        k = int(np.argmin(pts.chi))
        lo, hi = max(k - 1, 0), min(k + 1, pts.mu.size - 1)
        if pts.mu[hi] / pts.mu[lo] - 1.0 < rel_tol:
            return
        new = [np.geomspace(pts.mu[a], pts.mu[b], n_points + 2)[1:-1]
               for a, b in ((lo, k), (k, hi)) if b > a]
        pts.add(np.concatenate(new))


def _refine_crossings(pts: _Points, level: float, pairs, *, rounds: int = 2,
                      n_points: int = 8) -> list[float]:
    """mu where the profile crosses ``level`` between each (inside, outside) pair of
    evaluated points: batches of interior points, then log-linear interpolation."""
    pairs = list(pairs)
    for _ in range(rounds):
        new = [np.geomspace(a, b, n_points + 2)[1:-1] for a, b in pairs]
        if not new:
            break
        pts.add(np.concatenate(new))
        out = []
        for a, b in pairs:  # the innermost crossing from the inside point
            sel = np.flatnonzero((pts.mu >= min(a, b)) & (pts.mu <= max(a, b)))
            if b < a:
                sel = sel[::-1]
            above = np.flatnonzero(pts.chi[sel] > level)
            k = int(above[0]) if above.size else len(sel) - 1
            out.append((float(pts.mu[sel[max(k - 1, 0)]]), float(pts.mu[sel[k]])))
        pairs = out
    res = []
    for a, b in pairs:
        ca = float(pts.chi[np.searchsorted(pts.mu, a)])
        cb = float(pts.chi[np.searchsorted(pts.mu, b)])
        f = np.clip((level - ca) / (cb - ca), 0.0, 1.0) if cb != ca else 0.5
        res.append(float(a * (b / a) ** f))
    return res


def fit_mu_from_phase(coa, phase_deg, phase_se_deg, *, constant=None, creepage_swing=None,
                      coa_se=None, max_rel_half_width: float = 0.10, scale_by_chi2: bool = True,
                      n_nodes: int = 16, ratio_bounds: tuple[float, float] = R_BOUNDS
                      ) -> PhaseMuFit:
    """mu from the phase progression: fit ``tan(phi_i) = C/k(CoA_i)`` over the Polach family
    (module docstring; V-Track paper Eq. 1, Polach 2005 Eq. 8) and find the 95 %
    profile-likelihood interval of mu.

    ``coa`` [-] utilised adhesion per step, ``phase_deg`` [deg] the lag of the wheel speed
    behind the torque per step, ``phase_se_deg`` [deg] its standard error, ``constant`` C [-]
    (``Omega*J*V/(R^2*N)``) when known, ``creepage_swing`` [-] the creepage swing amplitude
    per step, ``coa_se`` [-] the CoA's standard error per step. ``max_rel_half_width``: mu
    counts as determined when its 95 % interval is closed and at most this fraction of mu
    wide on either side; ``scale_by_chi2`` widens the interval by the reduced chi2 when it
    exceeds 1. ``n_nodes``: nodes of the swing average (refitted with 64 when too few).
    ``ratio_bounds``: the range of r = kA/kS searched (a narrower range is a prior on the
    curve's shape, e.g. Polach's published sets for a train; default :data:`R_BOUNDS`).
    Steps with a non-finite value, a phase outside (0, 90) deg or a non-positive standard
    error are left out; at least (number of parameters + 1) steps must remain.
    """
    # the search visits far parameter corners where h overflows to inf/NaN; those points
    # get an infinite chi2 and are never chosen, so their floating-point warnings are noise
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return _fit(coa, phase_deg, phase_se_deg, constant=constant,
                    creepage_swing=creepage_swing, coa_se=coa_se,
                    max_rel_half_width=max_rel_half_width, scale_by_chi2=scale_by_chi2,
                    n_nodes=n_nodes, ratio_bounds=ratio_bounds)


def _fit(coa, phase_deg, phase_se_deg, *, constant, creepage_swing, coa_se,
         max_rel_half_width, scale_by_chi2, n_nodes, ratio_bounds=R_BOUNDS) -> PhaseMuFit:
    """The body of :func:`fit_mu_from_phase`."""
    coa = np.abs(_clean("coa", coa))
    n = coa.size
    phase = _clean("phase_deg", phase_deg, n)
    se = _clean("phase_se_deg", phase_se_deg, n)
    swing = None if creepage_swing is None else np.abs(_clean("creepage_swing",
                                                             creepage_swing, n))
    c_se = np.zeros(n) if coa_se is None else np.abs(_clean("coa_se", coa_se, n))
    c_se = np.where(np.isfinite(c_se), c_se, 0.0)
    if constant is not None and not (np.isfinite(constant) and constant > 0):
        raise InputError(f"the constant C = {constant} must be a positive number",
                         hint="C = Omega*J*V/(R^2*N); pass None to fit it")
    ok = (np.isfinite(coa) & (coa > 0) & np.isfinite(phase) & np.isfinite(se) & (se > 0)
          & (phase > 0) & (phase < 90))
    if swing is not None:
        swing = np.where(np.isfinite(swing), swing, 0.0)
        if not np.any(swing[ok] > 0):
            swing = None
    n_par = 3 if swing is None or constant is not None else 4
    if ok.sum() < n_par + 1:
        raise InputError(f"mu from the phase needs at least {n_par + 1} steps with a finite "
                         f"CoA > 0 and a phase between 0 and 90 deg, got {int(ok.sum())}",
                         hint="measure more torque steps")
    d = _Data(coa[ok], np.radians(phase[ok]), np.radians(se[ok]), c_se[ok],
              None if swing is None else swing[ok],
              None if constant is None else float(constant))
    cmax = float(d.coa.max())
    dof = int(ok.sum()) - n_par
    lo, hi = (float(b) for b in ratio_bounds)
    if not (R_BOUNDS[0] <= lo <= hi <= R_BOUNDS[1]):
        raise InputError(f"ratio_bounds {ratio_bounds} must lie within {R_BOUNDS}",
                         hint="r = kA/kS: 1 <= low <= high <= 7")
    eng = _Engine(d, n_nodes=n_nodes, ratio_bounds=(lo, max(hi, lo * 1.0001)))

    # the profile on a global grid of log(mu/max CoA): dense near saturation, steps of 2 %
    # over utilisations 0.37-0.96, sparse up to mu = 50x max CoA; plus mu -> max CoA
    floor_mu = cmax * (1.0 + 1e-7)
    v = np.concatenate([np.geomspace(5e-4, 0.02, 7), np.arange(0.04, 1.0, 0.02),
                        np.geomspace(1.0, np.log(50.0), 8)[1:]])
    pts = _Points(eng)
    pts.add(np.concatenate([[floor_mu], cmax * np.exp(v)]), search=True)
    pts.sweep(max_sweeps=3 if eng.mode == "free" else 1)
    _zoom_minima(pts, floor_mu)
    _polish_best(pts)
    k = int(np.argmin(pts.chi))
    chi_min, mu_hat = float(pts.chi[k]), float(pts.mu[k])
    p_hat = pts.data["p"][k]
    scale = max(1.0, chi_min / dof) if scale_by_chi2 else 1.0
    level = chi_min + CHI2_95 * scale
    # the run of evaluated points within the level around the minimum, and any other
    inside = pts.chi <= level
    a = b = k
    while a > 0 and inside[a - 1]:
        a -= 1
    while b < inside.size - 1 and inside[b + 1]:
        b += 1
    others = np.flatnonzero(inside)
    others = others[(others < a) | (others > b)]
    lowest = int(min(a, others.min())) if others.size else a
    pairs, keys = [], []
    if b < inside.size - 1:
        pairs.append((pts.mu[b], pts.mu[b + 1]))
        keys.append("hi")
    if a > 0:
        pairs.append((pts.mu[a], pts.mu[a - 1]))
        keys.append("lo")
    if lowest < a and lowest > 0:
        pairs.append((pts.mu[lowest], pts.mu[lowest - 1]))
        keys.append("lowest")
    cross = dict(zip(keys, _refine_crossings(pts, level, pairs), strict=True))
    hi_mu, lo_mu = cross.get("hi"), cross.get("lo")
    other = [float(m) for m in pts.mu[others]]
    closed = lo_mu is not None and hi_mu is not None
    determined = bool(closed and not other
                      and 0.5 * (hi_mu - lo_mu) <= max_rel_half_width * mu_hat)
    lower = cmax
    if lowest == a and lo_mu is not None:
        lower = max(cmax, lo_mu)
    elif lowest < a and "lowest" in cross:
        lower = max(cmax, cross["lowest"])

    if eng.mode != "small" and n_nodes < 64:
        # the swing average's trapezoidal rule: exact to ~1e-8 with 16 nodes at V-Track's
        # swings (measured); re-fit with 64 nodes where the swing is larger than that
        mu_c, p_c, x_c = np.array([[mu_hat]]), p_hat[None, :], pts.data["x"][k][None, :]
        fine_eng = _Engine(d, n_nodes=64, ratio_bounds=(lo, max(hi, lo * 1.0001)))
        fine = fine_eng.residuals(mu_c, p_c, x_c)[0]
        if np.max(np.abs(fine - eng.residuals(mu_c, p_c, x_c)[0])) > 1e-3:
            return _fit(coa, phase_deg, phase_se_deg, constant=constant,
                        creepage_swing=creepage_swing, coa_se=coa_se,
                        max_rel_half_width=max_rel_half_width,
                        scale_by_chi2=scale_by_chi2, n_nodes=64,
                        ratio_bounds=ratio_bounds)
    r_hat, lev_hat = float(np.exp(p_hat[0])), float(np.exp(p_hat[1]))
    if eng.mode == "free":
        k0_hat = float(np.exp(p_hat[2]))
        c_hat, rel = lev_hat * k0_hat, False
    elif d.constant is not None:
        c_hat, k0_hat, rel = d.constant, d.constant / lev_hat, False
    else:
        c_hat, k0_hat, rel = lev_hat, 1.0, True
    warnings: list[str] = []
    if not determined:
        why = ("its 95 % range is open above" if hi_mu is None else
               "the likelihood has separate basins within the 95 % level" if other else
               "its 95 % range is open below" if lo_mu is None else
               f"its 95 % range {lo_mu:.4f}..{hi_mu:.4f} is wider than "
               f"+-{100 * max_rel_half_width:.0f} % of {mu_hat:.4f}")
        warnings.append(f"the phase progression does not determine mu ({why}); mu >= "
                        f"{lower:.4f}. Measure closer to saturation")
    if scale > 1.0:
        warnings.append(f"the phases scatter {np.sqrt(scale):.2f}x more than their standard "
                        f"errors about the fit (reduced chi2 {chi_min / dof:.3g}); the "
                        "interval is widened accordingly")
    return PhaseMuFit(
        mu_estimate=mu_hat, mu_determined=determined,
        mu_interval_95=(lo_mu, hi_mu) if determined else (lower, None),
        mu_lower_bound=lower,
        mu_stderr_estimate=(hi_mu - lo_mu) / (2 * _Z975) if closed else None,
        constant=float(c_hat), constant_given=d.constant is not None, ratio_ka_ks=r_hat,
        initial_slope=float(k0_hat), k_relative=rel, level=lev_hat, chi2=chi_min, dof=dof,
        chi2_scale=scale, coa=d.coa, phase_deg=np.degrees(d.phase_rad),
        sigma_deg=np.degrees(d.se_rad),
        profile={"mu": pts.mu, "chi2": pts.chi, "level": level, "swing_mode": eng.mode,
                 "n_evaluations": int(pts.mu.size)},
        warnings=warnings)
