"""The coefficient of friction from the phase alone (issue 8): what a train, which carries no
force dynamometer, can measure.

Model
-----
The rigid-wheel relation (Eq. 1 of the V-Track paper with its constant, FACTS §1)::

    tan(phi_i) = C / k(CoA_i),      C = Omega*J*V/(R^2*N)

with ``k = dCoA/dxi`` the creep coefficient at the step's operating point on a Polach curve
(Polach 2005, Eqs. 3 and 8, lumped as in :mod:`torquemod.fit`)::

    CoA(xi) = mu * h(K*xi/mu; r),   h(x; r) = (2/pi)*[r*x/(1 + (r*x)^2) + arctan(x)]

where ``K = kS*s`` [-] is the slope scale (s the lumped contact stiffness) and ``r = kA/kS``.
Then ``k = K*h'(x)`` at ``x = h^-1(CoA/mu)``: the fall of ``k(CoA)/k(0)`` with the utilisation
``CoA/mu`` depends on ``mu`` and ``r`` only, so the phase progression fixes ``mu`` even when the
level ``C/K`` is unknown. With the creepage swing ``a_i`` of the modulation given, each step's
creep coefficient is the describing-function slope over the swing
(:func:`torquemod.contact.polach.swing_slope`) at the mean creepage whose swing-averaged CoA
is the measured one; the swing is in creepage units, so K then matters on its own.

Parameters fitted: ``mu`` (profiled), ``log r`` and the level: ``log K`` when C is given,
``log(C/K)`` (K = 1, k relative) when it is not. The swing is used only with C given: without
C its effect depends on K, which the phases alone fix too weakly for a well-posed fit.

Uncertainty
-----------
Residuals ``(phi_model - phi)/sigma`` with ``sigma^2 = se_phi^2 + (dphi/dCoA*se_CoA)^2``. The
95 % interval is the profile-likelihood range ``chi2(mu) <= chi2_min + 3.84*max(1, chi2_red)``
(scaled up when the scatter exceeds the stated errors, never down). ``mu`` is determined only
when that range is closed on both sides and within +-15 % of the estimate; otherwise
``mu = None`` and the lower bound is the larger of the largest CoA (adhesion cannot exceed
friction) and the range's lower end.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from .contact.polach import swing_average, swing_slope
from .errors import InputError
from .jsonutil import to_jsonable

__all__ = ["PhaseMuFit", "fit_mu_from_phase", "polach_h", "polach_h_slope"]

#: chi-square quantile of one degree of freedom at 95 %
CHI2_95 = 3.841458820694124
#: bounds of r = kA/kS
R_BOUNDS = (0.05, 20.0)
#: mu is "determined" when its 95 % range lies within this fraction of the estimate
MAX_REL_HALF_WIDTH = 0.15


def polach_h(x, r):
    """Normalised Polach force ``h(x; r) = (2/pi)*(r*x/(1+(r*x)^2) + arctan(x))`` (P05 Eq. 8
    with ``x = kS*eps``, ``r = kA/kS``), odd in x."""
    x = np.asarray(x, dtype=float)
    rx = r * x
    return (2.0 / np.pi) * (rx / (1.0 + rx * rx) + np.arctan(x))


def polach_h_slope(x, r):
    """``dh/dx`` of :func:`polach_h`."""
    x = np.asarray(x, dtype=float)
    rx2 = (r * x) ** 2
    return (2.0 / np.pi) * (r * (1.0 - rx2) / (1.0 + rx2) ** 2 + 1.0 / (1.0 + x * x))


def _branch(r: float) -> tuple[np.ndarray, np.ndarray]:
    """(x, h) on a dense grid of the rising branch of h (up to its first maximum)."""
    x = np.concatenate([[0.0], np.logspace(-5, 3, 3000)])
    h = polach_h(x, r)
    falling = np.flatnonzero(np.diff(h) <= 0)
    stop = falling[0] + 1 if falling.size else x.size
    return x[:stop], h[:stop]


def _invert(u: np.ndarray, r: float) -> np.ndarray:
    """x with h(x; r) = u on the rising branch (NaN where u is beyond the branch's top)."""
    xg, hg = _branch(r)
    u = np.asarray(u, dtype=float)
    x = np.interp(np.abs(u), hg, xg)
    for _ in range(3):  # Newton polish
        x = x - (polach_h(x, r) - np.abs(u)) / np.maximum(polach_h_slope(x, r), 1e-12)
    x = np.where(np.abs(u) < hg[-1], x, np.nan)
    return np.sign(u) * x


@dataclass
class _Model:
    """Evaluates the predicted phase [deg] for one parameter set."""

    coa: np.ndarray
    swing: np.ndarray | None
    constant: float | None

    def slope(self, coa, mu: float, r: float, k_scale: float) -> np.ndarray:
        """Creep coefficient [-] (K*h' in absolute units when K is known) at the CoA."""
        coa = np.asarray(coa, dtype=float)
        x = _invert(coa / mu, r)
        if self.swing is None:
            return k_scale * polach_h_slope(x, r)
        # describing-function slope at the mean creepage whose swing-averaged CoA is coa
        a = np.asarray(self.swing, dtype=float) * k_scale / mu  # swing in x units
        target = np.abs(coa) / mu
        x0 = self._solve_mean(r, target, a, x)
        return k_scale * swing_slope(lambda z: polach_h(z, r), x0, a,
                                     slope=lambda z: polach_h_slope(z, r))

    @staticmethod
    def _solve_mean(r, target, a, x_static):
        """x0 with <h(x0 + a cos)> = target: Newton from the static inverse with the mean
        slope <h'(x0 + a cos)> (positive on the rising branch)."""
        x0 = np.where(np.isfinite(x_static), x_static, np.nan)
        for _ in range(8):
            f = swing_average(lambda z: polach_h(z, r), x0, a) - target
            d = swing_average(lambda z: polach_h_slope(z, r), x0, a)
            x0 = x0 - f / np.where(d > 1e-9, d, 1e-9)
        return x0

    def phase_deg(self, coa, mu, r, k_scale, c) -> np.ndarray:
        k = self.slope(coa, mu, r, k_scale)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.degrees(np.arctan2(c, k))


@dataclass
class PhaseMuFit:
    """Result of :func:`fit_mu_from_phase` (units: CoA, mu, k dimensionless; phases [deg])."""

    mu_estimate: float
    mu_determined: bool
    mu_interval_95: tuple[float | None, float | None]
    mu_lower_bound: float
    mu_stderr_estimate: float | None
    constant: float
    constant_given: bool
    ratio_ka_ks: float
    k_scale: float
    k_scale_known: bool
    chi2: float
    dof: int
    coa: np.ndarray
    phase_deg: np.ndarray
    sigma_deg: np.ndarray
    profile: dict
    _model: _Model = field(repr=False)
    warnings: list[str] = field(default_factory=list)

    @property
    def mu(self) -> float | None:
        """mu from the phase [-], None when the steps do not determine it."""
        return self.mu_estimate if self.mu_determined else None

    @property
    def mu_stderr(self) -> float | None:
        return self.mu_stderr_estimate if self.mu_determined else None

    @property
    def utilisation(self) -> np.ndarray:
        """CoA_i/mu per step (NaN when mu is not determined)."""
        if not self.mu_determined:
            return np.full(self.coa.size, np.nan)
        return self.coa / self.mu_estimate

    def creep_coefficient(self, coa) -> np.ndarray:
        """Fitted creep coefficient at the given CoA (small-signal; relative to k(0) = 2(r+1)/pi
        when neither C nor the swing fixes the scale)."""
        x = _invert(np.asarray(coa, dtype=float) / self.mu_estimate, self.ratio_ka_ks)
        return self.k_scale * polach_h_slope(x, self.ratio_ka_ks)

    def phase_curve(self, coa) -> np.ndarray:
        """Predicted phase [deg] at the given CoA (small-signal slope: a smooth curve)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.degrees(np.arctan2(self.constant, self.creep_coefficient(coa)))

    def report(self) -> str:
        lo, hi = self.mu_interval_95
        head = (f"mu from the phase = {self.mu_estimate:.4f} (95 % {lo:.4f} .. {hi:.4f})"
                if self.mu_determined else
                f"mu from the phase NOT determined by these steps; mu >= "
                f"{self.mu_lower_bound:.4f}")
        lines = ["[[mu from the phase]] tan(phi) = C/k(CoA), Polach family", "  " + head,
                 f"  C = {self.constant:.4g} ({'given' if self.constant_given else 'fitted'})"
                 f", kA/kS = {self.ratio_ka_ks:.3g}, chi2 = {self.chi2:.3g} (dof {self.dof})"]
        lines += [f"  WARNING: {w}" for w in self.warnings]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return to_jsonable({
            "mu": self.mu, "mu_stderr": self.mu_stderr, "mu_estimate": self.mu_estimate,
            "mu_determined": self.mu_determined, "mu_interval_95": list(self.mu_interval_95),
            "mu_lower_bound": self.mu_lower_bound, "constant": self.constant,
            "constant_given": self.constant_given, "ratio_ka_ks": self.ratio_ka_ks,
            "k_scale": self.k_scale, "chi2": self.chi2, "dof": self.dof,
            "profile": self.profile, "warnings": list(self.warnings),
        })


def _clean(name: str, x, n: int | None = None) -> np.ndarray:
    arr = np.asarray(x, dtype=float).ravel()
    if n is not None and arr.size != n:
        raise InputError(f"{name} has {arr.size} values, expected {n}")
    return arr


def fit_mu_from_phase(coa, phase_deg, phase_se_deg, *, constant=None, creepage_swing=None,
                      coa_se=None, n_grid: int = 28) -> PhaseMuFit:
    """Fit ``tan(phi_i) = C/k(CoA_i)`` over the Polach family and estimate mu with a 95 %
    profile-likelihood interval (module docstring). ``coa`` [-] the utilised adhesion per
    step, ``phase_deg`` the phase lag, ``phase_se_deg`` its standard error, ``constant`` C
    [-] when the rig gives it, ``creepage_swing`` [-] per step, ``coa_se`` [-]."""
    coa = np.abs(_clean("coa", coa))
    n = coa.size
    phase = _clean("phase_deg", phase_deg, n)
    se = _clean("phase_se_deg", phase_se_deg, n)
    swing = None if creepage_swing is None else np.nan_to_num(
        np.abs(_clean("creepage_swing", creepage_swing, n)))
    if swing is not None and not np.any(swing > 0):
        swing = None
    c_se = np.zeros(n) if coa_se is None else np.nan_to_num(_clean("coa_se", coa_se, n))
    ok = np.isfinite(coa) & np.isfinite(phase) & np.isfinite(se) & (se > 0) & (phase > 0) \
        & (phase < 90)
    if ok.sum() < 4:
        raise InputError(f"mu from the phase needs at least 4 steps with a phase between 0 and "
                         f"90 deg, got {int(ok.sum())}", hint="measure more torque steps")
    coa, phase, se, c_se = coa[ok], phase[ok], se[ok], c_se[ok]
    if swing is not None:
        swing = swing[ok]
    c_given = constant is not None and np.isfinite(constant)
    early: list[str] = []
    if swing is not None and not c_given:
        # the swing is in creepage units: its effect needs the slope scale K = C/A, which the
        # phases alone fix only weakly (the fit is then ill-posed); give C to use it
        early.append("the creepage swing is not used without the constant C (give the rig's "
                     "inertia, or C measured from the torque/speed amplitude ratio)")
        swing = None
    model = _Model(coa, swing, float(constant) if c_given else None)
    fit_k = c_given or swing is not None
    fit_c = not c_given

    def unpack(p):
        """(r, C, K) from the free parameters: log r, then log A = log(C/K) when C is not
        given (well determined by the phase level), then log K when it matters (weakly)."""
        r = float(np.exp(p[0]))
        if c_given:
            k = float(np.exp(p[1]))
            return r, float(constant), k
        k = float(np.exp(p[2])) if fit_k else 1.0
        return r, float(np.exp(p[1])) * k, k

    def resid(p, mu):
        r, c, k = unpack(p)
        pred = model.phase_deg(coa, mu, r, k, c)
        # effective variance: the CoA's error moves the prediction by dphi/dCoA * se
        h = 1e-6 * max(mu, 1e-3)
        dp = (model.phase_deg(coa + h, mu, r, k, c) - pred) / h if c_se.any() else 0.0
        sig = np.sqrt(se ** 2 + (dp * c_se) ** 2)
        res = (pred - phase) / sig
        return np.where(np.isfinite(res), res, 1e3)

    # starting values from the low-CoA phase: tan(phi_0) = C/(K*h'(0)), h'(0) = 2(r+1)/pi
    t0 = float(np.tan(np.radians(phase[np.argmin(coa)])))
    n_par = 1 + int(fit_c) + int(fit_k)
    lo_b = [np.log(R_BOUNDS[0])] + [-12.0] * (n_par - 1)
    hi_b = [np.log(R_BOUNDS[1])] + [12.0] * (n_par - 1)

    def starts(r0):
        k0 = 1.0
        if c_given:
            k0 = float(constant) / (t0 * 2 * (r0 + 1) / np.pi)
        a0 = t0 * 2 * (r0 + 1) / np.pi  # C/K
        p = [np.log(r0)] + ([np.log(a0)] if fit_c else []) + ([np.log(k0)] if fit_k else [])
        return np.clip(p, np.array(lo_b) + 1e-9, np.array(hi_b) - 1e-9)

    def best_at(mu, guesses):
        best = None
        for g in guesses:
            sol = least_squares(resid, g, args=(mu,), bounds=(lo_b, hi_b), x_scale=1.0,
                                max_nfev=200)
            if best is None or sol.cost < best.cost:
                best = sol
        return best

    mu_lo = float(coa.max()) * 1.0005
    grid = mu_lo * np.geomspace(1.0, 6.0, n_grid)  # coarse: finds the basin(s)
    first = [starts(r0) for r0 in (0.5, 1.0, 2.5, 6.0)]
    chi = np.empty(grid.size)
    sols = []
    prev = None
    for j, mu in enumerate(grid):
        guesses = first if prev is None else [prev.x]  # warm start along the profile
        sol = best_at(mu, guesses)
        sols.append(sol)
        chi[j] = 2.0 * sol.cost
        prev = sol
    # and back down from the top with fresh starts there: the profile is path dependent
    # where the likelihood has several valleys; each point keeps the better solution
    prev = None
    for j in range(grid.size - 1, -1, -1):
        sol = best_at(grid[j], first if prev is None else [prev.x])
        if 2.0 * sol.cost < chi[j]:
            sols[j], chi[j] = sol, 2.0 * sol.cost
        prev = sols[j]
    j0 = int(np.argmin(chi))
    cache: dict[float, object] = {}

    def prof(mu: float):
        """Profile chi2 at mu, warm-started from the nearest grid solution."""
        if mu not in cache:
            near = sols[int(np.argmin(np.abs(grid - mu)))]
            cache[mu] = best_at(mu, [near.x, sols[j0].x])
        return 2.0 * cache[mu].cost

    # the minimum, refined between the neighbouring grid points
    a_mu = grid[max(j0 - 1, 0)]
    b_mu = grid[min(j0 + 1, grid.size - 1)]
    ref = minimize_scalar(prof, bounds=(a_mu, b_mu), method="bounded",
                          options={"xatol": 1e-5 * grid[j0]})
    mu_hat = float(ref.x)
    chi_min = min(float(ref.fun), float(chi[j0]))
    if chi[j0] < ref.fun:
        mu_hat = float(grid[j0])
    best_sol = cache.get(mu_hat, sols[j0])
    dof = max(1, coa.size - (n_par + 1))
    scale = max(1.0, chi_min / dof)
    level = chi_min + CHI2_95 * scale
    below = chi <= level

    def crossing(inside: float, outside: float) -> float:
        """mu where the profile crosses the level, by bisection between two grid values."""
        for _ in range(30):
            mid = 0.5 * (inside + outside)
            if prof(mid) <= level:
                inside = mid
            else:
                outside = mid
            if abs(outside - inside) < 1e-5 * mu_hat:
                break
        return 0.5 * (inside + outside)

    j_hat = int(np.searchsorted(grid, mu_hat))
    lo_i = max(j_hat - 1, 0)
    while lo_i > 0 and below[lo_i]:
        lo_i -= 1
    hi_i = min(j_hat, grid.size - 1)
    while hi_i < grid.size - 1 and below[hi_i]:
        hi_i += 1
    lo_mu = crossing(mu_hat, float(grid[lo_i])) if not below[lo_i] else None
    hi_mu = crossing(mu_hat, float(grid[hi_i])) if not below[hi_i] else None
    warnings: list[str] = list(early)
    closed = lo_mu is not None and hi_mu is not None
    other_basin = bool(np.any(below[:lo_i]) or np.any(below[hi_i + 1:]))
    determined = closed and not other_basin and (
        (hi_mu - lo_mu) / 2 <= MAX_REL_HALF_WIDTH * mu_hat)
    lower = float(coa.max())
    if lo_mu is not None and not other_basin:
        lower = max(lower, lo_mu)
    if not determined:
        why = ("its 95 % range is open above" if hi_mu is None else
               "the likelihood has separate basins" if other_basin else
               f"its 95 % range {lo_mu or lower:.3f}..{hi_mu:.3f} is wider than "
               f"+-{100 * MAX_REL_HALF_WIDTH:.0f} %")
        warnings.append(f"the phase progression does not determine mu ({why}); mu >= "
                        f"{lower:.4f} (the highest CoA reached, or the range's lower end)")
    if scale > 1.0:
        warnings.append(f"the phases scatter {np.sqrt(scale):.2f}x more than their standard "
                        "errors about the fit; the interval is widened accordingly")
    sols_x = best_sol.x
    r_hat, c_hat, k_hat = unpack(sols_x)
    interval = (lo_mu, hi_mu) if determined else (lower, None)
    return PhaseMuFit(
        mu_estimate=mu_hat, mu_determined=bool(determined), mu_interval_95=interval,
        mu_lower_bound=lower,
        mu_stderr_estimate=(hi_mu - lo_mu) / (2 * 1.959964) if determined else None,
        constant=c_hat, constant_given=bool(c_given), ratio_ka_ks=r_hat, k_scale=k_hat,
        k_scale_known=bool(fit_k), chi2=chi_min, dof=dof, coa=coa, phase_deg=phase,
        sigma_deg=se, profile={"mu": grid.tolist(), "chi2": chi.tolist(), "level": level},
        _model=model, warnings=warnings)
