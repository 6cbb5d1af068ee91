"""Fit stage on a results folder: creep points -> Polach fit -> theory check -> onset.

:func:`fit_results_folder` reads ``steps.csv``, ``cycles.csv`` and ``provenance.json`` written by
``torquemod process``, writes ``fit.json`` and rewrites ``steps.csv`` with three more columns
(original columns first, atomically):

* ``torque_pct_saturation`` DC torque as % of ``Ts = mu*N*Rw`` (NaN if mu is undetermined),
* ``creep_coefficient`` dCoA/dxi of the fitted curve at the step's creepage [-],
* ``phase_theory_deg`` the rigid-wheel phase ``atan(C/k)`` [deg] (see :mod:`torquemod.creep`).

Steps whose ``slip`` column is true (wheel slip found by ``torquemod process``) keep their
rows but are left out of the Polach fit, with a warning in ``fit.json``.

Rig keys read from ``provenance.json`` ``experiment.rig``: ``wheel_radius_m``,
``platform_radius_m``, and optionally ``wheel_inertia_kg_m2`` (J [kg m^2], the inertia of
everything turning with the wheel, referred to the wheel axis) and ``contact_stiffness``
(the lumped ``pi*G*a*b*c11/(4*Q)`` [-] of :func:`torquemod.fit.fit_polach`). With J the theory
constant ``C = 2*pi*f_mod*J*V/(R^2*N)`` is computed per step (f_mod the mean measured modulation
frequency, V the mean speed, N the mean measured normal load of the step, falling back to the
nominal test values); without it, one C is fitted across the steps.
"""

from __future__ import annotations

import dataclasses
import inspect
import json
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from ._version import __version__
from .config import coerce_options
from .creep import creep_points, saturation_onset, theory_check, theory_constant
from .errors import InputError, ProcessingError
from .fit import fit_polach
from .fsutil import write_atomic
from .jsonutil import dump_json, to_jsonable
from .theory import rigid_wheel_phase_deg

__all__ = ["ADDED_STEP_COLUMNS", "FitOptions", "fit_results_folder", "read_json",
           "write_json_atomic"]

ADDED_STEP_COLUMNS = ("torque_pct_saturation", "creep_coefficient", "phase_theory_deg",
                      "phase_fit_deg", "utilisation_phase")


@dataclass(frozen=True)
class FitOptions:
    """Options of the fit stage (all recorded in fit.json).

    ``velocity_dependent`` fits P05 Eq. (9) too (needs differing speeds); ``stiffness``
    overrides ``rig.contact_stiffness``; ``inertia_kg_m2`` overrides ``rig.wheel_inertia_kg_m2``;
    ``theory_constant`` forces C; ``weighted`` uses the steps' standard errors; ``onset_*`` are
    the arguments of :func:`torquemod.creep.saturation_onset`.
    """

    velocity_dependent: bool = False
    lateral: bool = True  # model CoA = sqrt(f(xi)^2 + (Fy/Fz)^2) with the measured Fy/Fz
    n_starts: int = 12
    seed: int = 0
    weighted: bool = True
    sigma_floor: float = 1e-4
    max_rel_stderr: float = 0.10
    min_saturation_fraction: float = 0.5
    min_peak_fraction: float = 0.9
    creepage_limit: float = 0.1
    stiffness: float | None = None
    inertia_kg_m2: float | None = None
    theory_constant: float | None = None
    onset_criterion: str = "tan_ratio"
    onset_k_sigma: float = 3.0
    onset_min_jump_deg: float = 5.0
    onset_rel_k_drop: float = 0.5
    onset_tan_ratio: float = 2.0
    onset_baseline_steps: int = 2

    @classmethod
    def coerce(cls, options) -> FitOptions:
        return coerce_options(cls, options, "fit")


def read_json(path: Path) -> dict:
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise InputError("file not found", path=path,
                         hint="run 'torquemod process' on the experiment first") from exc
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON ({exc})", path=path) from exc


