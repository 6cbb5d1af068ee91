"""The result of the Polach force fit (:func:`torquemod.analysis.fit.fit_polach`): the fitted
parameters, their uncertainties, the data and the fitted curve.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from torquemod._util.jsonutil import to_jsonable
from torquemod.analysis.polachcurve import longitudinal_mean, polach_coa, polach_slope

__all__ = ["PolachFit"]


@dataclass
class PolachFit:
    """Result of :func:`~torquemod.analysis.fit.fit_polach` (lmfit-like): Polach's creep-force
    curve (Polach 2005, Eqs. 3, 8 and 9) fitted to a creep curve.

    CoA (coefficient of adhesion) and creepage are dimensionless [-].

    Attributes
    ----------
    model : {"polach", "polach_velocity"}
        Constant friction, or friction falling with slip velocity (Polach 2005, Eq. 9).
    param_names : tuple of str
        The reported parameters, in order: ``mu`` [-] (mu0 when velocity-dependent),
        ``k_a``/``k_s`` [-] when the contact stiffness is known, else
        ``k_a_stiffness``/``k_s_stiffness`` [-]; ``a_ratio`` (Polach's A) [-] and
        ``b_s_m`` (Polach's B) [s/m] when velocity-dependent.
    params, stderr : dict of str to float
        The reported parameters and their standard errors, in the units above.
    covariance, correlation : ndarray
        Of the internal vector ``theta`` (units of ``theta`` squared; correlation [-]).
    theta : ndarray
        Internal vector ``(mu, kA*s, kS*s[, A, B])`` [-, -, -, -, s/m], ``s`` the lumped
        stiffness of Polach 2005, Eq. 3.
    residuals : ndarray
        Model minus data per point [-] (CoA).
    weighted_residuals : ndarray
        ``residuals / sigma`` [-].
    sigma : ndarray
        Standard error used per point [-] (CoA).
    xi, coa : ndarray
        The fitted points: creepage [-] and CoA [-].
    speeds_m_s : ndarray or None
        Rolling speed per point [m/s] (velocity-dependent model only).
    converged : bool
        The optimiser reported success.
    status : int
    message : str
        The optimiser's status code and message.
    nfev : int
        Number of model evaluations.
    chi2, reduced_chi2 : float
        Sum of squared weighted residuals [-], and that divided by ``dof``.
    dof : int
        Points minus fitted parameters.
    mu_estimate, mu_stderr_estimate : float
        The fitted friction coefficient [-] and its standard error, whether or not
        determined (use :attr:`mu`).
    mu_determined : bool
        The points determine mu (criteria in :mod:`torquemod.analysis.fit`).
    mu_lower_bound : float
        Largest measured CoA [-]: friction is at least this.
    curve_peak_coa : float
        Maximum of the fitted curve [-] over the creepage range considered.
    stiffness : float or None
        Lumped contact stiffness ``s = pi*G*a*b*c11/(4*Q)`` [-] when given (Polach 2005,
        Eq. 3 with Kalker's c11).
    weighted : bool
        Points weighted by ``1/sigma``.
    mu_interval_68, mu_interval_95 : tuple of (float or None)
        Profile-likelihood intervals of mu [-]; None where an end is not bounded.
    mu_profile : dict
        The profile of chi2 over mu behind the intervals.
    starts : list of dict
        The optimiser's start points and their costs.
    warnings : list of str
        What the caller should know (e.g. mu not determined).
    options : dict
        The options the fit ran with.
    swing : ndarray or None
        Creepage swing amplitude per point [-] when the modulation is modelled.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
    """

    model: str
    param_names: tuple[str, ...]
    params: dict[str, float]
    stderr: dict[str, float]
    covariance: np.ndarray
    correlation: np.ndarray
    theta: np.ndarray  # internal vector (mu, kA*s, kS*s[, A, B])
    residuals: np.ndarray  # model - data, CoA units
    weighted_residuals: np.ndarray
    sigma: np.ndarray  # standard error used per point (CoA units)
    xi: np.ndarray
    coa: np.ndarray
    speeds_m_s: np.ndarray | None
    converged: bool
    status: int
    message: str
    nfev: int
    chi2: float
    reduced_chi2: float
    dof: int
    mu_estimate: float
    mu_stderr_estimate: float
    mu_determined: bool
    mu_lower_bound: float
    curve_peak_coa: float
    stiffness: float | None
    weighted: bool
    mu_interval_68: tuple[float | None, float | None] = (None, None)
    mu_interval_95: tuple[float | None, float | None] = (None, None)
    mu_profile: dict = field(default_factory=dict)
    starts: list[dict] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    options: dict = field(default_factory=dict)
    swing: np.ndarray | None = None  # creepage swing per point [-] when modelled

    @property
    def mu(self) -> float | None:
        """Fitted friction coefficient [-] (mu0 when velocity-dependent); None when the points
        do not determine it (see :mod:`torquemod.analysis.fit`)."""
        return self.mu_estimate if self.mu_determined else None

    @property
    def mu_stderr(self) -> float | None:
        return self.mu_stderr_estimate if self.mu_determined else None

    @property
    def velocity_dependent(self) -> bool:
        return len(self.theta) == 5

    @property
    def initial_slope(self) -> float:
        """dCoA/dxi at xi = 0, ``2*(kA + kS)*s/pi`` [-]."""
        return float(2.0 * (self.theta[1] + self.theta[2]) / np.pi)

    def _speed(self, xi, speed_m_s):
        if not self.velocity_dependent:
            return None
        if speed_m_s is None:
            speed_m_s = float(np.mean(self.speeds_m_s))
        return np.broadcast_to(np.asarray(speed_m_s, dtype=float), np.shape(xi))

    def curve(self, xi, speed_m_s=None):
        """Fitted CoA at creepage ``xi`` [-] (speed defaults to the mean of the data)."""
        return polach_coa(xi, self.theta, speed_m_s=self._speed(xi, speed_m_s))

    def mean_curve(self, xi, swing, speed_m_s=None):
        """Mean CoA [-] of a step at mean creepage ``xi`` [-] whose creepage swings
        sinusoidally by amplitude ``swing`` [-]: the period average of the static curve
        (``CoA_mean`` of :mod:`torquemod.analysis.fit`), the model fitted with ``creepage_swing=``.
        ``swing = 0`` gives :meth:`curve`, the static curve. Speed as in :meth:`curve`."""
        return longitudinal_mean(xi, self.theta, np.asarray(swing, dtype=float),
                                 self._speed(xi, speed_m_s))

    def slope(self, xi, speed_m_s=None):
        """Creep coefficient dCoA/dxi of the fitted curve at ``xi`` [-]."""
        return polach_slope(xi, self.theta, speed_m_s=self._speed(xi, speed_m_s))

    def report(self) -> str:
        """Plain-text summary of the fit."""
        lines = [f"[[Polach fit]] model={self.model}  points={self.xi.size}  dof={self.dof}",
                 f"  converged={self.converged}  status={self.status}  nfev={self.nfev}",
                 f"  message: {self.message}",
                 f"  chi2={self.chi2:.4g}  reduced chi2={self.reduced_chi2:.4g}  "
                 f"weighted={self.weighted}"]
        if self.mu_determined:
            lines.append(f"  mu = {self.mu_estimate:.4f} +/- {self.mu_stderr_estimate:.4f}")
        else:
            lines.append(f"  mu NOT determined by these points; mu >= {self.mu_lower_bound:.4f}")
        lines.append(f"  maximum of the fitted curve (creepage <= "
                     f"{self.options.get('creepage_limit')}): CoA = {self.curve_peak_coa:.4f}")
        lines.append("[[Parameters]]")
        for name in self.param_names:
            if name == "mu" and not self.mu_determined:  # never a value +/- error here
                lo, hi = self.mu_interval_95
                lines.append(f"  {name:16s}   not determined (95 % range {lo:.4g} .. {hi:.4g})"
                             if lo is not None and hi is not None else
                             f"  {name:16s}   not determined")
                continue
            lines.append(f"  {name:16s} = {self.params[name]:12.6g} +/- {self.stderr[name]:.3g}")
        lines.append(f"  initial slope 2(kA+kS)s/pi = {self.initial_slope:.6g}")
        for w in self.warnings:
            lines.append(f"  WARNING: {w}")
        return "\n".join(lines)

    @classmethod
    def from_dict(cls, doc: dict, *, converged: bool, mu_stderr_estimate,
                  warnings: list[str]) -> PolachFit:
        """The fit back from its :meth:`to_dict` document (None read as NaN). What a
        document merged into a larger one may lose is passed in: the optimiser's own
        ``converged`` flag, the standard error of an undetermined mu and the fit's
        ``warnings``."""
        data = doc["data"]
        mu_det = bool(doc["mu_determined"])
        return cls(
            model=doc["model"], param_names=tuple(doc["covariance"]["names"]),
            params={k: _num(v) for k, v in doc["parameters"].items()},
            stderr={k: _num(v) for k, v in doc["stderr"].items()},
            covariance=_arr(doc["covariance"]["matrix"]), correlation=_arr(doc["correlation"]),
            theta=_arr(doc["theta_internal"]["values"]), residuals=_arr(doc["residuals"]),
            weighted_residuals=_arr(doc["weighted_residuals"]), sigma=_arr(data["sigma_coa"]),
            xi=_arr(data["creepage"]), coa=_arr(data["coa"]),
            speeds_m_s=None if data["speed_m_s"] is None else _arr(data["speed_m_s"]),
            converged=bool(converged), status=doc["status"], message=doc["message"],
            nfev=doc["nfev"], chi2=_num(doc["chi2"]), reduced_chi2=_num(doc["reduced_chi2"]),
            dof=doc["dof"],
            mu_estimate=_num(doc["mu"] if mu_det else doc["mu_estimate_unreliable"]),
            mu_stderr_estimate=_num(mu_stderr_estimate), mu_determined=mu_det,
            mu_lower_bound=_num(doc["mu_lower_bound"]),
            curve_peak_coa=_num(doc["curve_peak_coa"]), stiffness=doc["stiffness"],
            weighted=bool(doc["weighted"]), mu_interval_68=tuple(doc["mu_interval_68"]),
            mu_interval_95=tuple(doc["mu_interval_95"]), mu_profile=doc["mu_profile"],
            starts=doc["starts"], warnings=list(warnings), options=doc["options"],
            swing=None if data["creepage_swing"] is None else _arr(data["creepage_swing"]))

    def to_dict(self) -> dict:
        """JSON-ready dictionary (non-finite numbers become None)."""
        return to_jsonable({
            "model": self.model,
            "mu": self.mu,
            "mu_stderr": self.mu_stderr,
            "mu_determined": self.mu_determined,
            "mu_lower_bound": self.mu_lower_bound,
            "mu_interval_68": list(self.mu_interval_68),
            "mu_interval_95": list(self.mu_interval_95),
            "mu_profile": self.mu_profile,
            "curve_peak_coa": self.curve_peak_coa,
            "mu_estimate_unreliable": None if self.mu_determined else self.mu_estimate,
            "parameters": dict(self.params),
            "stderr": dict(self.stderr),
            "initial_slope": self.initial_slope,
            "theta_internal": {"names": ["mu", "k_a*stiffness", "k_s*stiffness"]
                               + (["a_ratio", "b_s_m"] if self.velocity_dependent else []),
                               "values": self.theta.tolist()},
            "stiffness": self.stiffness,
            "covariance": {"names": list(self.param_names),
                           "matrix": self.covariance.tolist()},
            "correlation": self.correlation.tolist(),
            "data": {"creepage": self.xi.tolist(), "coa": self.coa.tolist(),
                     "sigma_coa": self.sigma.tolist(),
                     "creepage_swing": None if self.swing is None else self.swing.tolist(),
                     "speed_m_s": None if self.speeds_m_s is None
                     else self.speeds_m_s.tolist()},
            "residuals": self.residuals.tolist(),
            "weighted_residuals": self.weighted_residuals.tolist(),
            "chi2": self.chi2, "reduced_chi2": self.reduced_chi2, "dof": self.dof,
            "converged": self.converged, "status": self.status, "message": self.message,
            "nfev": self.nfev, "weighted": self.weighted,
            "starts": self.starts, "warnings": list(self.warnings), "options": self.options,
        })


def _num(x) -> float:
    """A JSON number back as a float (None, written for a non-finite one, as NaN)."""
    return float("nan") if x is None else float(x)


def _arr(x) -> np.ndarray:
    """A JSON list (of lists) of numbers back as a float array (None as NaN)."""
    return np.array(x, dtype=float)
