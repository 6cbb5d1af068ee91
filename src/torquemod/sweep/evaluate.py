"""One sweep point: its twin configuration, its torque progression and its rows of the sweep
table (one per torque step).

``mode = "theory"``: per step the steady operating point (:func:`torquemod.twins.vtrack.theory.
operating_point`) and the periodic steady state under the full modulation
(:func:`torquemod.twins.vtrack.theory.large_signal_phase_deg`, driven by the motor as in the twin);
the
phase's standard error is the Cramér-Rao bound of the step's record (Rife and Boorstyn 1974, IEEE
Trans. Inf. Theory 20(5)) and mu from
the phase is fitted to those phases. ``mode = "full"``: the twin
(:func:`torquemod.twins.vtrack.simulate.
simulate_run`, recordings in memory) -> the processing chain (as :func:`torquemod.api.
process`, on those recordings) -> the fits (:func:`torquemod.api.analyze`), with the theory
columns beside the chain's; ``through_files`` writes the twin's experiment as HDF5 and reads
it back instead (the same rows).

``utilisation`` is ``T_dc / T_peak`` = longitudinal CoA / mu_true, with ``mu_true`` the peak of
the twin's creep curve (``T_peak/(R_w*N)``: the adhesion the wheel can use; truth.json's
``creep_curve_peak``). The fit from the phase estimates that available adhesion and is
judged against it; ``mu_friction``, the friction at the slip velocity of the highest step it
used, is reported beside it.
"""

from __future__ import annotations

import dataclasses
import math
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from torquemod.analysis.creep import theory_constant, time_constant_s
from torquemod.errors import InputError, ProcessingError

__all__ = ["CHAIN_RULE", "SETTLE_RULE", "SETTLE_TIME_CONSTANTS", "PointTask", "chain_config",
           "evaluate_point", "phase_crlb_deg", "point_config", "settle_time_s"]

_Z95 = 1.959963984540054

#: full mode: each step's run-in lasts at least this many time constants of the wheel's
#: slowest creep mode among the simulated steps (:func:`settle_time_s`)
SETTLE_TIME_CONSTANTS = 8.0
#: the rule's description, part of a full-mode point's fingerprint (a changed rule reruns)
SETTLE_RULE = "8 creep-mode time constants of the slowest recorded step (< slip_creepage)"
#: how :func:`chain_config` scales the chain with the frequency (in the fingerprint too)
CHAIN_RULE = "band, band-pass, high-pass, slow model x f/2; resampling rate x max(f/2, 1)"
#: (the same rule as torquemod.io.config.FREQUENCY_RULE; kept as the fingerprint's text)


@dataclass(frozen=True)
class PointTask:
    """What a worker needs to evaluate one sweep point (picklable, small).

    Attributes
    ----------
    point_id : str
        The point's identifier (a hash of its parameters and seed).
    index : int
        Its position in the sweep.
    params : dict
        Its swept parameters, by key.
    overrides : dict
        The twin configuration's overrides they make.
    seed : int
        The twin's random seed.
    mode : {"theory", "full"}
        Theory only, or twin -> chain -> fits.
    base : str or None
        The base configuration file; None: the packaged default.
    fractions_of_peak : tuple of float or None
        The DC torques as fractions of the creep-curve peak torque [-]; None: the base's.
    max_utilisation : float
        Utilisation limit of the recommendation [-] (``[recommend]``).
    processing : dict
        The chain's ``[processing]`` table (full mode).
    kind : {"rig", "train"}
        A rig point, or a train point (:mod:`torquemod.sweep.trainpoint`). Default "rig".
    max_mu_error : float
        Train sweeps: a mu row counts when its relative error is within this [-].
        Default 0.10.
    """

    point_id: str
    index: int
    params: dict
    overrides: dict
    seed: int
    mode: str
    base: str | None
    fractions_of_peak: tuple[float, ...] | None
    max_utilisation: float
    processing: dict = dataclasses.field(default_factory=dict)
    kind: str = "rig"  # "train": evaluated by torquemod.sweep.trainpoint
    max_mu_error: float = 0.10  # train: a mu row within this relative error counts


