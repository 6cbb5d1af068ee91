"""The fit stage, in memory: creep points -> Polach fit -> mu from the phase -> theory check
-> saturation onset.

:func:`analyze` takes a :class:`~torquemod.processing.pipeline.ProcessResult` and returns an
:class:`~torquemod.analysis.result.Analysis`. Everything comes from the result and its
experiment: the per-step tables, the per-cycle means (normal load, lateral force), the
measured modulation frequencies and the rig (radius, inertia, contact stiffness). Nothing is
read from files. The extended steps table gains the columns :data:`ADDED_STEP_COLUMNS`:

* ``torque_pct_saturation`` DC torque as % of ``Ts = mu*N*Rw`` (mu from the forces, else
  from the phase: :func:`saturation_torque`; NaN when neither determines mu),
* ``creep_coefficient`` dCoA/dxi of the fitted curve at the step's creepage [-],
* ``phase_theory_deg`` the rigid-wheel phase ``atan(C/k)`` [deg] (see
:mod:`torquemod.analysis.creep`),
* ``phase_fit_deg`` the phase of the fit that gives mu from the phase [deg],
* ``utilisation_phase`` CoA/mu with mu from the phase [-].

Steps flagged as slipping keep their rows but are left out of the Polach fit, with a warning.
With the rig's ``wheel_inertia_kg_m2`` (J [kg m^2]) the theory constant
``C = 2*pi*f_mod*J*V/(R^2*N)`` is computed per step (f_mod the mean measured modulation
frequency, V the mean speed, N the mean measured normal load of the step, falling back to the
nominal test values); without it, one C is fitted across the steps.
"""

from __future__ import annotations

import inspect
from datetime import UTC, datetime
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from torquemod.analysis.creep import (
    creep_points,
    saturation_onset,
    theory_check,
    theory_constant,
)
from torquemod.analysis.fit import fit_polach
from torquemod.analysis.options import FitOptions
from torquemod.analysis.result import Analysis
from torquemod.errors import InputError, OptionError, ProcessingError

if TYPE_CHECKING:
    from torquemod.processing.pipeline import ProcessResult

__all__ = ["ADDED_STEP_COLUMNS", "Analysis", "FitOptions", "analyze",
           "saturation_torque"]

ADDED_STEP_COLUMNS = ("torque_pct_saturation", "creep_coefficient", "phase_theory_deg",
                      "phase_fit_deg", "utilisation_phase")


def per_step_means(result: ProcessResult, steps: np.ndarray) -> dict:
    """Per-step means of speed, normal load, modulation frequency and lateral share of CoA.

    From the result's tables and per-cycle means; the load and frequency fall back to the
    nominal test values where not measured.

    Parameters
    ----------
    result : ProcessResult
        The processing result.
    steps : ndarray of int
        The steps wanted.

    Returns
    -------
    dict of str to ndarray
        One value per step: ``speed_m_s`` mean speed [m/s], ``fz_n`` normal load [N],
        ``freq_hz`` modulation frequency [Hz] and ``lateral_coa`` |Fy|/Fz [-] (when
        recorded).
    """
    test = result.experiment.test
    idx = pd.Index(steps, name="step")
    details = pd.DataFrame(result.cycle_details)
    out = {"speed_m_s": np.full(steps.size, np.nan), "fz_n": np.full(steps.size, np.nan),
           "lateral_coa": np.full(steps.size, np.nan)}
    table = result.steps.set_index("step")
    if "speed_m_s" in table:
        out["speed_m_s"] = pd.to_numeric(table["speed_m_s"]).reindex(idx).to_numpy(float)
    if not details.empty:
        num = {c: pd.to_numeric(details[c], errors="coerce") for c in ("fy_n", "fz_n")
               if c in details}
        if "fz_n" in num:
            frame = pd.DataFrame({"step": details["step"], "fz_n": num["fz_n"]})
            if "fy_n" in num:
                frame["lateral_coa"] = (num["fy_n"] / num["fz_n"]).abs()
            g = frame.groupby("step").mean()
            for col in g.columns:
                out[col] = g[col].reindex(idx).to_numpy(float)
    out["freq_hz"] = result.cycles.groupby("step")["modulation_hz"].mean().reindex(
        idx).to_numpy(float)
    out["fz_n"] = np.abs(np.where(np.isfinite(out["fz_n"]), out["fz_n"], test.normal_load_n))
    out["freq_hz"] = np.where(np.isfinite(out["freq_hz"]), out["freq_hz"],
                              test.modulation_frequency_hz)
    return out


