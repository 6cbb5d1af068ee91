"""Creep-curve points, the phase predicted by the rigid-wheel theory, and the saturation onset.

Theory (the constant of Eq. 1 of the V-Track paper): a rigid wheel of inertia J
[kg m^2], rolling radius R [m], normal load N [N] and speed V [m/s], modulated at
Omega = 2*pi*f_mod [rad/s], whose creep coefficient is k = dCoA/dxi, has the wheel speed
lagging the torque by ``phi = atan(C/k)`` with ``C = Omega*J*V/(R^2*N)`` [-].
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from torquemod.errors import InputError

if TYPE_CHECKING:  # pandas is slow to import; only the annotation needs it
    import pandas as pd

__all__ = [
    "ONSET_CRITERIA",
    "CreepPoints",
    "OnsetResult",
    "TheoryCheck",
    "creep_points",
    "fit_theory_constant",
    "phase_from_constant_deg",
    "saturation_onset",
    "theory_check",
    "theory_constant",
    "time_constant_s",
]

REQUIRED_COLUMNS = ("step", "creepage", "coa")
ONSET_CRITERIA = ("tan_ratio", "phase", "creep_coefficient", "either", "both")


@dataclass(frozen=True)
class CreepPoints:
    """Creep-curve points, one per torque step, sorted by step.

    Attributes
    ----------
    step : ndarray of int
        The torque step.
    dc_torque_nm : ndarray
        The step's DC torque [N*m].
    creepage : ndarray
        Mean longitudinal creepage over the step's cycles [-].
    creepage_std : ndarray
        Its standard deviation over cycles [-].
    creepage_se : ndarray
        Its standard error ``std/sqrt(n_cycles)`` [-] (NaN when unknown).
    coa : ndarray
        Mean coefficient of adhesion over cycles [-].
    coa_std : ndarray
        Its standard deviation over cycles [-].
    coa_se : ndarray
        Its standard error [-] (NaN when unknown).
    phase_deg : ndarray
        Mean phase lag of the wheel speed behind the torque [deg].
    phase_std_deg : ndarray
        Its standard deviation over cycles [deg].
    n_cycles : ndarray of int
        Cycles averaged.
    """

    step: np.ndarray
    dc_torque_nm: np.ndarray
    creepage: np.ndarray
    creepage_std: np.ndarray
    creepage_se: np.ndarray
    coa: np.ndarray
    coa_std: np.ndarray
    coa_se: np.ndarray
    phase_deg: np.ndarray
    phase_std_deg: np.ndarray
    n_cycles: np.ndarray

    def __len__(self) -> int:
        return int(self.step.size)


def creep_points(steps_df: pd.DataFrame) -> CreepPoints:
    """Creep-curve points from a steps table, sorted by step.

    Parameters
    ----------
    steps_df : pandas.DataFrame
        A ``steps.csv`` table: ``step``, ``creepage`` [-] and ``coa`` [-] are required;
        ``dc_torque_nm`` [N*m], ``phase_deg``, ``phase_std_deg`` [deg], ``creepage_std``,
        ``coa_std`` [-] and ``n_cycles`` are used when present. Rows with a non-finite
        creepage or CoA are dropped.

    Returns
    -------
    CreepPoints
        One point per step, with the standard error of the CoA ``coa_std/sqrt(n_cycles)``.

    Raises
    ------
    InputError
        A required column is missing or no row is finite.
    """
    missing = [c for c in REQUIRED_COLUMNS if c not in steps_df.columns]
    if missing:
        raise InputError(f"steps table lacks column(s) {missing}",
                         hint="pass the steps.csv written by 'torquemod process'")
    df = steps_df.sort_values("step")
    df = df[np.isfinite(df["creepage"].to_numpy(float)) & np.isfinite(df["coa"].to_numpy(float))]
    if df.empty:
        raise InputError("no step has a finite creepage and CoA")

    def col(name, default=np.nan):
        if name in df.columns:
            return df[name].to_numpy(dtype=float)
        return np.full(len(df), default, dtype=float)

    n = col("n_cycles")
    with np.errstate(invalid="ignore", divide="ignore"):
        root_n = np.where(n > 0, np.sqrt(n), np.nan)
        xi_std, coa_std = col("creepage_std"), col("coa_std")
        return CreepPoints(
            step=df["step"].to_numpy(dtype=int), dc_torque_nm=col("dc_torque_nm"),
            creepage=col("creepage"), creepage_std=xi_std, creepage_se=xi_std / root_n,
            coa=col("coa"), coa_std=coa_std, coa_se=coa_std / root_n,
            phase_deg=col("phase_deg"), phase_std_deg=col("phase_std_deg"), n_cycles=n)


def theory_constant(*, inertia_kg_m2, speed_m_s, wheel_radius_m, normal_load_n, frequency_hz):
    """Rigid-wheel constant ``C = Omega*J*V/(R^2*N)`` of ``tan(phi) = C/k``.

    A rigid wheel modulated at ``Omega = 2*pi*f`` whose creep coefficient is
    ``k = dCoA/dxi`` has its speed lagging the torque by ``phi = atan(C/k)``.

    Parameters
    ----------
    inertia_kg_m2 : float
        Wheel (wheelset) inertia J [kg m^2].
    speed_m_s : float or array_like
        Rolling speed V [m/s].
    wheel_radius_m : float or array_like
        Rolling radius R [m].
    normal_load_n : float or array_like
        Normal load N [N].
    frequency_hz : float or array_like
        Modulation frequency f [Hz].

    Returns
    -------
    float or ndarray
        C [-].

    Notes
    -----
    Eq. (1) of [1]_ states ``tan(phi)`` proportional to ``1/k``; C is the constant of
    proportionality for a rigid wheel, ``J*d(omega)/dt = T - R*N*CoA``, linearised about
    the operating point and driven at ``Omega``.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).

    Examples
    --------
    >>> import math
    >>> c = theory_constant(inertia_kg_m2=1.0, speed_m_s=1.0, wheel_radius_m=1.0,
    ...                     normal_load_n=2 * math.pi, frequency_hz=1.0)
    >>> round(float(c), 12)
    1.0
    """
    omega = 2.0 * np.pi * np.asarray(frequency_hz, dtype=float)
    return (omega * inertia_kg_m2 * np.asarray(speed_m_s, dtype=float)
            / (np.asarray(wheel_radius_m, dtype=float) ** 2 * np.asarray(normal_load_n, float)))


def time_constant_s(*, inertia_kg_m2, speed_m_s, wheel_radius_m, normal_load_n,
                    creep_coefficient):
    """Time constant ``tau = J*V/(R^2*N*k)`` with which the rigid wheel's speed relative to
    the rail settles at creep coefficient k.

    The same model as :func:`theory_constant`: ``tan(phi) = Omega*tau = C/k``. It grows
    without bound towards the creep curve's peak (k -> 0).

    Parameters
    ----------
    inertia_kg_m2, speed_m_s, wheel_radius_m, normal_load_n
        J [kg m^2], V [m/s], R [m], N [N] as for :func:`theory_constant`.
    creep_coefficient : float or array_like
        k = dCoA/dxi [-].

    Returns
    -------
    float or ndarray
        tau [s]; inf at k = 0.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
    k = np.asarray(creep_coefficient, dtype=float)
    with np.errstate(divide="ignore"):
        return (inertia_kg_m2 * np.asarray(speed_m_s, dtype=float)
                / (np.asarray(wheel_radius_m, dtype=float) ** 2
                   * np.asarray(normal_load_n, dtype=float) * k))