def tasks(spec) -> list[PointTask]:
    """One :class:`PointTask` per point of a sweep.

    Parameters
    ----------
    spec : SweepSpec
        The sweep's specification.

    Returns
    -------
    list of PointTask
        In the sweep's order.
    """
    base = None if spec.base is None else str(spec.base.resolve())
    return [PointTask(point_id=p.point_id, index=p.index, params=p.params,
                      overrides=p.overrides(), seed=p.seed, mode=spec.mode, base=base,
                      fractions_of_peak=spec.fractions_of_peak,
                      max_utilisation=spec.recommend.max_utilisation,
                      processing=spec.processing if spec.mode == "full" else {},
                      kind=spec.kind, max_mu_error=spec.recommend.max_mu_error)
            for p in spec.points]


def point_config(task: PointTask):
    """The twin's configuration of a point and its creep-curve peak torque.

    Parameters
    ----------
    task : PointTask
        The point.

    Returns
    -------
    config : SimConfig
        The base configuration with the point's overrides, its DC torques set to
        ``fractions_of_peak`` of the peak torque when given.
    t_peak_nm : float
        The peak torque T_peak = mu_true*R_w*N [N*m].
    """
    from torquemod.twins.vtrack.simulate import load_config
    from torquemod.twins.vtrack.theory import creep_curve_peak
    config = load_config(task.base, overrides=task.overrides)
    _, t_peak = creep_curve_peak(config.rig)
    if task.fractions_of_peak is not None:
        torques = tuple(float(f) * t_peak for f in task.fractions_of_peak)
        config = dataclasses.replace(config, procedure=dataclasses.replace(
            config.procedure, dc_torques_nm=torques))
    return config, float(t_peak)


def phase_crlb_deg(torque_amplitude_nm, speed_amplitude_rad_s, *, torque_noise_nm: float,
                   speed_noise_rad_s: float, sample_rate_hz: float, duration_s: float):
    """Cramér-Rao bound of the phase difference of two sinusoids in white noise.

    A lower bound: the chain also sees the rig's disturbances.

    Parameters
    ----------
    torque_amplitude_nm : float or array_like
        Torque amplitude A1 [N*m].
    speed_amplitude_rad_s : float or array_like
        Wheel-speed amplitude A2 [rad/s].
    torque_noise_nm : float
        Torque noise standard deviation sigma1 [N*m].
    speed_noise_rad_s : float
        Speed noise standard deviation sigma2 [rad/s].
    sample_rate_hz : float
        Sample rate fs [Hz].
    duration_s : float
        Record length T [s].

    Returns
    -------
    float or ndarray
        Standard deviation of the phase difference [deg].

    Notes
    -----
    ``var = (2*s1^2/A1^2 + 2*s2^2/A2^2)/(fs*T)`` [rad^2]: each phase's bound
    ``2*sigma^2/(A^2*N)`` for N = fs*T samples of a tone of known frequency [1]_, [2]_, the two
    independent.

    References
    ----------
    .. [1] D.C. Rife and R.R. Boorstyn, "Single-tone parameter estimation from discrete-time
       observations", IEEE Trans. Inf. Theory 20(5) (1974) 591-598.
    .. [2] S.M. Kay, "Fundamentals of Statistical Signal Processing: Estimation Theory",
       Prentice Hall 1993, §3.

    Examples
    --------
    >>> round(float(phase_crlb_deg(1.0, 1.0, torque_noise_nm=0.01, speed_noise_rad_s=0.01,
    ...                            sample_rate_hz=1000.0, duration_s=2.0)), 6)
    0.025623
    """
    n = sample_rate_hz * duration_s
    var = (2.0 * torque_noise_nm**2 / np.asarray(torque_amplitude_nm, float) ** 2
           + 2.0 * speed_noise_rad_s**2 / np.asarray(speed_amplitude_rad_s, float) ** 2) / n
    return np.degrees(np.sqrt(var))