def write_json_atomic(path: Path, data: dict) -> None:
    """Write ``data`` as strict JSON (NaN/inf -> null) via a temporary file and os.replace."""
    text = dump_json(data)
    write_atomic(path, lambda fh: fh.write(text + "\n"))


def _per_step(prov: dict, cycles: pd.DataFrame | None, steps: np.ndarray) -> dict:
    """Mean speed [m/s], normal load [N], modulation frequency [Hz] and lateral share of the
    CoA, |Fy|/Fz [-], per step."""
    exp = prov.get("experiment", {})
    rig, test = exp.get("rig", {}), exp.get("test", {})
    out = {"speed_m_s": np.full(steps.size, np.nan), "fz_n": np.full(steps.size, np.nan),
           "freq_hz": np.full(steps.size, np.nan), "lateral_coa": np.full(steps.size, np.nan)}
    pc = pd.DataFrame(prov.get("cycles") or [])
    if not pc.empty and "step" in pc:
        if "speed_m_s" not in pc and "platform_speed_rad_s" in pc and "platform_radius_m" in rig:
            pc["speed_m_s"] = pc["platform_speed_rad_s"].abs() * float(rig["platform_radius_m"])
        if "fy_n" in pc and "fz_n" in pc:
            pc["lateral_coa"] = (pc["fy_n"] / pc["fz_n"]).abs()
        g = pc.groupby("step").mean(numeric_only=True)
        for key, col in (("speed_m_s", "speed_m_s"), ("fz_n", "fz_n"),
                         ("lateral_coa", "lateral_coa")):
            if col in g:
                out[key] = g[col].reindex(steps).to_numpy(float)
    if cycles is not None and "modulation_hz" in cycles:
        out["freq_hz"] = cycles.groupby("step")["modulation_hz"].mean().reindex(steps).to_numpy(
            float)
    for key, default in (("fz_n", test.get("normal_load_n")),
                         ("freq_hz", test.get("modulation_frequency_hz"))):
        if default is not None:
            out[key] = np.where(np.isfinite(out[key]), out[key], float(default))
    out["fz_n"] = np.abs(out["fz_n"])
    return out


def _slip_flags(steps_df: pd.DataFrame) -> dict[int, bool]:
    """step -> slip flag from the ``slip`` column of steps.csv (absent: no step flagged)."""
    if "slip" not in steps_df.columns:
        return {}
    flags = steps_df["slip"].map(lambda v: str(v).strip().lower() in ("true", "1", "1.0"))
    return {int(s): bool(f) for s, f in zip(steps_df["step"], flags, strict=True)}


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


def _phase_keys(pfit) -> dict:
    """The four fit.json keys of mu from the phase (issue 8); a lower bound as the interval's
    low end when mu is not determined."""
    if pfit is None:
        return {"mu_from_phase": None, "mu_from_phase_stderr": None,
                "mu_from_phase_interval_95": [None, None], "mu_from_phase_determined": False}
    lo, hi = pfit.mu_interval_95
    return {"mu_from_phase": pfit.mu if pfit.mu_determined else None,
            "mu_from_phase_stderr": pfit.mu_stderr if pfit.mu_determined else None,
            "mu_from_phase_interval_95": [lo, hi if pfit.mu_determined else None],
            "mu_from_phase_determined": bool(pfit.mu_determined)}


def _step_column(steps_df: pd.DataFrame, name: str) -> np.ndarray | None:
    """A numeric column of steps.csv as floats, or None when absent."""
    if name not in steps_df.columns:
        return None
    return pd.to_numeric(steps_df[name], errors="coerce").to_numpy(float)


