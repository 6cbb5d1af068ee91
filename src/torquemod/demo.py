"""End-to-end demonstration: simulate -> process -> fit -> report, plus a synthetic results
folder for tests and documentation.

:func:`run_demo` drives the digital twin (:mod:`torquemod.simulate`) and the processing chain
(:mod:`torquemod.pipeline`), then :func:`torquemod.analysis.fit_results_folder` and
:func:`torquemod.report.write_report` on ``out_dir/results``.

:func:`write_synthetic_results` fabricates a folder in the layout ``torquemod process`` writes
(``steps.csv``, ``cycles.csv``, ``provenance.json``, ``traces.npz``) from a known Polach curve
and the rigid-wheel phase law, with noise. It is independent of the simulator and the pipeline.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from ._version import __version__
from .creep import phase_from_constant_deg, theory_constant
from .fit import polach_coa, polach_slope

__all__ = ["SYNTHETIC_TRUTH", "run_demo", "write_synthetic_results"]

#: Ground truth of :func:`write_synthetic_results` (lumped Polach form, stiffness s = 250).
SYNTHETIC_TRUTH = {"mu": 0.24, "k_a": 1.0, "k_s": 0.4, "stiffness": 250.0,
                   "wheel_radius_m": 0.075, "platform_radius_m": 1.0,
                   "wheel_inertia_kg_m2": 4.0, "normal_load_n": 4200.0,
                   "speed_m_s": 7.0 / 3.6, "modulation_frequency_hz": 2.0,
                   "modulation_amplitude_nm": 8.0}


def write_synthetic_results(out_dir, *, seed: int = 0,
                            saturation_fractions=(0.003, 0.3, 0.55, 0.7, 0.8, 0.9),
                            n_cycles: int = 3, coa_noise: float = 0.001,
                            creepage_rel_noise: float = 0.02, phase_noise_deg: float = 0.5,
                            include_inertia: bool = True, fs_raw_hz: float = 400.0,
                            duration_s: float = 6.5) -> Path:
    """Write a fabricated results folder to ``out_dir`` and return its path.

    The steps' CoA are ``saturation_fractions * mu`` of :data:`SYNTHETIC_TRUTH`; creepages
    follow from the Polach curve, phases from ``atan(C/k)``; per-cycle values get Gaussian
    noise (``coa_noise`` [-], ``creepage_rel_noise`` [-], ``phase_noise_deg`` [deg]).
    With ``include_inertia=False`` the rig lacks ``wheel_inertia_kg_m2`` (the truth, 4 kg m^2,
    stands for the wheel plus the drive line referred to the wheel axis).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tr = SYNTHETIC_TRUTH
    rng = np.random.default_rng(seed)
    theta = np.array([tr["mu"], tr["k_a"] * tr["stiffness"], tr["k_s"] * tr["stiffness"]])
    fr = np.asarray(saturation_fractions, dtype=float)
    xi_true = np.array([brentq(lambda x, f=f: polach_coa(x, theta) - f * tr["mu"], 0.0, 1.0)
                        for f in fr])
    coa_true = fr * tr["mu"]
    k_true = polach_slope(xi_true, theta)
    c = theory_constant(inertia_kg_m2=tr["wheel_inertia_kg_m2"], speed_m_s=tr["speed_m_s"],
                        wheel_radius_m=tr["wheel_radius_m"], normal_load_n=tr["normal_load_n"],
                        frequency_hz=tr["modulation_frequency_hz"])
    phase_true = phase_from_constant_deg(c, k_true)
    dc = coa_true * tr["normal_load_n"] * tr["wheel_radius_m"]
    omega_p = tr["speed_m_s"] / tr["platform_radius_m"]

    cyc_rows, prov_cycles, traces, inputs = [], [], {}, []
    fs_rs = 53.344
    for i in range(fr.size):
        step = i + 1
        for cyc in range(1, n_cycles + 1):
            xi = xi_true[i] * (1 + creepage_rel_noise * rng.standard_normal())
            coa = coa_true[i] + coa_noise * rng.standard_normal()
            ph = phase_true[i] + phase_noise_deg * rng.standard_normal()
            f_t = 2.0 + 0.004 * rng.standard_normal()
            f_w = f_t + 0.01 + 0.003 * rng.standard_normal()
            cyc_rows.append({"step": step, "cycle": cyc, "torque_peak_hz": f_t,
                             "wheel_peak_hz": f_w, "modulation_hz": 0.5 * (f_t + f_w),
                             "phase_deg": ph, "creepage": xi, "coa": coa})
            w_mean = omega_p * tr["platform_radius_m"] * (1 + xi) / tr["wheel_radius_m"]
            prov_cycles.append({"step": step, "cycle": cyc, "platform_speed_rad_s": omega_p,
                                "wheel_speed_rad_s": w_mean, "fz_n": tr["normal_load_n"],
                                "speed_m_s": tr["speed_m_s"]})
            inputs.append({"file": f"step{step}_cycle{cyc}.csv", "sha256": "0" * 64,
                           "step": step, "cycle": cyc})
            key = f"s{step}c{cyc}__"
            f_mod = 0.5 * (f_t + f_w)
            t_raw = np.arange(int(duration_s * fs_raw_hz)) / fs_raw_hz
            lag = np.radians(ph)
            torque = (dc[i] + tr["modulation_amplitude_nm"] * np.sin(2 * np.pi * f_mod * t_raw)
                      + 0.8 * rng.standard_normal(t_raw.size))
            dw = 0.05 * np.sin(2 * np.pi * f_mod * t_raw - lag)
            wheel = (w_mean + dw + 0.02 * np.sin(2 * np.pi * w_mean / (2 * np.pi) * t_raw)
                     + 0.01 * rng.standard_normal(t_raw.size))
            t_s = np.arange(int(duration_s * fs_rs)) / fs_rs
            traces[key + "t_raw_s"] = t_raw
            traces[key + "torque_raw_nm"] = torque
            traces[key + "wheel_speed_raw_rad_s"] = wheel
            traces[key + "t_s"] = t_s
            traces[key + "torque_resampled_nm"] = np.interp(t_s, t_raw, torque)
            traces[key + "wheel_speed_resampled_rad_s"] = np.interp(t_s, t_raw, wheel)
            traces[key + "torque_filtered_nm"] = (tr["modulation_amplitude_nm"]
                                                  * np.sin(2 * np.pi * f_mod * t_s))
            traces[key + "wheel_speed_filtered_rad_s"] = 0.05 * np.sin(2 * np.pi * f_mod * t_s
                                                                       - lag)
            traces[key + "phase_window_s"] = np.array([1.75, 1.75 + 3 / f_mod])

    cycles = pd.DataFrame(cyc_rows)
    g = cycles.groupby("step")
    steps = pd.DataFrame({
        "step": np.arange(1, fr.size + 1), "dc_torque_nm": dc,
        "phase_deg": g["phase_deg"].mean().to_numpy(),
        "phase_std_deg": g["phase_deg"].std(ddof=1).to_numpy(),
        "creepage": g["creepage"].mean().to_numpy(),
        "creepage_std": g["creepage"].std(ddof=1).to_numpy(),
        "coa": g["coa"].mean().to_numpy(), "coa_std": g["coa"].std(ddof=1).to_numpy(),
        "n_cycles": g.size().to_numpy()})
    rig = {"wheel_radius_m": tr["wheel_radius_m"], "platform_radius_m": tr["platform_radius_m"]}
    if include_inertia:
        rig["wheel_inertia_kg_m2"] = tr["wheel_inertia_kg_m2"]
    prov = {"torquemod_version": __version__, "created_utc": "2025-01-01T00:00:00+00:00",
            "experiment": {"manifest": "synthetic/experiment.toml", "rig": rig,
                           "test": {"normal_load_n": tr["normal_load_n"],
                                    "modulation_frequency_hz": tr["modulation_frequency_hz"],
                                    "modulation_amplitude_nm": tr["modulation_amplitude_nm"]}},
            "inputs": inputs, "parameters": {"synthetic": True, "seed": seed},
            "warnings": ["synthetic data: fabricated by torquemod.demo.write_synthetic_results"],
            "cycles": prov_cycles}
    cycles.to_csv(out / "cycles.csv", index=False)
    steps.to_csv(out / "steps.csv", index=False)
    (out / "provenance.json").write_text(json.dumps(prov, indent=2), encoding="utf-8")
    np.savez_compressed(out / "traces.npz", **traces)
    return out