def creep_time_constant_s(config, creep_coefficient) -> np.ndarray:
    """Time constant of the wheel's speed relative to the platform at an operating point.

    The drive line turns as one body below its torsional mode, so its inertia is the wheel's
    and the motor side's, ``J_w + J_m`` (:func:`torquemod.analysis.creep.time_constant_s`).

    Parameters
    ----------
    config : SimConfig
        The twin's configuration (rig geometry, inertias, speed, load).
    creep_coefficient : float or array_like
        Creep coefficient k = dCoA/dxi at the operating point [-].

    Returns
    -------
    ndarray
        The time constant [s].
    """
    rig = config.rig
    return time_constant_s(inertia_kg_m2=rig.wheel_inertia_kg_m2 + rig.drive_inertia_kg_m2,
                           speed_m_s=rig.speed_m_s, wheel_radius_m=rig.wheel_radius_m,
                           normal_load_n=rig.normal_load_n,
                           creep_coefficient=creep_coefficient)


def settle_time_s(config, rows: list[dict]) -> float:
    """Run-in of every step in full mode.

    The configured ``procedure.settle_s``, or :data:`SETTLE_TIME_CONSTANTS` time constants
    (:func:`creep_time_constant_s`) of the slowest step the twin records (below the peak and
    below ``procedure.slip_creepage``), whichever is longer. A step starts from the previous
    step's steady state and ramps its DC torque; near the creep curve's peak that transient
    decays slowly (tau ~ 1 s at 90 % utilisation on leaves) and, not settled, it biases the
    recorded phase: measured twin minus large-signal theory -0.24 deg on leaves at 90 %,
    2 Hz, after 3 s, and 3e-5 deg after 10 s. exp(-8) leaves ~0.002 deg there.

    Parameters
    ----------
    config : SimConfig
        The twin's configuration.
    rows : list of dict
        The point's steps with their theory operating points (creep coefficient, creepage).

    Returns
    -------
    float
        The run-in [s].
    """
    # the steps the twin records: below the creep curve's peak and below the creepage at
    # which it counts the wheel as slipping (procedure.slip_creepage; it stops there)
    slip = config.procedure.slip_creepage
    ks = [r["creep_coefficient"] for r in rows if not r.get("slipped")
          and abs(r.get("creepage_true", np.inf)) < slip
          and np.isfinite(r.get("creep_coefficient", np.nan)) and r["creep_coefficient"] > 0]
    tau = float(np.max(creep_time_constant_s(config, ks))) if ks else 0.0
    return max(float(config.procedure.settle_s), SETTLE_TIME_CONSTANTS * tau)


def _theory_steps(config, t_peak: float) -> list[dict]:
    """Operating point and large-signal periodic state of each step until the first that
    slips (included, flagged)."""
    from torquemod.twins.vtrack.theory import large_signal_phase_deg, operating_point
    rig, mod = config.rig, config.modulation
    f = mod.actual_frequency_hz
    sens, dist = config.sensors, config.disturbances
    noisy = dist.enabled
    duration = config.procedure.cycles_per_step * rig.revolution_s
    rows = []
    for i, dc in enumerate(config.procedure.dc_torques_nm, start=1):
        # rounded: a fraction of the peak comes back as itself, not 0.9500000000000001
        row = {"step": i, "dc_torque_nm": float(dc),
               "utilisation": round(float(dc) / t_peak, 12)}
        op = operating_point(dc, rig)
        ls = None if op.slipped else large_signal_phase_deg(dc, rig, f, mod.amplitude_nm,
                                                            drive="motor")
        if ls is None or ls.slipped:
            rows.append({**row, "slipped": True})
            break
        crlb = phase_crlb_deg(ls.torque_amplitude_nm, ls.speed_amplitude_rad_s,
                              torque_noise_nm=sens.torque_noise_nm if noisy else 0.0,
                              speed_noise_rad_s=sens.wheel_speed_noise_rad_s if noisy else 0.0,
                              sample_rate_hz=sens.sample_rate_hz, duration_s=duration)
        rows.append({**row, "slipped": False, "coa_true": op.coa,
                     "creepage_true": op.creepage, "creep_coefficient": op.creep_coefficient,
                     "lateral_coa_true": abs(op.fy_n) / rig.normal_load_n,
                     "phase_theory_deg": ls.phase_deg,
                     "phase_small_signal_deg": ls.small_signal_phase_deg,
                     "phase_crlb_deg": float(crlb),
                     "creepage_swing": 0.5 * (ls.creepage_max - ls.creepage_min),
                     "torque_amplitude_nm": ls.torque_amplitude_nm,
                     "torque_ripple_pct": 100.0 * ls.torque_amplitude_nm / t_peak,
                     "speed_amplitude_rad_s": ls.speed_amplitude_rad_s})
    if rows and rows[0]["slipped"]:
        raise ProcessingError(
            f"the wheel slips at the first step: DC torque {rows[0]['dc_torque_nm']:.4g} N*m "
            f"is at or above the creep curve's peak {t_peak:.4g} N*m (or no periodic state "
            "exists there)")
    return rows


