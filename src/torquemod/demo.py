"""End-to-end demonstration: simulate -> process -> fit -> report, plus a synthetic result
for tests and documentation.

:func:`run_demo` drives the digital twin (:mod:`torquemod.twin`) and the orchestrator
(:func:`torquemod.api.run`), writing the whole demo folder atomically.

:func:`synthetic_result` fabricates a :class:`~torquemod.processing.pipeline.ProcessResult` from a
known
Polach curve and the rigid-wheel phase law, with noise; :func:`write_synthetic_results` saves
it as a results folder. It is independent of the simulator and the processing chain.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from torquemod.analysis.creep import phase_from_constant_deg, theory_constant
from torquemod.analysis.polachcurve import polach_coa, polach_slope
from torquemod.io.experiment import Experiment, RecordingEntry, Rig, TestSetup
from torquemod.processing.pipeline import (
    CYCLE_COLUMNS,
    ProcessResult,
    aggregate_steps,
    resolve_config,
)

__all__ = ["SYNTHETIC_TRUTH", "run_demo", "synthetic_result", "write_synthetic_results"]

#: Ground truth of :func:`synthetic_result` (lumped Polach form, stiffness s = 250).
SYNTHETIC_TRUTH = {"mu": 0.24, "k_a": 1.0, "k_s": 0.4, "stiffness": 250.0,
                   "wheel_radius_m": 0.075, "platform_radius_m": 1.0,
                   "wheel_inertia_kg_m2": 4.0, "normal_load_n": 4200.0,
                   "speed_m_s": 7.0 / 3.6, "modulation_frequency_hz": 2.0,
                   "modulation_amplitude_nm": 8.0}


def synthetic_result(*, seed: int = 0,
                            saturation_fractions=(0.003, 0.3, 0.55, 0.7, 0.8, 0.9),
                            n_cycles: int = 3, coa_noise: float = 0.001,
                            creepage_rel_noise: float = 0.02, phase_noise_deg: float = 0.5,
                            include_inertia: bool = True, fs_raw_hz: float = 400.0,
                            duration_s: float = 6.5) -> ProcessResult:
    """A fabricated :class:`ProcessResult` (experiment "synthetic", no files behind it).

    The steps' CoA are ``saturation_fractions*mu`` of :data:`SYNTHETIC_TRUTH`; creepages
    follow from the Polach curve [1]_, phases from ``atan(C/k)`` [2]_; per-cycle values get
    Gaussian noise.

    Parameters
    ----------
    seed : int
        Random seed. Default 0.
    saturation_fractions : sequence of float
        Each step's CoA as a share of mu [-].
    n_cycles : int
        Cycles per step [-]. Default 3.
    coa_noise : float
        Standard deviation of the CoA noise [-]. Default 0.001.
    creepage_rel_noise : float
        Relative standard deviation of the creepage noise [-]. Default 0.02.
    phase_noise_deg : float
        Standard deviation of the phase noise [deg]. Default 0.5.
    include_inertia : bool
        Give the rig's ``wheel_inertia_kg_m2`` (the truth, 4 kg m^2, stands for the wheel plus
        the drive line referred to the wheel axis). Default True.
    fs_raw_hz : float
        Sample rate of the fabricated traces [Hz]. Default 400.
    duration_s : float
        Length of each cycle [s]. Default 6.5.

    Returns
    -------
    ProcessResult
        The result.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (3), (8).
    .. [2] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
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

    cyc_rows, details, traces, entries = [], [], {}, []
    fs_rs = 53.344
    for i in range(fr.size):
        step = i + 1
        for cyc in range(1, n_cycles + 1):
            xi = xi_true[i] * (1 + creepage_rel_noise * rng.standard_normal())
            coa = coa_true[i] + coa_noise * rng.standard_normal()
            ph = phase_true[i] + phase_noise_deg * rng.standard_normal()
            f_t = 2.0 + 0.004 * rng.standard_normal()
            f_w = f_t + 0.01 + 0.003 * rng.standard_normal()
            # not modelled here (NaN): the chain's per-cycle standard error, the drive's
            # CoA, the modulation amplitudes and the creepage swing
            cyc_rows.append({"step": step, "cycle": cyc, "torque_peak_hz": f_t,
                             "wheel_peak_hz": f_w, "modulation_hz": 0.5 * (f_t + f_w),
                             "phase_deg": ph, "creepage": xi, "coa": coa,
                             "coa_source": "forces", "speed_m_s": tr["speed_m_s"],
                             "creepage_drift": 0.0})
            w_mean = omega_p * tr["platform_radius_m"] * (1 + xi) / tr["wheel_radius_m"]
            details.append({"step": step, "cycle": cyc, "dc_torque_nm": float(dc[i]),
                            "source": f"step{step}_cycle{cyc}.csv", "slip": None,
                            "platform_speed_rad_s": omega_p, "wheel_speed_rad_s": w_mean,
                            "fz_n": tr["normal_load_n"], "speed_m_s": tr["speed_m_s"]})
            entries.append(RecordingEntry(step=step, dc_torque_nm=float(dc[i]),
                                          path=Path(f"step{step}_cycle{cyc}.csv"), cycle=cyc,
                                          index=len(entries)))
            one = traces.setdefault((step, cyc), {})
            f_mod = 0.5 * (f_t + f_w)
            t_raw = np.arange(int(duration_s * fs_raw_hz)) / fs_raw_hz
            lag = np.radians(ph)
            torque = (dc[i] + tr["modulation_amplitude_nm"] * np.sin(2 * np.pi * f_mod * t_raw)
                      + 0.8 * rng.standard_normal(t_raw.size))
            dw = 0.05 * np.sin(2 * np.pi * f_mod * t_raw - lag)
            wheel = (w_mean + dw + 0.02 * np.sin(2 * np.pi * w_mean / (2 * np.pi) * t_raw)
                     + 0.01 * rng.standard_normal(t_raw.size))
            t_s = np.arange(int(duration_s * fs_rs)) / fs_rs
            one["t_raw_s"] = t_raw
            one["torque_raw_nm"] = torque
            one["wheel_speed_raw_rad_s"] = wheel
            one["t_s"] = t_s
            one["torque_resampled_nm"] = np.interp(t_s, t_raw, torque)
            one["wheel_speed_resampled_rad_s"] = np.interp(t_s, t_raw, wheel)
            one["torque_filtered_nm"] = (tr["modulation_amplitude_nm"]
                                                  * np.sin(2 * np.pi * f_mod * t_s))
            one["wheel_speed_filtered_rad_s"] = 0.05 * np.sin(2 * np.pi * f_mod * t_s
                                                                       - lag)
            one["phase_window_s"] = np.array([1.75, 1.75 + 3 / f_mod])

    cycles = pd.DataFrame(cyc_rows).reindex(columns=CYCLE_COLUMNS)
    steps = aggregate_steps(cycles, {i + 1: float(dc[i]) for i in range(fr.size)})
    extra = {"wheel_inertia_kg_m2": tr["wheel_inertia_kg_m2"]} if include_inertia else {}
    exp = Experiment(
        manifest_path=Path("synthetic/experiment.toml"),
        rig=Rig(tr["wheel_radius_m"], tr["platform_radius_m"], extra),
        test=TestSetup(tr["normal_load_n"], tr["modulation_frequency_hz"],
                       tr["modulation_amplitude_nm"]),
        recordings=tuple(entries))
    return ProcessResult(
        experiment=exp, config=resolve_config(exp), cycles=cycles, steps=steps,
        cycle_details=details, traces=traces,
        warnings=["synthetic data: fabricated by torquemod.demo.synthetic_result"],
        input_sha256={str(e.path): "0" * 64 for e in entries},
        created_utc="2025-01-01T00:00:00+00:00")