def phase_from_constant_deg(constant, creep_coefficient):
    """Rigid-wheel phase lag ``phi = atan2(C, k)`` of the wheel speed behind the torque.

    Parameters
    ----------
    constant : float or array_like
        C [-] (:func:`theory_constant`).
    creep_coefficient : float or array_like
        k = dCoA/dxi [-].

    Returns
    -------
    float or ndarray
        phi [deg]: 90 deg at k = 0, beyond 90 deg for k < 0 (the falling branch of the
        creep curve, where the small-signal wheel is unstable).

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).

    Examples
    --------
    >>> float(phase_from_constant_deg(1.0, 1.0))
    45.0
    >>> float(phase_from_constant_deg(1.0, 0.0))
    90.0
    """
    return np.degrees(np.arctan2(np.asarray(constant, dtype=float),
                                 np.asarray(creep_coefficient, dtype=float)))


def fit_theory_constant(phase_deg, creep_coefficient) -> tuple[float, float, int]:
    """One constant C for all steps: least squares of ``tan(phi_measured)`` on ``1/k``
    through the origin, the model ``tan(phi) = C/k``.

    Parameters
    ----------
    phase_deg : array_like
        Measured phase lag per step [deg]; points with 0 < |phi| < 90 deg are used.
    creep_coefficient : array_like
        k = dCoA/dxi per step [-]; points with k > 0 are used.

    Returns
    -------
    tuple of (float, float, int)
        C [-], its standard error [-] and the number of points used; NaNs and 0 when no
        point is usable (the standard error is NaN with one point).

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).

    Examples
    --------
    >>> c, se, n = fit_theory_constant([45.0, 63.43494882292201], [1.0, 0.5])
    >>> round(c, 9), n
    (1.0, 2)
    """
    phi = np.radians(np.asarray(phase_deg, dtype=float))
    k = np.asarray(creep_coefficient, dtype=float)
    ok = np.isfinite(phi) & np.isfinite(k) & (k > 0) & (np.abs(phi) < np.pi / 2)
    if not np.any(ok):
        return np.nan, np.nan, 0
    u, y = 1.0 / k[ok], np.tan(phi[ok])
    c = float(np.sum(u * y) / np.sum(u * u))
    m = int(ok.sum())
    se = float(np.sqrt(np.sum((y - c * u) ** 2) / (m - 1) / np.sum(u * u))) if m > 1 else np.nan
    return c, se, m