def _phase_mu(coa, phase_deg, se_deg, constant, swing, speed_m_s=None) -> dict:
    """The available adhesion from the phase (:func:`torquemod.analysis.phasefit.fit_mu_from_phase`)
    over the given steps. ``mu_phase*`` (the names of earlier versions): value (NaN when not
    determined), 95 % interval (low end = lower bound when not determined), determined
    flag, and why it was not fitted; ``adhesion_available_phase*`` the same quantity named:
    the estimate, the interval whenever it is closed, the lower bound, the probe depth that
    would determine it; ``mu0_phase`` the law's friction coefficient where identified."""
    from torquemod.analysis.phasefit import fit_mu_from_phase
    out = {"mu_phase": math.nan, "mu_phase_lo": math.nan, "mu_phase_hi": math.nan,
           "mu_phase_determined": False, "mu_phase_note": "",
           "adhesion_available_phase": math.nan, "adhesion_available_phase_low": math.nan,
           "adhesion_available_phase_high": math.nan,
           "adhesion_available_phase_lower_bound": math.nan,
           "adhesion_available_phase_determined": False, "probe_depth_needed_phase": math.nan,
           "mu0_phase": math.nan, "phase_fit_law": ""}
    try:
        fit = fit_mu_from_phase(coa, phase_deg, se_deg, constant=constant,
                                creepage_swing=swing, speed_m_s=speed_m_s)
    except (InputError, ProcessingError) as exc:
        out["mu_phase_note"] = str(exc).splitlines()[0]
        return out
    lo, hi = fit.mu_interval_95
    a = fit.adhesion
    out.update(mu_phase=fit.mu if fit.mu_determined else math.nan,
               mu_phase_lo=math.nan if lo is None else float(lo),
               mu_phase_hi=math.nan if hi is None else float(hi),
               mu_phase_determined=bool(fit.mu_determined),
               adhesion_available_phase=float(a.estimate),
               adhesion_available_phase_low=float(a.low) if a.closed else math.nan,
               adhesion_available_phase_high=float(a.high) if a.closed else math.nan,
               adhesion_available_phase_lower_bound=float(a.lower_bound),
               adhesion_available_phase_determined=bool(a.determined),
               probe_depth_needed_phase=float(a.probe_depth),
               mu0_phase=float(a.mu0) if a.mu0_identified else math.nan,
               phase_fit_law=a.law)
    return out


def _forces_mu_theory(df: pd.DataFrame) -> dict:
    """The Polach force fit (:func:`torquemod.analysis.fit.fit_polach`, as the chain's analysis
    calls it, unweighted) on the exact steady-state creep points of the steps that do not
    slip: what the force method gives with perfect measurements."""
    from torquemod.analysis.fit import fit_polach
    live = df[~df["slipped"].astype(bool)]
    out = {"mu_forces": math.nan, "mu_forces_lo": math.nan, "mu_forces_hi": math.nan,
           "mu_forces_determined": False,
           "mu_forces_lower_bound": float(live["coa_true"].max())}
    try:
        fit = fit_polach(live["creepage_true"].to_numpy(float),
                         live["coa_true"].to_numpy(float),
                         lateral_coa=live["lateral_coa_true"].to_numpy(float))
    except (InputError, ProcessingError):
        return out
    lo, hi = fit.mu_interval_95
    out.update(mu_forces=_f(fit.mu), mu_forces_lo=_f(lo), mu_forces_hi=_f(hi),
               mu_forces_determined=fit.mu is not None,
               mu_forces_lower_bound=float(fit.mu_lower_bound))
    return out