def write_synthetic_results(out_dir, **kwargs) -> Path:
    """Save :func:`synthetic_result` as a results folder without an analysis.

    As ``torquemod process --no-fit`` leaves it.

    Parameters
    ----------
    out_dir : str or pathlib.Path
        The folder.
    **kwargs
        Passed to :func:`synthetic_result`.

    Returns
    -------
    pathlib.Path
        The folder.
    """
    from torquemod.results.folder import save
    return save(synthetic_result(**kwargs), None, out_dir, report=False)


def run_demo(out_dir, *, config_path=None, seed: int = 0, force: bool = False,
             progress: bool = True, quick: bool = False, on_stage=None,
             with_train: bool = False) -> dict:
    """Simulate an experiment, process it, fit the creep curve and write the report.

    ``out_dir/experiment`` receives the simulated recordings and manifest, ``out_dir/results``
    the results folder with ``fit.json``, figures and ``report.html``. The whole ``out_dir``
    is assembled beside its place and appears in one rename, so an interrupted demo leaves
    nothing behind that blocks the next run.

    Parameters
    ----------
    out_dir : str or pathlib.Path
        The demo's folder.
    config_path : str or pathlib.Path or None
        The twin's configuration; None: the packaged default.
    seed : int
        Random seed. Default 0.
    force : bool
        Replace an existing ``out_dir``. Default False.
    progress : bool
        Show progress. Default True.
    quick : bool
        Shorten the simulation (2 cycles per step, 1.5 s run-in). Default False.
    on_stage : callable or None
        Receives a line of text as each stage starts.
    with_train : bool
        Add the train part (``out_dir/train-run``, ``out_dir/train-results``) as ``train``.
        Default False.

    Returns
    -------
    dict
        Paths (``experiment``, ``manifest``, ``results``, ``report``, ``fit_json``), the
        :class:`Analysis` (``analysis``), its summary numbers (``mu``, ``mu_stderr``,
        ``mu_determined``, ``saturation_torque_nm`` [N*m], ``onset_step``,
        ``theory_rms_deg`` [deg], ``steps``, ``warnings``, ...) and ``truth`` (the
        simulator's creep-curve peak, slip step and theory phases).
    """
    from torquemod._util.fsutil import atomic_dir
    from torquemod.api import analyze, process, save
    from torquemod.twins.vtrack import simulate

    say = on_stage or (lambda _text: None)
    out = Path(out_dir).absolute()
    config = simulate.load_config(config_path)
    if quick:
        config = _quick_config(config)
    with atomic_dir(out, force=force) as tmp:
        say("simulating the experiment (the first run compiles the simulator's numba "
            "kernels, which can take a minute; later runs reuse the compiled cache) ...")
        sim = simulate.run_simulation(config, tmp / "experiment", seed=seed, fmt="csv",
                                      progress=progress)
        say("processing the simulated recordings ...")
        res = _moved(process(tmp / "experiment" / "experiment.toml", progress=progress),
                     tmp, out)
        say("fitting the creep curve and mu from the phase ...")
        ana = analyze(res)
        say("writing the results folder with figures and report.html ...")
        save(res, ana, tmp / "results")
    summary = ana.summary()
    train = _train_demo(out, seed=seed, say=say) if with_train else None
    return {"experiment": str(out / "experiment"),
            "manifest": str(out / "experiment" / "experiment.toml"),
            "results": str(out / "results"), "report": str(out / "results" / "report.html"),
            "fit_json": str(out / "results" / "fit.json"), "analysis": ana,
            **{k: v for k, v in summary.items() if k != "steps"},
            "steps": [{k: st[k] for k in ("step", "dc_torque_nm", "phase_deg",
                                          "phase_theory_deg", "torque_pct_saturation")}
                      for st in summary["steps"]],
            "truth": _truth_headline(sim), "train": train}