def run_demo(out_dir, *, config_path=None, seed: int = 0, force: bool = False,
             progress: bool = True, quick: bool = False) -> dict:
    """Simulate an experiment, process it, fit the creep curve and write the report.

    ``out_dir/experiment`` receives the simulated recordings and manifest,
    ``out_dir/results`` the processed results, ``fit.json``, figures and ``report.html``.
    ``quick`` shortens the simulation (2 cycles per step, 1.5 s run-in; see
    :func:`_quick_config`).

    Returns paths (``experiment``, ``results``, ``report``, ``fit_json``) and headline
    numbers: ``mu``, ``mu_stderr``, ``mu_determined``, ``saturation_torque_nm``,
    ``onset_step``, ``theory_rms_deg``, ``steps`` (per-step phase, theory phase, % of Ts),
    ``warnings`` and ``truth`` (the simulator's creep-curve peak, slip step, theory phases).
    """
    from . import pipeline, simulate
    from .analysis import fit_results_folder
    from .report import write_report

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    config = simulate.load_config(config_path)
    if quick:
        config = _quick_config(config)
    sim = simulate.run_simulation(config, out / "experiment", seed=seed, fmt="csv",
                                  progress=progress, force=force)
    manifest = out / "experiment" / "experiment.toml"  # run_simulation writes it there
    result = pipeline.process_experiment(manifest, config=pipeline.ProcessingConfig(),
                                         progress=progress)
    pipeline.write_results(result, out / "results", force=force)
    summary = fit_results_folder(out / "results")
    report = write_report(out / "results")
    return {"experiment": str(out / "experiment"), "manifest": str(manifest),
            "results": str(out / "results"), "report": str(report),
            "fit_json": summary["fit_json"], "mu": summary["mu"],
            "mu_stderr": summary["mu_stderr"], "mu_determined": summary["mu_determined"],
            "mu_lower_bound": summary["mu_lower_bound"],
            "curve_peak_coa": summary["curve_peak_coa"],
            "saturation_torque_nm": summary["saturation_torque_nm"],
            "onset_step": summary["onset_step"], "theory_rms_deg": summary["theory_rms_deg"],
            "fit_skipped": summary.get("fit_skipped"),
            **{k: summary.get(k) for k in ("mu_from_phase", "mu_from_phase_stderr",
                                           "mu_from_phase_interval_95",
                                           "mu_from_phase_determined")},
            "steps": [{k: s[k] for k in ("step", "dc_torque_nm", "phase_deg",
                                         "phase_theory_deg", "torque_pct_saturation")}
                      for s in summary["steps"]],
            "warnings": summary["warnings"], "truth": _truth_headline(sim)}