def _f(x) -> float:
    return math.nan if x is None else float(x)


def chain_config(frequency_hz: float, processing: dict | None = None):
    """The processing chain's parameters for a modulation frequency.

    :meth:`torquemod.io.config.ProcessingConfig.for_modulation`: the defaults, tuned for the
    V-Track paper's 2 Hz, with every frequency-bound setting scaled by ``frequency_hz/2``;
    above 2 Hz also the resampling rate, so that a period keeps its 26.7 samples (the paper's
    peak/valley phase interpolates each peak by a parabola, whose bias grows as the samples
    per period fall: noise-free twin at 8 Hz, 6.7 samples a period, the chain's phase 0.025
    deg (median) to 0.074 deg off the theory; with the rate scaled, 0.0012 deg). Then the keys
    the sweep's ``processing`` table gives.

    Parameters
    ----------
    frequency_hz : float
        Modulation frequency [Hz].
    processing : dict or None
        The sweep's ``processing`` table, nested as a manifest's ``[processing]``.

    Returns
    -------
    ProcessingConfig
        The chain's parameters.

    Raises
    ------
    InputError
        A bad ``processing`` key or value, naming ``sweep [processing]``.
    """
    from torquemod.io.config import ProcessingConfig
    return ProcessingConfig.for_modulation(frequency_hz, processing or {},
                                           source="sweep [processing]")


def _full_steps(config, t_peak: float, seed: int, workdir: Path | None,
                processing: dict | None = None) -> tuple[list[dict], dict]:
    """Twin -> chain -> fits: the chain's and the twin's columns per step, and the point's
    force fit and mu from the phase over all steps (the analysis of ``torquemod fit``).
    The twin's recordings go to the chain in memory, or, with a ``workdir``, through an
    HDF5 experiment folder there (the same numbers)."""
    from torquemod.api import analyze, process
    from torquemod.twins.vtrack.simulate import run_simulation, simulate_run
    cfg = chain_config(config.modulation.frequency_hz, processing)
    # workers=1: the sweep's parallel units are Dask worker processes, one per core
    if workdir is not None:
        truth = run_simulation(config, workdir / "experiment", seed=seed, fmt="hdf5",
                               progress=False, workers=1)
    else:
        # the theory columns come from _theory_steps: the truth's large-signal phase is
        # not needed (it is not part of the rows); of what the twin simulated the rows take
        # the slip and each step's phase (phase_simulated_deg), not its statistics
        run = simulate_run(config, seed=seed, workers=1, large_signal=False,
                           statistics=False)
        truth = run.truth
    if truth["slip_step"] == 1:
        raise ProcessingError(
            f"the wheel slips at the first step (DC torque "
            f"{config.procedure.dc_torques_nm[0]:.4g} N*m, creep-curve peak {t_peak:.4g} N*m)")
    if workdir is not None:
        res = process(workdir / "experiment" / "experiment.toml", cfg, workers=1)
    else:
        res = _process_in_memory(run, cfg)
    # probe=False: analyze's probe depth reaches none of the point's columns (the sweep's
    # own probe depth, probe_depth_needed_phase, comes from _phase_mu)
    ana = analyze(res, probe=False)
    chain = ana.steps.set_index("step")
    rows = []
    for st in truth["steps"]:
        i = int(st["step"])
        row = {"step": i, "slipped_twin": bool(st["slipped"])}
        sim = st.get("simulated")
        if sim is not None:
            row["phase_simulated_deg"] = sim["phase_deg"]
        if i in chain.index:
            c = chain.loc[i]
            row.update(phase_deg=_f(c["phase_deg"]), phase_se_deg=_f(c["phase_se_deg"]),
                       phase_std_deg=_f(c["phase_std_deg"]), creepage=_f(c["creepage"]),
                       coa=_f(c["coa"]), coa_torque=_f(c["coa_torque"]),
                       creepage_swing_measured=_f(c["creepage_swing"]),
                       torque_amplitude_measured_nm=_f(c["torque_amplitude_nm"]),
                       creep_coefficient_fit=_f(c["creep_coefficient"]),
                       n_cycles=int(c["n_cycles"]), slip_flag_chain=bool(c["slip"]))
        rows.append(row)
    pol, pf = ana.polach, ana.phase_fit
    lo, hi = (None, None) if pol is None else pol.mu_interval_95
    point = {"mu_forces": _f(ana.mu), "mu_forces_lo": _f(lo), "mu_forces_hi": _f(hi),
             "mu_forces_determined": bool(ana.mu_determined),
             "mu_forces_lower_bound": _f(ana.mu_lower_bound)}
    plo, phi = (None, None) if pf is None else pf.mu_interval_95
    point.update(mu_phase_all=_f(None if pf is None else pf.mu), mu_phase_all_lo=_f(plo),
                 mu_phase_all_hi=_f(phi),
                 mu_phase_all_determined=bool(pf is not None and pf.mu_determined))
    return rows, point