def measured_constant(steps_df: pd.DataFrame, use: np.ndarray, *, wheel_radius_m: float,
                      normal_load_n: float) -> float | None:
    """The theory constant C = Omega*J*V/(R^2*N) measured from the modulation itself: the
    wheel's mechanical impedance T/w = j*Omega*J + R^2*N*k/V has the quadrature part
    Omega*J, so ``C_i = (|T_i|/|w_i|)*sin(phi_i)*V_i/(R^2*N)`` at every step (amplitudes
    [N*m], [rad/s] of the fitted modulation, speed V [m/s]); the median over the steps. It
    holds where the torque is measured between the drive and the wheel and the speed at the
    wheel (V-Track's torque shaft with its encoder). None when a column is missing."""
    cols = [_step_column(steps_df, k) for k in ("torque_amplitude_nm", "wheel_amplitude_rad_s",
                                               "phase_deg", "speed_m_s")]
    if any(c is None for c in cols) or not (wheel_radius_m and normal_load_n):
        return None
    t, w, phi, v = (c[use] for c in cols)
    with np.errstate(divide="ignore", invalid="ignore"):
        ci = t / w * np.sin(np.radians(phi)) * v / (wheel_radius_m**2 * normal_load_n)
    ci = ci[np.isfinite(ci) & (ci > 0)]
    return float(np.median(ci)) if ci.size else None


def _phase_fit(steps_df: pd.DataFrame, pts, use: np.ndarray, constant,
               measured_c: tuple[float, float] | None = None) -> tuple[object, str]:
    """mu from the phase progression (:mod:`torquemod.phasefit`) over the steps in ``use``:
    (result or None, reason it was skipped or "")."""
    try:
        from .phasefit import fit_mu_from_phase
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
    if c is None and measured_c:
        c = measured_constant(steps_df, use, wheel_radius_m=measured_c[0],
                              normal_load_n=measured_c[1])
    try:
        res = fit_mu_from_phase(coa[use], pts.phase_deg[use], se[use], constant=c,
                                creepage_swing=None if swing is None else swing[use])
    except (InputError, ProcessingError) as exc:
        return None, str(exc)
    return res, ""