def _rig_value(result: ProcessResult, key: str, override):
    """An option, else the rig's extra key (e.g. ``wheel_inertia_kg_m2``), else None."""
    if override is not None:
        return override
    value = result.experiment.rig.extra.get(key)
    return None if value is None else float(value)


def analyze(result: ProcessResult, options: FitOptions | dict | None = None, **fit_options
            ) -> Analysis:
    """The fit stage on a processed experiment, in memory.

    Fits Polach's creep-force curve (Polach 2005, Eqs. 3, 8 and 9) to the steps' creepage
    [-] and coefficient of adhesion [-], and the friction coefficient from the measured
    phase lags through ``tan(phi) = C/k`` (Eq. 1 of the V-Track paper).

    Parameters
    ----------
    result : ProcessResult
        What :func:`torquemod.process` (or :func:`torquemod.load`) returned.
    options : FitOptions or dict, optional
        :class:`FitOptions` fields as an instance or a mapping.
    **fit_options
        Single :class:`FitOptions` fields over ``options`` (keywords win), e.g.
        ``analyze(res, velocity_dependent=True)``.

    Returns
    -------
    Analysis
        The creep points, the Polach fit, the phase fit and their summaries.

    Raises
    ------
    InputError
        ``result`` is not a :class:`ProcessResult` or an option is invalid.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
    .. [2] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
    _require_process_result(result)
    base = FitOptions.coerce(options)
    opts = FitOptions.coerce({**base.__dict__, **fit_options}) if fit_options else base
    steps_df = result.steps.reset_index(drop=True)
    warnings: list[str] = []
    pts = creep_points(steps_df)
    per = per_step_means(result, pts.step)
    slip = dict(zip(steps_df["step"].astype(int), steps_df["slip"].astype(bool), strict=True))
    use = np.array([not slip.get(int(s), False) for s in pts.step], dtype=bool)
    if not use.all():
        warnings.append(f"step(s) {[int(s) for s in pts.step[~use]]} flagged as slipping "
                        "(steps.csv 'slip'; see provenance.json warnings) are left out of the "
                        "Polach fit")
    stiffness = _rig_value(result, "contact_stiffness", opts.stiffness)
    fit, skipped = _polach_stage(opts, pts, per, use, stiffness, steps_df)
    if skipped:
        warnings.append(f"the Polach fit of the creep curve was skipped: {skipped}")
    else:
        warnings += fit.warnings

    radius = result.experiment.rig.wheel_radius_m
    n_nom = result.experiment.test.normal_load_n

    inertia = _rig_value(result, "wheel_inertia_kg_m2", opts.inertia_kg_m2)
    constant, rig_args = opts.theory_constant, None
    if constant is None and inertia is not None:
        if all(np.all(np.isfinite(per[k])) for k in ("speed_m_s", "fz_n", "freq_hz")):
            rig_args = {"inertia_kg_m2": inertia, "speed_m_s": per["speed_m_s"],
                        "wheel_radius_m": radius, "normal_load_n": per["fz_n"],
                        "frequency_hz": per["freq_hz"]}
            constant = theory_constant(**rig_args)
        else:
            warnings.append("wheel inertia given but speed, load or frequency per step is "
                            "missing: the theory constant is fitted instead")
    source = ("rig inertia" if rig_args is not None else
              "given" if constant is not None else None)
    pfit, p_skipped = _phase_fit(steps_df, pts, use, constant, measured_c=(radius, n_nom),
                                 source=source, probe=opts.probe)
    if pfit is None:
        warnings.append(f"mu from the phase was not estimated: {p_skipped}")
    else:
        warnings += [f"mu from the phase: {w}" for w in pfit.warnings]
        if pfit.constant_source == "amplitudes":
            warnings.append(f"mu from the phase: C = {pfit.constant:.4g} "
                            f"(+-{100 * pfit.constant_rel_se:.1f} %) measured from the "
                            "torque/wheel-speed amplitude ratio (no rig inertia given)")
    ts, ts_se, ts_source = saturation_torque(fit, pfit, normal_load_n=n_nom,
                                             wheel_radius_m=radius)
    pct = 100.0 * pts.dc_torque_nm / ts if ts else np.full(len(pts), np.nan)
    coa_phase = _step_column(steps_df, "coa_torque")
    if coa_phase is None or not np.all(np.isfinite(coa_phase[use])):
        coa_phase = pts.coa
    nan = np.full(len(pts), np.nan)
    phase_fit_deg = np.asarray(pfit.phase_curve(coa_phase), float) if pfit else nan
    util_phase = coa_phase / pfit.mu if pfit is not None and pfit.mu else nan

    if fit is not None:
        k = fit.slope(pts.creepage, per["speed_m_s"] if fit.velocity_dependent else None)
    elif pfit is not None:
        k = np.asarray(pfit.creep_coefficient(coa_phase), float)
    else:
        k = nan
    tc = theory_check(pts.phase_deg, k, constant=constant)
    phase_theory = tc.phase_theory_deg  # atan(C/k), C from the rig when rig_args are known
    if tc.mode == "fitted" and tc.n_used < 2:
        warnings.append("too few usable steps to fit the theory constant")
    onset = saturation_onset(pts.step, pts.phase_deg, pts.phase_std_deg, k,
                             criterion=opts.onset_criterion, k_sigma=opts.onset_k_sigma,
                             min_jump_deg=opts.onset_min_jump_deg,
                             rel_k_drop=opts.onset_rel_k_drop, tan_ratio=opts.onset_tan_ratio,
                             baseline_steps=opts.onset_baseline_steps)
    if onset.step is None:
        warnings.append("no saturation onset found by the criterion: " + onset.describe())
    extra = pd.DataFrame({"step": pts.step, "torque_pct_saturation": pct,
                          "creep_coefficient": k, "phase_theory_deg": phase_theory,
                          "phase_fit_deg": phase_fit_deg, "utilisation_phase": util_phase})
    speeds = per["speed_m_s"][np.isfinite(per["speed_m_s"])]
    return Analysis(
        options=opts, steps=steps_df.merge(extra, on="step", how="left"), points=pts,
        used=use, polach=fit, polach_skipped=skipped, phase_fit=pfit,
        phase_fit_skipped=p_skipped or None, theory=tc, phase_theory_deg=phase_theory,
        theory_rig=None if rig_args is None else {"wheel_inertia_kg_m2": inertia,
                                                  "wheel_radius_m": radius},
        onset=onset, saturation_torque_nm=ts, saturation_torque_stderr_nm=ts_se,
        saturation_torque_source=ts_source,
        normal_load_n=n_nom, wheel_radius_m=radius, stiffness=stiffness,
        speed_m_s=float(np.mean(speeds)) if speeds.size else None, warnings=warnings,
        created_utc=datetime.now(UTC).isoformat(timespec="seconds"),
        source={"processed_with": result.torquemod_version,
                "processed_utc": result.created_utc,
                "manifest": str(result.experiment.manifest_path)},
        name=result.name)


def saturation_torque(polach, phase_fit, *, normal_load_n: float, wheel_radius_m: float
                      ) -> tuple[float | None, float | None, str | None]:
    """The saturation torque ``Ts = mu*N*Rw``, its standard error and which mu gave it.

    The force fit's mu when it is determined ("forces"), else mu from the phase when that is
    determined ("phase"). Every place that shows Ts or % of Ts takes it from here (the
    abscissa of Fig. 4 of [1]_).

    Parameters
    ----------
    polach : PolachFit or None
        The force fit.
    phase_fit : PhaseMuFit or None
        The fit from the phase.
    normal_load_n : float
        Normal load N [N].
    wheel_radius_m : float
        Wheel radius Rw [m].

    Returns
    -------
    ts_nm : float or None
        Ts [N*m].
    ts_stderr_nm : float or None
        Its standard error [N*m].
    source : {"forces", "phase"} or None
        Which mu; all three None when neither fit determines mu.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Fig. 4.
    """
    n_r = float(normal_load_n) * float(wheel_radius_m)
    if polach is not None and polach.mu is not None:
        se = polach.mu_stderr
        return polach.mu * n_r, None if se is None else se * n_r, "forces"
    if phase_fit is not None and phase_fit.mu_determined and phase_fit.mu:
        se = getattr(phase_fit, "mu_stderr", None)
        return phase_fit.mu * n_r, None if se is None else se * n_r, "phase"
    return None, None, None


def _require_process_result(result) -> None:
    """A clear error when :func:`analyze` is given something else than a processed result
    (an experiment, a manifest path, a results folder)."""
    from torquemod.processing.pipeline import ProcessResult
    if isinstance(result, ProcessResult):
        return
    what = type(result).__name__
    if what == "Experiment" or isinstance(result, str) or hasattr(result, "__fspath__"):
        raise OptionError(f"analyze() takes the result of process(), got {what} {result!r:.80}:"
                          " call res = tm.process(exp) first, then tm.analyze(res) (a saved "
                          "results folder: res, ana = tm.load(folder))")
    raise OptionError(f"analyze() takes a ProcessResult (from tm.process), got {what}")


def _polach_stage(opts, pts, per, use, stiffness, steps_df):
    """(PolachFit or None, reason it was skipped or None)."""
    if not np.all(np.isfinite(pts.creepage[use])):
        return None, "no creepage was measured (no platform speed channel)"
    use_w = opts.weighted and np.any(np.isfinite(pts.coa_se[use]))
    try:
        return _fit(opts, pts, per, use, use_w, per["lateral_coa"][use], stiffness,
                    _step_column(steps_df, "creepage_swing")), None
    except InputError as exc:
        return None, str(exc) + (f" ({int((~use).sum())} step(s) flagged as slipping were "
                                 "left out)" if not use.all() else "")


def _fit(opts: FitOptions, pts, per: dict, use: np.ndarray, use_w: bool,
         lateral: np.ndarray, stiffness, swing: np.ndarray | None = None):
    """The Polach fit over the steps in ``use`` (the swing-averaged curve when the fit
    supports it and the steps carry their creepage swing)."""
    extra = {}
    if swing is not None and "creepage_swing" in inspect.signature(fit_polach).parameters:
        extra["creepage_swing"] = np.nan_to_num(swing[use])
    return fit_polach(
        pts.creepage[use], pts.coa[use],
        xi_std=pts.creepage_se[use] if use_w else None,
        coa_std=pts.coa_se[use] if use_w else None,
        velocity_dependent=opts.velocity_dependent,
        speeds_m_s=per["speed_m_s"][use] if opts.velocity_dependent else None,
        lateral_coa=lateral if opts.lateral and np.all(np.isfinite(lateral)) else None,
        stiffness=None if stiffness is None else float(stiffness), n_starts=opts.n_starts,
        seed=opts.seed, sigma_floor=opts.sigma_floor, max_rel_stderr=opts.max_rel_stderr,
        min_saturation_fraction=opts.min_saturation_fraction,
        min_peak_fraction=opts.min_peak_fraction, creepage_limit=opts.creepage_limit, **extra)


def _step_column(steps_df: pd.DataFrame, name: str) -> np.ndarray | None:
    """A numeric column of the steps table as floats, or None when absent or holding no
    finite value (a quantity that was not measured)."""
    if name not in steps_df.columns:
        return None
    values = pd.to_numeric(steps_df[name], errors="coerce").to_numpy(float)
    return values if np.isfinite(values).any() else None


def measured_constant(steps_df: pd.DataFrame, use: np.ndarray, *, wheel_radius_m: float,
                      normal_load_n: float, phase_se_deg=None):
    """The theory constant C = Omega*J*V/(R^2*N) measured from the modulation itself.

    Holds where the torque is measured between the drive and the wheel and the speed at the
    wheel (V-Track's torque shaft with its encoder).

    Parameters
    ----------
    steps_df : pandas.DataFrame
        The steps table with the fitted modulation amplitudes (|T| [N*m], |w| [rad/s]), the
        phase [deg] and the speed V [m/s].
    use : ndarray of bool
        The steps to use.
    wheel_radius_m : float
        R [m].
    normal_load_n : float
        N [N].
    phase_se_deg : array_like or None
        Standard errors of the phases per step [deg] (all steps; ``use`` selects); None: 0.

    Returns
    -------
    ConstantEstimate or None
        C [-] (the median over the steps), its relative standard error [-] and the number of
        steps (:func:`torquemod.analysis.phasefit.constant_from_amplitudes`; the implied
        inertia is NaN: the frequency does not enter here); None when a column is missing.

    Notes
    -----
    The wheel's mechanical impedance ``T/w = j*Omega*J + R^2*N*k/V`` has the quadrature part
    Omega*J, so at every step ``C_i = (|T_i|/|w_i|)*sin(phi_i)*V_i/(R^2*N)``; with Eq. (1) of
    [1]_, ``tan(phi) = C/k``.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
    from torquemod.analysis.phasefit import constant_from_amplitudes
    cols = [_step_column(steps_df, k) for k in ("torque_amplitude_nm", "wheel_amplitude_rad_s",
                                               "phase_deg", "speed_m_s")]
    if any(c is None for c in cols) or not (wheel_radius_m and normal_load_n):
        return None
    t, w, phi, v = (c[use] for c in cols)
    se = (np.zeros(t.size) if phase_se_deg is None
          else np.asarray(phase_se_deg, dtype=float)[use])
    return constant_from_amplitudes(t, w, phi, se, v, np.nan, wheel_radius_m=wheel_radius_m,
                                    normal_load_n=normal_load_n)


def _phase_fit(steps_df: pd.DataFrame, pts, use: np.ndarray, constant,
               measured_c: tuple[float, float] | None = None,
               source: str | None = None, probe: bool = True) -> tuple[object, str]:
    """mu from the phase progression (:mod:`torquemod.analysis.phasefit`) over the steps in ``use``:
    (result or None, reason it was skipped or ""); ``probe``: also the probe depth."""
    try:
        from torquemod.analysis.phasefit import fit_mu_from_phase
    except ImportError:  # pragma: no cover - the module ships with the package
        return None, "the phase fit is not available"
    coa = _step_column(steps_df, "coa_torque")
    if coa is None or not np.all(np.isfinite(coa[use])):
        coa = pts.coa
    se = _step_column(steps_df, "phase_se_deg")
    fallback = pts.phase_std_deg / np.sqrt(np.maximum(pts.n_cycles, 1))
    if se is None:
        se = fallback
    se = np.where(np.isfinite(se) & (se > 0), se, fallback)
    se = np.where(np.isfinite(se) & (se > 0), se, 0.1)  # one cycle, no sine fit: 0.1 deg
    swing = _step_column(steps_df, "creepage_swing")
    c = None if constant is None else np.asarray(constant, dtype=float)
    if c is not None and c.ndim:
        c = float(np.nanmean(c[use]))
    c_rel = 0.0
    if c is None and measured_c:
        est = measured_constant(steps_df, use, wheel_radius_m=measured_c[0],
                                normal_load_n=measured_c[1], phase_se_deg=se)
        if est is not None:
            c, c_rel, source = est.constant, est.rel_se, "amplitudes"
    try:
        speed = _step_column(steps_df, "speed_m_s")
        res = fit_mu_from_phase(coa[use], pts.phase_deg[use], se[use], constant=c,
                                creepage_swing=None if swing is None else swing[use],
                                speed_m_s=None if speed is None
                                else float(np.nanmedian(np.abs(speed[use]))),
                                constant_rel_se=c_rel, constant_source=source,
                                probe=probe)
    except (InputError, ProcessingError) as exc:
        return None, str(exc)
    return res, ""