def _process_in_memory(run, cfg):
    """The processing chain (as :func:`torquemod.api.process` with ``workers=1``) on a
    :class:`~torquemod.twins.vtrack.rig.simrun.SimulatedRun`'s recordings, without files."""
    from torquemod.processing.pipeline import load_and_process, process_experiment, resolve_config
    exp = run.experiment()
    cfg = resolve_config(exp, cfg)
    loaded = ((e, load_and_process(e, exp, cfg, recording=run.recording(exp, e)))
              for e in exp.recordings)
    return process_experiment(exp, config=cfg, workers=1, loaded=loaded)


def _friction_at_top(df: pd.DataFrame, use: pd.Series, rig) -> float:
    """The twin's friction coefficient (Polach 2005 Eq. 9) at the slip velocity of the
    highest step the fit from the phase used (creepage x speed at its operating point),
    reported beside ``mu_true`` (the creep curve's peak, the available adhesion, which that
    fit estimates and which lies below it where friction falls with slip). NaN when no step
    was used."""
    from torquemod.analysis.contact.polach import friction_coefficient
    used = df[use]
    if not len(used) or not np.isfinite(used["creepage_true"].iloc[-1]):
        return math.nan
    c = rig.contact
    w = abs(float(used["creepage_true"].iloc[-1])) * rig.speed_m_s
    return float(friction_coefficient(w, mu0=c.mu0, a_ratio=c.a_ratio, b_s_m=c.b_s_m))


