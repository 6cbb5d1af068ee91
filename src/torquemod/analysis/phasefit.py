"""The available adhesion from the phase alone: what a rig without a force dynamometer, or a
train, can measure. A thin layer over :func:`torquemod.analysis.friction.
fit_available_adhesion_from_phase` (the one estimator for the rig, the train and the sweep)
that keeps this module's historical names and result type.

The rigid-wheel relation (V-Track paper Eq. 1 with its constant) ``tan(phi_i) = C/k_i``,
``C = Omega*J*V/(R^2*N)``, gives the creep coefficient k up to the scale C at every step; the
fall of k with the utilised adhesion fixes the **available adhesion** (the maximum of the
adhesion-creepage curve) over a broad family of creep laws (:mod:`torquemod.analysis.creeplaws`).
``mu`` in this module's results *is* that available adhesion (for a constant-friction law
whose curve rises to its friction, the friction coefficient itself); the law's own friction
coefficient is ``mu0`` where the data identify it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from torquemod.analysis.friction import CHI2_95, MODEL_REL_ERROR, fit_available_adhesion_from_phase
from torquemod.analysis.phasefitresult import PhaseMuFit
from torquemod.analysis.polachshape import polach_h, polach_h_curvature, polach_h_slope
from torquemod.errors import InputError

__all__ = ["CHI2_95", "MODEL_REL_CONSTANT", "R_BOUNDS", "ConstantEstimate", "PhaseMuFit",
           "constant_from_amplitudes", "fit_mu_from_phase", "polach_h", "polach_h_curvature",
           "polach_h_slope"]

#: bounds of r = kA/kS in the family's Polach members (:mod:`torquemod.analysis.creeplaws`)
R_BOUNDS = (0.3, 7.0)
#: relative model error [-] of C measured from the amplitudes: what the rigid-wheel impedance
#: leaves out (compliance between the torque sensor and the contact, the contact's
#: relaxation, the large swing's harmonics). Measured: the median over six steps within
#: +0.8 % of the true inertia on the digital twin and on an independent rig simulation
#: (docs/friction.md); 2 % keeps that bias well inside one standard error.
MODEL_REL_CONSTANT = 0.02


@dataclass(frozen=True)
class ConstantEstimate:
    """The rigid-wheel constant measured from the modulation (:func:`constant_from_amplitudes`).

    Attributes
    ----------
    constant : float
        C = Omega*J*V/(R^2*N) [-], the median over the steps.
    rel_se : float
        Its relative standard error [-]: the steps' scatter or the phases' noise, and
        :data:`MODEL_REL_CONSTANT`.
    inertia_kg_m2 : float
        The implied wheel inertia J [kg m^2] (NaN without the modulation frequency).
    n : int
        Number of steps it comes from.
    """

    constant: float
    rel_se: float
    inertia_kg_m2: float
    n: int


def constant_from_amplitudes(torque_amplitude_nm, wheel_amplitude_rad_s, phase_deg,
                             phase_se_deg, speed_m_s, frequency_hz, *, wheel_radius_m: float,
                             normal_load_n: float, model_rel: float = MODEL_REL_CONSTANT
                             ) -> ConstantEstimate | None:
    """The constant ``C = Omega*J*V/(R^2*N)`` of ``tan(phi) = C/k`` (V-Track paper Eq. 1)
    from the amplitudes the chain measures, without the wheel's inertia J.

    In the rigid-wheel model behind Eq. 1 the wheel answers the torque ripple dT with the
    speed ripple dw through the impedance ``dT/dw = j*Omega*J + R^2*N*k/V`` (the creep force
    ``N*CoA(xi)`` linearised about the step's creepage, ``dxi = R*dw/V``), so its quadrature
    part is ``Omega*J = sin(phi)*|dT|/|dw|`` and at every step

        C_i = sin(phi_i)*|dT_i|/|dw_i|*V_i/(R^2*N).

    The estimate is the median over the steps; its relative standard error combines the
    steps' scatter (``1.2533*1.4826*MAD/sqrt(n)``, the median's efficiency for a normal
    sample), the phases' standard errors (``se_phi/sin(phi)`` per step, the amplitude ratio's
    relative error taken equal to the phase's in radians, as for one complex ratio) and the
    model error ``model_rel``.

    Parameters
    ----------
    torque_amplitude_nm, wheel_amplitude_rad_s : array_like
        Amplitudes [N*m], [rad/s] of the modulation's first harmonic per step, the torque
        measured between the drive and the wheel, the speed at the wheel.
    phase_deg, phase_se_deg : array_like
        Lag of the wheel speed behind the torque [deg] and its standard error per step.
    speed_m_s, frequency_hz : array_like or float
        Rolling speed V [m/s] and modulation frequency [Hz] per step (the frequency gives
        only the implied inertia; NaN leaves it NaN).
    wheel_radius_m, normal_load_n : float
        R [m] and N [N].
    model_rel : float
        Relative model error [-] of the rigid-wheel impedance.

    Returns
    -------
    ConstantEstimate or None
        None when fewer than two steps give a finite positive value.
    """
    t, w, ph, se, v, f = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (
        torque_amplitude_nm, wheel_amplitude_rad_s, phase_deg, phase_se_deg, speed_m_s,
        frequency_hz)))
    if not (wheel_radius_m > 0 and normal_load_n > 0):
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.sin(np.radians(ph))
        ci = t / w * s * v / (wheel_radius_m**2 * normal_load_n)
        ji = t / w * s / (2.0 * np.pi * f)
        rel_i = np.radians(np.abs(se)) / s
    ok = np.isfinite(ci) & (ci > 0)
    if ok.sum() < 2:
        return None
    ci, ji = ci[ok], ji[ok]
    n = int(ci.size)
    c = float(np.median(ci))
    mad = float(np.median(np.abs(ci / c - 1.0)))
    scatter = 1.2533 * 1.4826 * mad / np.sqrt(n)
    rel_i = rel_i[ok]
    rel_i = rel_i[np.isfinite(rel_i)]
    noise = 1.2533 * float(np.sqrt(np.mean(rel_i**2)) / np.sqrt(n)) if rel_i.size else 0.0
    rel = float(np.sqrt(max(scatter, noise) ** 2 + model_rel**2))
    return ConstantEstimate(constant=c, rel_se=rel, inertia_kg_m2=float(np.median(ji)), n=n)


def _clean(name: str, x, n: int | None = None) -> np.ndarray:
    arr = np.asarray(x, dtype=float).ravel()
    if n is not None and arr.size != n:
        raise InputError(f"{name} has {arr.size} values, expected {n} (one per step)",
                         hint="give one value per torque step")
    return arr


def fit_mu_from_phase(coa, phase_deg, phase_se_deg, *, constant=None, creepage_swing=None,
                      coa_se=None, max_rel_half_width: float = 0.10, scale_by_chi2: bool = True,
                      ratio_bounds: tuple[float, float] = R_BOUNDS,
                      model_rel_error: float = MODEL_REL_ERROR,
                      speed_m_s: float | None = None, constant_rel_se: float = 0.0,
                      constant_source: str | None = None, probe: bool = True) -> PhaseMuFit:
    """The available adhesion from the phase progression of a rig's torque steps.

    Steps with a non-finite value, a phase outside (0, 90) deg or a non-positive standard
    error are left out; at least four must remain. A thin layer over
    :func:`torquemod.analysis.friction.fit_available_adhesion_from_phase`.

    Parameters
    ----------
    coa : array_like
        Utilised adhesion CoA per step [-].
    phase_deg : array_like
        Lag of the wheel speed behind the torque per step [deg].
    phase_se_deg : array_like
        Standard error of ``phase_deg`` [deg].
    constant : float or None
        C = Omega*J*V/(R^2*N) [-] when known; None: ``k0/C`` is fitted (the adhesion does not
        need C).
    creepage_swing : array_like or None
        Creepage swing amplitude per step [-]; None: small-signal slopes.
    coa_se : array_like or None
        Standard error of ``coa`` [-]; None: 0.
    max_rel_half_width : float
        The adhesion counts as determined when its 95 % interval is closed and at most this
        fraction of the estimate wide on either side [-]. Default 0.10.
    scale_by_chi2 : bool
        Widen the interval by the reduced chi2 when it exceeds 1. Default True.
    ratio_bounds : tuple of float
        Range of r = kA/kS of the family's Polach members [-] (a narrower range is a prior on
        the curve's shape); within :data:`R_BOUNDS`. Default :data:`R_BOUNDS`.
    model_rel_error : float
        Relative model error per step [-]. Default
        :data:`~torquemod.analysis.friction.MODEL_REL_ERROR`.
    speed_m_s : float or None
        Rolling speed V [m/s]; with C it bounds how far the friction can fall with the slip
        velocity. Default None.
    constant_rel_se : float
        Relative standard error of C when it was measured [-]
        (:func:`constant_from_amplitudes`). Default 0.
    constant_source : str or None
        Where C came from (``"rig inertia"``, ``"amplitudes"``, ...); default ``"given"``,
        or ``"not given"`` without C.
    probe : bool
        When the adhesion is not determined, also find the probe depth (utilisation of one
        more step) that would determine it; False leaves it NaN and changes nothing else.
        Default True.

    Returns
    -------
    PhaseMuFit
        ``mu`` (the available adhesion, the maximum of the adhesion-creepage curve [-]), its
        95 % interval, whether it is determined, the lower bound, ``mu0`` where identified.

    Raises
    ------
    InputError
        Arrays of different lengths, C not positive, ``ratio_bounds`` outside
        :data:`R_BOUNDS`, fewer than four usable steps, or no creep law of the family fits
        (every step beyond the curves' peaks).

    Notes
    -----
    The rigid-wheel relation ``tan(phi_i) = C/k_i`` [1]_ (Eq. 1) gives the creep coefficient
    k up to the scale C at every step: ``y_i = cot(phi_i) = k_i/C`` with standard error
    ``se_phi/sin^2(phi)``. The fall of k with CoA, ``k = k0*s(CoA/P; theta)``, fixes the
    available adhesion P over a family of creep laws (Polach [2]_, Burckhardt [3]_ and
    saturating laws); the 95 % interval is the profile-likelihood set
    ``chi2(P) <= chi2_min + 3.84*max(1, chi2_min/dof)`` [4]_.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    .. [2] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (3), (8), (9).
    .. [3] M. Burckhardt, "Fahrwerktechnik: Radschlupf-Regelsysteme", Vogel, Würzburg 1993.
    .. [4] S.S. Wilks, "The large-sample distribution of the likelihood ratio for testing
       composite hypotheses", Ann. Math. Statist. 9(1) (1938) 60-62.
    """
    coa = np.abs(_clean("coa", coa))
    n = coa.size
    phase = _clean("phase_deg", phase_deg, n)
    se = _clean("phase_se_deg", phase_se_deg, n)
    swing = None if creepage_swing is None else np.abs(_clean("creepage_swing",
                                                             creepage_swing, n))
    c_se = None if coa_se is None else _clean("coa_se", coa_se, n)
    if constant is not None and not (np.isfinite(constant) and constant > 0):
        raise InputError(f"the constant C = {constant} must be a positive number",
                         hint="C = Omega*J*V/(R^2*N); pass None to fit it")
    lo, hi = (float(b) for b in ratio_bounds)
    if not (R_BOUNDS[0] <= lo <= hi <= R_BOUNDS[1]):
        raise InputError(f"ratio_bounds {ratio_bounds} must lie within {R_BOUNDS}",
                         hint="r = kA/kS: 0.3 <= low <= high <= 7")
    ok = (np.isfinite(coa) & (coa > 0) & np.isfinite(phase) & np.isfinite(se) & (se > 0)
          & (phase > 0) & (phase < 90))
    if ok.sum() < 4:
        raise InputError("the available adhesion from the phase needs at least 4 steps with "
                         f"a finite CoA > 0 and a phase between 0 and 90 deg, got "
                         f"{int(ok.sum())}", hint="measure more torque steps")
    if swing is not None and not np.any(swing[ok] > 0):
        swing = None
    fit = fit_available_adhesion_from_phase(
        coa[ok], phase[ok], se[ok], constant=constant,
        creepage_swing=None if swing is None else swing[ok],
        coa_se=None if c_se is None else c_se[ok], model_rel_error=model_rel_error,
        max_rel_half_width=max_rel_half_width, scale_by_chi2=scale_by_chi2,
        ratio_bounds=(lo, hi),
        speed_m_s=speed_m_s if speed_m_s is not None and np.isfinite(speed_m_s) else None,
        constant_rel_se=constant_rel_se if constant is not None else 0.0, probe=probe)
    if fit is None:
        raise InputError("the phase progression fits no creep law of the family (every "
                         "step lies beyond the curves' peaks)",
                         hint="check the steps' CoA and phases")
    source = constant_source or ("given" if constant is not None else "not given")
    return PhaseMuFit.from_adhesion(fit, coa[ok], phase[ok], se[ok], constant,
                                    constant_source=source,
                                    constant_rel_se=float(constant_rel_se)
                                    if constant is not None else 0.0)