def fit_results_folder(results_dir, *, options=None) -> dict:
    """Fit the creep curve of a processed experiment and write ``fit.json`` + ``steps.csv``.

    Returns a summary: ``mu``, ``mu_stderr``, ``mu_determined``, ``mu_lower_bound``,
    ``saturation_torque_nm``, ``onset_step``, ``theory_rms_deg``, ``theory_max_deg``,
    ``steps`` (per-step list), ``warnings``, ``fit_json`` and ``steps_csv`` paths (str); the
    summary is JSON-serialisable (NaN -> None).
    """
    opts = FitOptions.coerce(options)
    results_dir = Path(results_dir)
    steps_path = results_dir / "steps.csv"
    if not steps_path.is_file():
        raise InputError("steps.csv not found", path=results_dir,
                         hint="run 'torquemod process' first")
    steps_df = pd.read_csv(steps_path)
    steps_df = steps_df.drop(columns=[c for c in ADDED_STEP_COLUMNS if c in steps_df.columns])
    prov = read_json(results_dir / "provenance.json")
    cycles_path = results_dir / "cycles.csv"
    cycles = pd.read_csv(cycles_path) if cycles_path.is_file() else None
    exp = prov.get("experiment", {})
    rig, test = exp.get("rig", {}), exp.get("test", {})
    warnings: list[str] = []

    pts = creep_points(steps_df)
    per = _per_step(prov, cycles, pts.step)
    # steps flagged as slipping by `torquemod process` stay in the tables but not in the fit
    slip_by_step = _slip_flags(steps_df)
    use = np.array([not slip_by_step.get(int(s), False) for s in pts.step], dtype=bool)
    if not use.all():
        warnings.append(f"step(s) {[int(s) for s in pts.step[~use]]} flagged as slipping "
                        "(steps.csv 'slip'; see provenance.json warnings) are left out of the "
                        "Polach fit")
    stiffness = opts.stiffness if opts.stiffness is not None else rig.get("contact_stiffness")
    use_w = opts.weighted and np.any(np.isfinite(pts.coa_se[use]))
    lateral = per["lateral_coa"][use]
    swing = _step_column(steps_df, "creepage_swing")
    fit, skipped = None, None
    if not np.all(np.isfinite(pts.creepage[use])):
        skipped = "no creepage was measured (no platform speed channel)"
    else:
        try:
            fit = _fit(opts, pts, per, use, use_w, lateral, stiffness, swing)
        except InputError as exc:
            skipped = str(exc) + (f" ({int((~use).sum())} step(s) flagged as slipping were "
                                  "left out)" if not use.all() else "")
    if skipped:
        warnings.append(f"the Polach fit of the creep curve was skipped: {skipped}")
    else:
        warnings += fit.warnings

    # saturation torque Ts = mu*N*Rw (paper, Section 3)
    radius = rig.get("wheel_radius_m")
    n_nom = test.get("normal_load_n")
    if n_nom is None and np.any(np.isfinite(per["fz_n"])):
        n_nom = float(np.nanmean(per["fz_n"]))
    ts = ts_se = None
    if fit is not None and fit.mu is not None and radius and n_nom:
        ts = fit.mu * float(n_nom) * float(radius)
        ts_se = fit.mu_stderr * float(n_nom) * float(radius)
    pct = 100.0 * pts.dc_torque_nm / ts if ts else np.full(len(pts), np.nan)

    inertia = opts.inertia_kg_m2 if opts.inertia_kg_m2 is not None \
        else rig.get("wheel_inertia_kg_m2")
    constant = opts.theory_constant
    rig_args = None
    if constant is None and inertia is not None:
        if radius and np.all(np.isfinite(per["speed_m_s"])) and np.all(
                np.isfinite(per["fz_n"])) and np.all(np.isfinite(per["freq_hz"])):
            rig_args = {"inertia_kg_m2": float(inertia), "speed_m_s": per["speed_m_s"],
                        "wheel_radius_m": float(radius), "normal_load_n": per["fz_n"],
                        "frequency_hz": per["freq_hz"]}
            constant = theory_constant(**rig_args)
        else:
            warnings.append("wheel inertia given but speed, load or frequency per step is "
                            "missing: the theory constant is fitted instead")
    # mu from the phase progression (runs whether or not forces were recorded)
    c_source = "rig" if constant is not None else "measured"
    pfit, p_skipped = _phase_fit(steps_df, pts, use, constant,
                                 measured_c=(radius, n_nom) if radius and n_nom else None)
    if pfit is None:
        warnings.append(f"mu from the phase was not estimated: {p_skipped}")
    else:
        warnings += [f"mu from the phase: {w}" for w in pfit.warnings]
        if c_source == "measured" and pfit.constant_given:
            warnings.append(f"mu from the phase: C = {pfit.constant:.4g} measured from the "
                            "torque/wheel-speed amplitude ratio (no rig inertia given)")
    coa_phase = _step_column(steps_df, "coa_torque")
    if coa_phase is None or not np.all(np.isfinite(coa_phase[use])):
        coa_phase = pts.coa
    phase_fit_deg = np.asarray(pfit.phase_curve(coa_phase), float) if pfit is not None \
        else np.full(len(pts), np.nan)
    util_phase = coa_phase / pfit.mu if pfit is not None and pfit.mu else \
        np.full(len(pts), np.nan)

    if fit is not None:
        k = fit.slope(pts.creepage, per["speed_m_s"] if fit.velocity_dependent else None)
    elif pfit is not None:
        k = np.asarray(pfit.creep_coefficient(coa_phase), float)
    else:
        k = np.full(len(pts), np.nan)
    tc = theory_check(pts.phase_deg, k, constant=constant)
    phase_theory = tc.phase_theory_deg
    if rig_args is not None:  # the project's rigid-wheel formula (torquemod.theory)
        phase_theory = np.asarray(rigid_wheel_phase_deg(k, **rig_args), dtype=float)
    if tc.mode == "fitted" and tc.n_used < 2:
        warnings.append("too few usable steps to fit the theory constant")

    onset = saturation_onset(pts.step, pts.phase_deg, pts.phase_std_deg, k,
                             criterion=opts.onset_criterion, k_sigma=opts.onset_k_sigma,
                             min_jump_deg=opts.onset_min_jump_deg,
                             rel_k_drop=opts.onset_rel_k_drop,
                             tan_ratio=opts.onset_tan_ratio,
                             baseline_steps=opts.onset_baseline_steps)
    if onset.step is None:
        warnings.append("no saturation onset found by the criterion: " + onset.describe())

    # extended steps.csv: original columns first, same row order as read
    extra = pd.DataFrame({"step": pts.step, "torque_pct_saturation": pct,
                          "creep_coefficient": k, "phase_theory_deg": phase_theory,
                          "phase_fit_deg": phase_fit_deg, "utilisation_phase": util_phase})
    out_df = steps_df.merge(extra, on="step", how="left")
    write_atomic(steps_path, lambda fh: out_df.to_csv(fh, index=False, lineterminator="\n"))

    per_step = [{"step": int(s), "dc_torque_nm": float(t), "creepage": float(x),
                 "coa": float(c), "phase_deg": float(p), "phase_std_deg": float(ps),
                 "phase_theory_deg": float(pt), "creep_coefficient": float(kk),
                 "torque_pct_saturation": float(q), "slip": not bool(u),
                 "phase_fit_deg": float(pf), "utilisation_phase": float(up)}
                for s, t, x, c, p, ps, pt, kk, q, u, pf, up in zip(
                    pts.step, pts.dc_torque_nm, pts.creepage, pts.coa, pts.phase_deg,
                    pts.phase_std_deg, phase_theory, k, pct, use, phase_fit_deg, util_phase,
                    strict=True)]
    if fit is not None:
        fit_dict = fit.to_dict()
    else:
        finite = pts.coa[use][np.isfinite(pts.coa[use])]
        fit_dict = {"mu": None, "mu_stderr": None, "mu_determined": False,
                    "mu_lower_bound": float(finite.max()) if finite.size else None,
                    "converged": None}
    fit_dict["fit_skipped"] = skipped
    fit_dict.update(_phase_keys(pfit))
    theory = tc.to_dict()
    if rig_args is not None:
        theory["rig"] = {"wheel_inertia_kg_m2": float(inertia), "wheel_radius_m": float(radius)}
    diff = pts.phase_deg - phase_theory
    okd = np.isfinite(diff)
    theory["rms_difference_deg"] = float(np.sqrt(np.mean(diff[okd] ** 2))) if okd.any() else None
    theory["max_abs_difference_deg"] = float(np.max(np.abs(diff[okd]))) if okd.any() else None
    doc = {
        **fit_dict,
        "saturation_torque_nm": ts, "saturation_torque_stderr_nm": ts_se,
        "normal_load_n": n_nom, "wheel_radius_m": radius,
        "theory": theory, "onset": onset.to_dict(), "steps": per_step,
        "warnings": warnings,
        "fit_options": dataclasses.asdict(opts),
        "torquemod_version": __version__,
        "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "source": {"results_dir": str(results_dir),
                   "processed_with": prov.get("torquemod_version"),
                   "processed_utc": prov.get("created_utc"),
                   "manifest": exp.get("manifest")},
        "identifiability": "only mu, kA*s and kS*s are identifiable (s = pi*G*a*b*c11/(4*Q)); "
                           + ("kA, kS reported with the given s" if stiffness is not None
                              else "the products are reported"),
    }
    write_json_atomic(results_dir / "fit.json", doc)
    return to_jsonable({
        "mu": fit_dict["mu"], "mu_stderr": fit_dict["mu_stderr"],
        "mu_determined": fit_dict["mu_determined"],
        "mu_lower_bound": fit_dict["mu_lower_bound"],
        "curve_peak_coa": fit_dict.get("curve_peak_coa"), "fit_skipped": skipped,
        **_phase_keys(pfit),
        "saturation_torque_nm": ts,
        "saturation_torque_stderr_nm": ts_se, "onset_step": onset.step,
        "theory_mode": tc.mode, "theory_rms_deg": theory["rms_difference_deg"],
        "theory_max_deg": theory["max_abs_difference_deg"],
        "converged": fit_dict.get("converged"),
        "steps": per_step, "warnings": warnings,
        "fit_json": str(results_dir / "fit.json"), "steps_csv": str(steps_path),
    })