def evaluate_point(task: PointTask, *, workdir: str | Path | None = None,
                   through_files: bool = False) -> pd.DataFrame:
    """The rows of one sweep point, one per torque step.

    A rig point in full mode runs the twin, the chain and the fits in memory; with
    ``through_files`` the twin's experiment is written as HDF5 into a temporary folder in
    ``workdir`` (removed after) and read back by the chain, which gives the same rows. A
    train point (:func:`torquemod.sweep.trainpoint.evaluate_train_point`) uses ``workdir``
    for its run.

    Parameters
    ----------
    task : PointTask
        The point.
    workdir : str or pathlib.Path or None
        Folder for temporary files. Default None (the system's).
    through_files : bool
        Go through files instead of memory (rig, full mode). Default False.

    Returns
    -------
    pandas.DataFrame
        The point's rows of the sweep table.

    Raises
    ------
    TorquemodError
        The point cannot be evaluated: a bad parameter, a wheel that slips at the first step.
    """
    if task.kind == "train":
        from torquemod.sweep.trainpoint import evaluate_train_point
        return evaluate_train_point(task, workdir=workdir)
    t0 = time.perf_counter()
    config, t_peak = point_config(task)
    rig, mod = config.rig, config.modulation
    mu_true = t_peak / (rig.wheel_radius_m * rig.normal_load_n)
    rows = _theory_steps(config, t_peak)
    point = {}
    settle = math.nan  # theory mode simulates nothing
    if task.mode == "full":
        settle = settle_time_s(config, rows)
        config = dataclasses.replace(config, procedure=dataclasses.replace(
            config.procedure, settle_s=settle))
        if through_files:
            tmp = Path(tempfile.mkdtemp(prefix=f"sweep-{task.point_id}-", dir=workdir))
            try:
                chain_rows, point = _full_steps(config, t_peak, task.seed, tmp,
                                                task.processing)
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
        else:
            chain_rows, point = _full_steps(config, t_peak, task.seed, None, task.processing)
        by_step = {r["step"]: r for r in chain_rows}
        for r in rows:
            r.update(by_step.get(r["step"], {}))
    df = pd.DataFrame(rows)
    if task.mode != "full":
        point.update(_forces_mu_theory(df))
    for col in ("phase_deg", "phase_se_deg", "coa", "creepage", "phase_simulated_deg"):
        if col not in df:
            df[col] = np.nan
    constant = float(theory_constant(inertia_kg_m2=rig.wheel_inertia_kg_m2,
                                     speed_m_s=rig.speed_m_s, wheel_radius_m=rig.wheel_radius_m,
                                     normal_load_n=rig.normal_load_n,
                                     frequency_hz=mod.actual_frequency_hz))
    below = (~df["slipped"].astype(bool)) & (df["utilisation"] <= task.max_utilisation + 1e-9)
    if task.mode == "full":
        coa = df["coa_torque"].where(np.isfinite(df["coa_torque"]), df["coa"])
        se = df["phase_se_deg"].where(df["phase_se_deg"] > 0, 0.1)
        phase, swing = df["phase_deg"], df["creepage_swing_measured"]
    else:
        coa, phase, swing = df["coa_true"], df["phase_theory_deg"], df["creepage_swing"]
        se = df["phase_crlb_deg"].clip(lower=1e-3)  # noise-free twin: a 0.001 deg floor
    # a step whose DC torque does not exceed the modulation's amplitude reverses the torque
    # within each period: the creepage crosses zero and the phase is not the linearised
    # tan(phi) = C/k the fit models (measured: 1-2 deg below it at zero DC torque on every
    # condition, which pulled mu up to twice the truth on vtrack at 4 Hz)
    linear = df["dc_torque_nm"].abs() > mod.amplitude_nm
    use = below & linear & np.isfinite(coa) & np.isfinite(phase)
    point.update(_phase_mu(coa[use].to_numpy(float), phase[use].to_numpy(float),
                           se[use].to_numpy(float), constant,
                           swing[use].to_numpy(float) if np.isfinite(swing[use]).all()
                           else None, rig.speed_m_s))
    point["mu_phase_n_steps"] = int(use.sum())
    # the fit from the phase estimates the available adhesion: the creep curve's peak
    point["mu_friction"] = _friction_at_top(df, use, rig)
    point["mu_phase_error"] = point["mu_phase"] / mu_true - 1.0
    point["mu_phase_lo_error"] = point["mu_phase_lo"] / mu_true - 1.0
    df["phase_twin_minus_theory_deg"] = df["phase_simulated_deg"] - df["phase_theory_deg"]
    head = {"point_id": task.point_id, "point_index": task.index,
            **{k: v for k, v in task.params.items()}, "seed": task.seed, "kind": "rig",
            "mode": task.mode}
    info = {"modulation_frequency_hz": mod.actual_frequency_hz,
            "modulation_frequency_nominal_hz": mod.frequency_hz,
            "modulation_amplitude_nm": mod.amplitude_nm, "speed_m_s": rig.speed_m_s,
            "normal_load_n": rig.normal_load_n, "wheel_radius_m": rig.wheel_radius_m,
            "wheel_inertia_kg_m2": rig.wheel_inertia_kg_m2, "mu0": rig.contact.mu0,
            "mu_true": mu_true, "peak_torque_nm": t_peak, "theory_constant": constant,
            "settle_s": settle, **point, "point_wall_s": time.perf_counter() - t0}
    for key, value in reversed(list(head.items())):
        df.insert(0, key, [value] * len(df) if isinstance(value, list) else value)
    for key, value in info.items():
        df[key] = value
    return df
