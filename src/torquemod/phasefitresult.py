"""The result of a fit of mu from the phase (:func:`torquemod.phasefit.fit_mu_from_phase`):
a typed container with ``report()``, ``to_dict()`` and the fitted curves."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .jsonutil import to_jsonable
from .polachshape import slope_ratio_small


@dataclass
class PhaseMuFit:
    """Result of :func:`fit_mu_from_phase` (CoA, mu, k, C dimensionless; phases [deg]).

    ``constant`` is C (given, or fitted: ``L*k0``); when neither C nor a swing fixes the
    scale of k, k is relative to its initial value (``k0 = 1``) and ``constant`` is ``L``.
    """

    mu_estimate: float
    mu_determined: bool
    mu_interval_95: tuple
    mu_lower_bound: float
    mu_stderr_estimate: float | None
    constant: float
    constant_given: bool
    ratio_ka_ks: float
    initial_slope: float
    k_relative: bool
    level: float
    chi2: float
    dof: int
    chi2_scale: float
    coa: np.ndarray
    phase_deg: np.ndarray
    sigma_deg: np.ndarray
    profile: dict
    warnings: list = field(default_factory=list)

    @property
    def mu(self) -> float | None:
        """mu from the phase [-]; None when the steps do not determine it."""
        return self.mu_estimate if self.mu_determined else None

    @property
    def mu_stderr(self) -> float | None:
        """Half the 95 % interval / 1.96 [-]; None when mu is not determined."""
        return self.mu_stderr_estimate if self.mu_determined else None

    @property
    def utilisation(self) -> np.ndarray:
        """CoA_i/mu per step (NaN when mu is not determined)."""
        if not self.mu_determined:
            return np.full(self.coa.size, np.nan)
        return self.coa / self.mu_estimate

    def creep_coefficient(self, coa) -> np.ndarray:
        """Fitted small-signal creep coefficient dCoA/dxi [-] at the CoA values (relative to
        k0 = 1 when ``k_relative``): ``k0*h'(x)/h'(0)``, ``x = h^-1(CoA/mu)``."""
        coa = np.abs(np.asarray(coa, dtype=float))
        _, ratio = slope_ratio_small(coa, self.mu_estimate, self.ratio_ka_ks)
        return self.initial_slope / ratio

    def phase_curve(self, coa) -> np.ndarray:
        """Predicted phase [deg] at the CoA values, ``atan(C/k(CoA))`` (small-signal slope: a
        smooth curve; NaN at CoA >= mu)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.degrees(np.arctan(self.constant / self.creep_coefficient(coa)))

    def report(self) -> str:
        """A few lines of text."""
        lo, hi = self.mu_interval_95
        head = (f"mu from the phase = {self.mu_estimate:.4f} (95 % {lo:.4f} .. {hi:.4f})"
                if self.mu_determined else
                f"mu from the phase NOT determined by these steps; mu >= "
                f"{self.mu_lower_bound:.4f} (best fit {self.mu_estimate:.4f})")
        given = "given" if self.constant_given else "fitted"
        rel = " (relative)" if self.k_relative else ""
        par = (f"  C = {self.constant:.4g} ({given}), kA/kS = {self.ratio_ka_ks:.3g}, "
               f"k0 = {self.initial_slope:.4g}{rel}, chi2 = {self.chi2:.3g} (dof {self.dof})")
        lines = ["[[mu from the phase]] tan(phi) = C/k(CoA), Polach family", "  " + head, par]
        lines += [f"  WARNING: {w}" for w in self.warnings]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready dict (non-finite numbers as None)."""
        return to_jsonable({
            "mu": self.mu, "mu_stderr": self.mu_stderr, "mu_estimate": self.mu_estimate,
            "mu_determined": self.mu_determined, "mu_interval_95": list(self.mu_interval_95),
            "mu_lower_bound": self.mu_lower_bound, "constant": self.constant,
            "constant_given": self.constant_given, "ratio_ka_ks": self.ratio_ka_ks,
            "initial_slope": self.initial_slope, "k_relative": self.k_relative,
            "chi2": self.chi2, "dof": self.dof, "chi2_scale": self.chi2_scale,
            "utilisation": self.utilisation, "profile": self.profile,
            "warnings": list(self.warnings),
        })
