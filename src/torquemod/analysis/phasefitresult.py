"""The result of a fit of the available adhesion from the phase
(:func:`torquemod.analysis.phasefit.fit_mu_from_phase`): a typed container with ``report()``,
``to_dict()`` and the fitted curves."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from torquemod._util.jsonutil import to_jsonable

if TYPE_CHECKING:
    from torquemod.analysis.friction import AdhesionFit

_Z975 = 1.959963984540054


@dataclass
class PhaseMuFit:
    """Result of :func:`fit_mu_from_phase` (CoA, mu, k, C dimensionless; phases [deg]).

    ``mu_estimate``, ``mu_interval_95``, ``mu_lower_bound``: the **available adhesion** (the
    maximum of the adhesion-creepage curve), its 95 % interval (``(lower bound, None)`` when
    not determined) and lower bound; ``adhesion`` the full
    :class:`torquemod.analysis.friction.AdhesionFit` (the interval when closed, mu0, the probe depth
    that would determine it). ``constant`` is C when given; otherwise the observations fix
    k only relative to C and ``initial_slope`` is ``k0/C`` (``k_relative``).
    ``ratio_ka_ks`` is the best member's kA/kS when that member is a Polach law, else NaN.

    The phases follow ``tan(phi) = C/k`` (Eq. 1 of the V-Track torque-modulation paper),
    ``k = dCoA/dxi`` the creep coefficient of the adhesion-creepage law.

    Attributes
    ----------
    mu_estimate : float
        Available adhesion [-] (the maximum of the adhesion-creepage curve).
    mu_determined : bool
        The phases determine it (a closed, narrow enough 95 % interval).
    mu_interval_95 : tuple
        ``(low, high)`` [-]; ``(mu_lower_bound, None)`` when not determined.
    mu_lower_bound : float
        Lower bound of the available adhesion [-].
    mu_stderr_estimate : float or None
        Width of the 95 % interval over ``2*1.96`` [-] when closed, else None.
    constant : float
        Rigid-wheel constant ``C = Omega*J*V/(R^2*N)`` [-] of ``tan(phi) = C/k`` when
        given, else 1.0.
    constant_given : bool
        C was given (from the rig) rather than fitted.
    ratio_ka_ks : float
        kA/kS [-] of the best-fitting Polach law (Polach 2005, Eq. 8), else NaN.
    initial_slope : float
        ``k0`` = dCoA/dxi at xi = 0 [-]; ``k0/C`` when ``k_relative``.
    k_relative : bool
        C unknown, so k is known only relative to C.
    level : float
        The profile's 95 % threshold [-] (chi2 units) that bounds the interval.
    chi2 : float
        Sum of squared standardised phase residuals [-] at the best fit.
    dof : int
        Points minus fitted parameters.
    chi2_scale : float
        Factor (>= 1) by which the interval's chi2 was rescaled for excess scatter [-].
    coa : ndarray
        CoA of the points [-].
    phase_deg, sigma_deg : ndarray
        Measured phase lag and its standard error per point [deg].
    profile : dict
        The chi2 profile over the available adhesion behind the interval.
    warnings : list of str
        What the caller should know.
    adhesion : AdhesionFit or None
        The full fit behind these numbers.
    constant_source : str
        Where C came from: ``"rig inertia"``, ``"amplitudes"`` (measured from the torque and
        wheel-speed amplitudes, no inertia given), ``"given"`` or ``"not given"``.
    constant_rel_se : float
        Relative standard error [-] of a measured C (0 when C is known or not given).

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    .. [2] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
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
    adhesion: AdhesionFit | None = None
    constant_source: str = ""
    constant_rel_se: float = 0.0

    @classmethod
    def from_adhesion(cls, fit, coa, phase_deg, se_deg, constant, *, constant_source: str = "",
                      constant_rel_se: float = 0.0) -> PhaseMuFit:
        """Wrap an :class:`~torquemod.analysis.friction.AdhesionFit` of phases."""
        det = fit.determined
        warnings = []
        if not det:
            why = ("its 95 % range is open above" if not math.isfinite(fit.high) else
                   "the likelihood has separate basins within the 95 % level"
                   if not fit.closed else
                   f"its 95 % range {fit.low:.4f}..{fit.high:.4f} is wider than "
                   f"+-{100 * fit.max_rel_half_width:.0f} % of {fit.estimate:.4f}")
            depth = (f"; a step at {100 * fit.probe_depth:.0f} % of it would determine it"
                     if math.isfinite(fit.probe_depth) else "")
            warnings.append(f"the phase progression does not determine the available "
                            f"adhesion ({why}); it is >= {fit.lower_bound:.4f}{depth}. "
                            "Measure closer to saturation")
        if fit.chi2_scale > 1.0:
            warnings.append(f"the phases scatter {math.sqrt(fit.chi2_scale):.2f}x more than "
                            f"their standard errors about the fit (reduced chi2 "
                            f"{fit.chi2 / fit.dof:.3g}); the interval is widened accordingly")
        given = constant is not None
        polach = fit.law in ("polach", "polach_falling")
        closed = fit.closed
        return cls(
            mu_estimate=fit.estimate, mu_determined=det,
            mu_interval_95=(fit.low, fit.high) if det else (fit.lower_bound, None),
            mu_lower_bound=fit.lower_bound,
            mu_stderr_estimate=(fit.high - fit.low) / (2 * _Z975) if closed else None,
            constant=float(constant) if given else 1.0, constant_given=given,
            ratio_ka_ks=float(fit.params[0]) if polach else math.nan,
            initial_slope=float(fit.k0) * (float(constant) if given else 1.0),
            k_relative=not given, level=fit.level, chi2=fit.chi2, dof=fit.dof,
            chi2_scale=fit.chi2_scale, coa=np.asarray(coa, float),
            phase_deg=np.asarray(phase_deg, float), sigma_deg=np.asarray(se_deg, float),
            profile={"adhesion_available": fit.p_grid, "chi2": fit.profile,
                     "level": fit.level, "n_evaluations": int(fit.p_grid.size)},
            warnings=warnings, adhesion=fit,
            constant_source=constant_source or ("given" if given else "not given"),
            constant_rel_se=float(constant_rel_se))

    def state(self) -> dict:
        """Every field, the adhesion fit's included, JSON-ready with non-finite numbers as the
        text ``"inf"``, ``"-inf"`` or ``"nan"``: what :meth:`from_state` rebuilds the fit
        from."""
        doc = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
               if f.name not in ("adhesion", "profile")}
        doc["adhesion"] = {f.name: getattr(self.adhesion, f.name)
                           for f in dataclasses.fields(self.adhesion)}
        return to_jsonable(_nonfinite_as_text(doc))

    @classmethod
    def from_state(cls, doc: dict) -> PhaseMuFit:
        """The fit back from :meth:`state` (None read as NaN in the numeric fields)."""
        from torquemod.analysis.friction import AdhesionFit

        def back(value, default):
            if isinstance(default, np.ndarray):
                return np.array([float(v) for v in value], dtype=float)
            return float(value)
        a = dict(doc["adhesion"])
        a_types = {"estimate": 0.0, "low": 0.0, "high": 0.0, "lower_bound": 0.0, "mu0": 0.0,
                   "mu0_low": 0.0, "mu0_high": 0.0, "probe_depth": 0.0, "chi2": 0.0,
                   "k0": 0.0, "chi2_scale": 0.0, "max_rel_half_width": 0.0,
                   "model_rel_error": 0.0, "c_max": 0.0, "level": 0.0,
                   "p_grid": np.zeros(0), "profile": np.zeros(0), "best_s": np.zeros(0)}
        for key, default in a_types.items():
            a[key] = back(a[key], default)
        a["params"] = tuple(float(v) for v in a["params"])
        adhesion = AdhesionFit(**a)
        d = dict(doc)
        for key in ("mu_estimate", "mu_lower_bound", "constant", "ratio_ka_ks",
                    "initial_slope", "level", "chi2", "chi2_scale", "constant_rel_se"):
            if key not in d:  # saved before the field existed: its default
                continue
            d[key] = back(d[key], 0.0)
        for key in ("coa", "phase_deg", "sigma_deg"):
            d[key] = back(d[key], np.zeros(0))
        if d["mu_stderr_estimate"] is not None:
            d["mu_stderr_estimate"] = float(d["mu_stderr_estimate"])
        d["mu_interval_95"] = tuple(None if v is None else float(v)
                                    for v in d["mu_interval_95"])
        d["adhesion"] = adhesion
        d["profile"] = {"adhesion_available": adhesion.p_grid, "chi2": adhesion.profile,
                        "level": adhesion.level, "n_evaluations": int(adhesion.p_grid.size)}
        return cls(**d)

    @property
    def mu(self) -> float | None:
        """The available adhesion from the phase [-]; None when the steps do not determine
        it."""
        return self.mu_estimate if self.mu_determined else None

    @property
    def mu_stderr(self) -> float | None:
        """Half the 95 % interval / 1.96 [-]; None when not determined."""
        return self.mu_stderr_estimate if self.mu_determined else None

    @property
    def utilisation(self) -> np.ndarray:
        """CoA_i / available adhesion per step (NaN when it is not determined)."""
        if not self.mu_determined:
            return np.full(self.coa.size, np.nan)
        return self.coa / self.mu_estimate

    def creep_coefficient(self, coa) -> np.ndarray:
        """Fitted small-signal creep coefficient dCoA/dxi [-] at the CoA values (relative to
        C = 1 when ``k_relative``): ``k0*s(CoA/P)`` of the best-fitting law."""
        return self.initial_slope * self.adhesion.creep_ratio(coa)

    def phase_curve(self, coa) -> np.ndarray:
        """Predicted phase [deg] at the CoA values, ``atan(C/k(CoA))`` (small-signal slope:
        a smooth curve; NaN at CoA >= the available adhesion)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.degrees(np.arctan(self.constant / self.creep_coefficient(coa)))

    def report(self) -> str:
        """A few lines of text."""
        a = self.adhesion
        if self.mu_determined:
            lo, hi = self.mu_interval_95
            head = (f"available adhesion from the phase = {self.mu_estimate:.4f} "
                    f"(95 % {lo:.4f} .. {hi:.4f})")
        else:
            rng = (f"; 95 % range {a.low:.4f} .. {a.high:.4f}" if a.closed else "")
            depth = (f"; a step at {100 * a.probe_depth:.0f} % of it would determine it"
                     if math.isfinite(a.probe_depth) else "")
            head = (f"available adhesion from the phase NOT determined by these steps: >= "
                    f"{self.mu_lower_bound:.4f}{rng} (best fit {self.mu_estimate:.4f}"
                    f"{depth})")
        mu0 = (f", mu0 of the law = {a.mu0:.4f}" if a.mu0_identified else
               ", mu0 of the law not identified")
        given = ("not given (k relative to C)" if not self.constant_given else
                 f"from the torque/wheel-speed amplitudes (+-{100 * self.constant_rel_se:.1f} %)"
                 if self.constant_source == "amplitudes" else "given")
        par = (f"  best law {a.law} {tuple(round(v, 3) for v in a.params)}, C {given}, "
               f"k0 = {self.initial_slope:.4g}{mu0}, chi2 = {self.chi2:.3g} (dof {self.dof})")
        lines = ["[[available adhesion from the phase]] tan(phi) = C/k(CoA), broad family "
                 "of creep laws", "  " + head, par]
        lines += [f"  WARNING: {w}" for w in self.warnings]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready dict (non-finite numbers as None)."""
        return to_jsonable({
            "mu": self.mu, "mu_stderr": self.mu_stderr, "mu_estimate": self.mu_estimate,
            "mu_determined": self.mu_determined, "mu_interval_95": list(self.mu_interval_95),
            "mu_lower_bound": self.mu_lower_bound, "constant": self.constant,
            "constant_given": self.constant_given, "constant_source": self.constant_source,
            "constant_rel_se": self.constant_rel_se, "ratio_ka_ks": self.ratio_ka_ks,
            "initial_slope": self.initial_slope, "k_relative": self.k_relative,
            "chi2": self.chi2, "dof": self.dof, "chi2_scale": self.chi2_scale,
            "utilisation": self.utilisation, "profile": self.profile,
            "warnings": list(self.warnings), **self.adhesion.to_dict(),
        })


def _nonfinite_as_text(obj):
    """``obj`` with every non-finite float (also in arrays, lists, tuples and dicts) as its
    text, which ``float()`` reads back."""
    if isinstance(obj, dict):
        return {k: _nonfinite_as_text(v) for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        return _nonfinite_as_text(obj.tolist())
    if isinstance(obj, list | tuple):
        return [_nonfinite_as_text(v) for v in obj]
    if isinstance(obj, float | np.floating) and not math.isfinite(obj):
        return str(float(obj))
    return obj