def _train_demo(out: Path, *, seed: int, say) -> dict:
    """The train part of the demo: simulate the default run, estimate the friction along
    it, write ``out/train-run`` and ``out/train-results`` (each folder atomically)."""
    from torquemod.ontrain import run_onboard
    from torquemod.ontrain.report import segment_estimates
    from torquemod.twins.train import load_train_config, run_train_simulation
    say("simulating the default train run (powered axle, dry/wet/leaves/friction modifier) "
        "...")
    sim = run_train_simulation(load_train_config(), out / "train-run", seed=seed)
    say("estimating the friction along the train run ...")
    res = run_onboard(out / "train-run" / "run.toml", out / "train-results")[0]
    segs = segment_estimates(res.track, sim["segments"])
    return {"run": str(out / "train-run" / "run.toml"),
            "results": str(out / "train-results"),
            "report": str(out / "train-results" / "report.html"), "segments": segs,
            "summary": res.summary()}


def _moved(result: ProcessResult, old: Path, new: Path) -> ProcessResult:
    """``result`` with its experiment's paths under ``old`` moved under ``new`` (the demo
    is assembled in a temporary folder that is renamed at the end)."""
    def move(p) -> Path:
        p = Path(p)
        return new / p.relative_to(old) if p.is_relative_to(old) else p

    exp = result.experiment
    exp = dataclasses.replace(
        exp, manifest_path=move(exp.manifest_path),
        recordings=tuple(dataclasses.replace(e, path=move(e.path)) for e in exp.recordings))
    hashes = {str(move(k)): v for k, v in result.input_sha256.items()}
    def text(t):
        return t.replace(str(old), str(new)) if isinstance(t, str) else t

    return dataclasses.replace(
        result, experiment=exp, input_sha256=hashes,
        warnings=[text(w) for w in result.warnings],
        cycle_details=[{k: text(v) for k, v in d.items()} for d in result.cycle_details])


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