@dataclass(frozen=True)
class TheoryCheck:
    """Measured against predicted rigid-wheel phase per step.

    Attributes
    ----------
    mode : {"rig", "fitted"}
        C from the rig parameters, or one C fitted across the steps.
    constant : ndarray
        C = Omega*J*V/(R^2*N) per step [-].
    constant_stderr : float
        Standard error of a fitted C [-]; NaN in ``rig`` mode.
    creep_coefficient : ndarray
        k = dCoA/dxi per step [-].
    phase_measured_deg : ndarray
        Measured phase per step [deg].
    phase_theory_deg : ndarray
        ``atan(C/k)`` per step [deg].
    difference_deg : ndarray
        Measured minus theory [deg].
    rms_difference_deg : float
        RMS of the finite differences [deg].
    max_abs_difference_deg : float
        Largest |difference| [deg].
    n_used : int
        Steps compared (finite difference).

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """

    mode: str
    constant: np.ndarray
    constant_stderr: float
    creep_coefficient: np.ndarray
    phase_measured_deg: np.ndarray
    phase_theory_deg: np.ndarray
    difference_deg: np.ndarray
    rms_difference_deg: float
    max_abs_difference_deg: float
    n_used: int

    def to_dict(self) -> dict:
        c = np.unique(self.constant[np.isfinite(self.constant)])
        return {
            "mode": self.mode,
            "formula": "tan(phi) = C / k,  C = 2*pi*f_mod*J*V / (R^2*N)",
            "constant": float(c[0]) if c.size == 1 else self.constant.tolist(),
            "constant_stderr": self.constant_stderr,
            "rms_difference_deg": self.rms_difference_deg,
            "max_abs_difference_deg": self.max_abs_difference_deg,
            "n_steps_compared": self.n_used,
        }