def _truth_headline(truth: dict) -> dict:
    """The simulator's ground truth (``run_simulation``'s truth dict) worth comparing with:
    the peak of its creep curve, the slip step and the theory phases."""
    peak = truth["creep_curve_peak"]
    c = truth["parameters"]["rig"]["contact"]
    rig = truth["parameters"]["rig"]
    top = [s for s in truth["steps"] if not s.get("slipped") and s.get("creepage") is not None]
    w = abs(top[-1]["creepage"]) * rig["speed_m_s"] if top else 0.0
    # Polach 2005 Eq. (9): the friction the top step's slip velocity sees
    mu_top = c["mu0"] * ((1 - c["a_ratio"]) * math.exp(-c["b_s_m"] * w) + c["a_ratio"])
    return {"peak_coa": peak["coa"], "peak_torque_nm": peak["torque_nm"],
            "mu0": c["mu0"], "mu_at_top_step": mu_top,
            "slip_step": truth["slip_step"],
            "phase_theory_deg": [s["phase_theory_deg"] for s in truth["steps"]]}



def _quick_config(config):
    """A shortened simulation: at most 2 cycles per step and at most 1.5 s of run-in after
    each step change (``procedure.cycles_per_step``, ``procedure.settle_s``)."""
    proc = config.procedure
    return dataclasses.replace(config, procedure=dataclasses.replace(
        proc, cycles_per_step=min(proc.cycles_per_step, 2), settle_s=min(proc.settle_s, 1.5)))