def theory_check(phase_deg, creep_coefficient, *, constant=None) -> TheoryCheck:
    """Compare measured phases with the rigid-wheel prediction ``atan(C/k)``.

    Parameters
    ----------
    phase_deg : array_like
        Measured phase lag per step [deg].
    creep_coefficient : array_like
        k = dCoA/dxi per step [-].
    constant : float or array_like, optional
        C [-] from the rig (scalar or per step, :func:`theory_constant`); when None it is
        fitted with :func:`fit_theory_constant`.

    Returns
    -------
    TheoryCheck
        Predicted against measured phase per step [deg] and the C used.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
    phase = np.asarray(phase_deg, dtype=float)
    k = np.asarray(creep_coefficient, dtype=float)
    if constant is None:
        c, se, _ = fit_theory_constant(phase, k)
        mode = "fitted"
    else:
        c, se, mode = constant, np.nan, "rig"
    c_arr = np.broadcast_to(np.asarray(c, dtype=float), phase.shape).copy()
    theory = phase_from_constant_deg(c_arr, k)
    diff = phase - theory
    ok = np.isfinite(diff)
    rms = float(np.sqrt(np.mean(diff[ok] ** 2))) if ok.any() else np.nan
    mx = float(np.max(np.abs(diff[ok]))) if ok.any() else np.nan
    return TheoryCheck(mode, c_arr, float(se), k, phase, theory, diff, rms, mx, int(ok.sum()))


@dataclass(frozen=True)
class OnsetResult:
    """Saturation-onset indicator (:func:`saturation_onset`).

    Attributes
    ----------
    step : int or None
        The first step meeting the criterion; None when none does.
    index : int or None
        Its index in the arrays given.
    criterion : str
        The criterion used (``tan_ratio``, ``phase``, ``creep_coefficient``, ``either``,
        ``both``).
    threshold_deg : float
        The phase-rise threshold ``max(k_sigma*pooled std, min_jump_deg)`` [deg].
    pooled_phase_std_deg : float
        Pooled standard deviation of the phase over cycles [deg].
    phase_jumps_deg : list of float or None
        Phase rise from each step to the next (n - 1 values; None where not finite)
        [deg].
    creep_coefficient_ratios : list of float or None
        Each step's k over the previous step's (n - 1 values) [-].
    parameters : dict
        The criterion's settings (``k_sigma`` [-], ``min_jump_deg`` [deg], ``rel_k_drop`` [-],
        ``tan_ratio`` [-], ``baseline_steps``).
    tan_ratios : list of float or None
        tan(phase) over its low-torque value (the median over the first
        ``baseline_steps``), per step [-]; by Eq. (1) of [1]_ the inverse ratio of creep
        coefficients.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """

    step: int | None
    index: int | None
    criterion: str
    threshold_deg: float
    pooled_phase_std_deg: float
    phase_jumps_deg: list = field(default_factory=list)
    creep_coefficient_ratios: list = field(default_factory=list)
    parameters: dict = field(default_factory=dict)
    tan_ratios: list = field(default_factory=list)

    def describe(self) -> str:
        p = self.parameters
        rule = (f"phase rise over the previous step > max({p['k_sigma']:g} x pooled phase std "
                f"{self.pooled_phase_std_deg:.3g} deg, {p['min_jump_deg']:g} deg) = "
                f"{self.threshold_deg:.3g} deg")
        krule = (f"creep coefficient below {1 - p['rel_k_drop']:.0%} of the previous step's")
        trule = (f"tan(phase) at least {p.get('tan_ratio', 2.0):g} x its low-torque value "
                 f"(the median over the first {p.get('baseline_steps', 2)} steps), i.e. the "
                 "creep coefficient (Eq. 1) fallen by that factor, and the rise above "
                 f"{p['k_sigma']:g} x the pooled phase std")
        text = {"tan_ratio": trule, "phase": rule, "creep_coefficient": krule,
                "either": f"{rule}, or {krule}", "both": f"{rule}, and {krule}"}[self.criterion]
        where = f"step {self.step}" if self.step is not None else "no step"
        return f"saturation onset: {where} (criterion: {text})"

    def to_dict(self) -> dict:
        return {"step": self.step, "criterion": self.criterion,
                "threshold_deg": self.threshold_deg,
                "pooled_phase_std_deg": self.pooled_phase_std_deg,
                "phase_jumps_deg": self.phase_jumps_deg,
                "creep_coefficient_ratios": self.creep_coefficient_ratios,
                "tan_ratios": self.tan_ratios,
                "parameters": self.parameters, "description": self.describe()}


def saturation_onset(step, phase_deg, phase_std_deg=None, creep_coefficient=None, *,
                     criterion: str = "tan_ratio", k_sigma: float = 3.0,
                     min_jump_deg: float = 5.0, rel_k_drop: float = 0.5,
                     tan_ratio: float = 2.0, baseline_steps: int = 2) -> OnsetResult:
    """First step at which the phase rises sharply (the onset of friction saturation).

    Steps are taken in the given (DC-torque) order. Step i (i >= 1) is flagged by

    * ``"tan_ratio"`` (default): ``tan(phi_i) >= tan_ratio * tan(phi_0)`` with ``tan(phi_0)``
      the median over the first ``baseline_steps`` steps, and ``phi_i - phi_0 >
      k_sigma * s_pooled``. By Eq. (1) of the V-Track paper (tan(phi) ~ 1/k) this is where the
      creep coefficient has fallen to ``1/tan_ratio`` of its low-torque (linear) value;
    * ``"phase"``: ``phi_i - phi_{i-1} > max(k_sigma * s_pooled, min_jump_deg)`` where
      ``s_pooled = sqrt(mean(phase_std^2))`` over the steps (0 when unknown);
    * ``"creep_coefficient"``: ``k_i < (1 - rel_k_drop) * k_{i-1}`` (slope of the fitted curve);
    * ``"either"`` / ``"both"``: the union / intersection of the two.

    Parameters
    ----------
    step : array_like
        Step numbers, in DC-torque order.
    phase_deg : array_like
        Phase lag per step [deg].
    phase_std_deg : array_like, optional
        Its standard deviation per step [deg]; unknown counts as 0.
    creep_coefficient : array_like, optional
        k = dCoA/dxi per step [-] (needed by the ``"creep_coefficient"`` criterion).
    criterion : {"tan_ratio", "phase", "creep_coefficient", "either", "both"}
        As above.
    k_sigma : float, default 3.0
        Significance of a rise, in pooled standard deviations [-].
    min_jump_deg : float, default 5.0
        Smallest phase jump flagged by ``"phase"`` [deg].
    rel_k_drop : float, default 0.5
        Relative fall of k flagged by ``"creep_coefficient"`` [-].
    tan_ratio : float, default 2.0
        Rise of ``tan(phi)`` over the baseline flagged by ``"tan_ratio"`` [-].
    baseline_steps : int, default 2
        Low-torque steps whose median phase is the baseline.

    Returns
    -------
    OnsetResult
        The first flagged step (None when no step meets the criterion) and why.

    Raises
    ------
    InputError
        Unknown ``criterion``.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
    if criterion not in ONSET_CRITERIA:
        raise InputError(f"unknown onset criterion {criterion!r}; choose one of {ONSET_CRITERIA}")
    step = np.asarray(step)
    phi = np.asarray(phase_deg, dtype=float)
    sd = (np.full(phi.shape, np.nan) if phase_std_deg is None
          else np.asarray(phase_std_deg, dtype=float))
    good = np.isfinite(sd)
    pooled = float(np.sqrt(np.mean(sd[good] ** 2))) if good.any() else 0.0
    threshold = max(k_sigma * pooled, min_jump_deg)
    jumps = np.diff(phi)
    phase_hit = np.concatenate([[False], np.nan_to_num(jumps, nan=-np.inf) > threshold])
    if creep_coefficient is None:
        k_hit = np.zeros(phi.shape, dtype=bool)
        ratios = np.full(max(phi.size - 1, 0), np.nan)
        if criterion not in ("phase", "tan_ratio"):
            raise InputError(f"criterion {criterion!r} needs the creep coefficients")
    else:
        k = np.asarray(creep_coefficient, dtype=float)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratios = k[1:] / k[:-1]
        k_hit = np.concatenate([[False], np.nan_to_num(ratios, nan=np.inf) < 1 - rel_k_drop])
    nb = int(min(max(baseline_steps, 1), phi.size))
    tan_phi = np.tan(np.radians(phi))
    base_tan = float(np.median(tan_phi[:nb])) if phi.size else np.nan
    base_phi = float(np.median(phi[:nb])) if phi.size else np.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        t_ratios = tan_phi / base_tan if base_tan > 0 else np.full(phi.shape, np.nan)
    tan_hit = (np.nan_to_num(t_ratios, nan=-np.inf) >= tan_ratio) & (
        np.nan_to_num(phi - base_phi, nan=-np.inf) > k_sigma * pooled)
    tan_hit[:nb] = False
    hit = {"tan_ratio": tan_hit, "phase": phase_hit, "creep_coefficient": k_hit,
           "either": phase_hit | k_hit, "both": phase_hit & k_hit}[criterion]
    idx = np.flatnonzero(hit)
    i = int(idx[0]) if idx.size else None
    return OnsetResult(
        step=None if i is None else int(step[i]), index=i, criterion=criterion,
        threshold_deg=float(threshold), pooled_phase_std_deg=pooled,
        phase_jumps_deg=[None if not np.isfinite(v) else float(v) for v in jumps],
        creep_coefficient_ratios=[None if not np.isfinite(v) else float(v) for v in ratios],
        parameters={"k_sigma": k_sigma, "min_jump_deg": min_jump_deg, "rel_k_drop": rel_k_drop,
                    "tan_ratio": tan_ratio, "baseline_steps": baseline_steps},
        tan_ratios=[None if not np.isfinite(v) else float(v) for v in t_ratios])
