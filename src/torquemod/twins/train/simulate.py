"""The train twin end to end: integrate a run, measure it as a train's logger would, and
write it as a run (``run.toml`` + MDF4, ``run_h5.toml`` + HDF5) with ``truth.parquet``.

Sensors (:func:`measure`): the torque estimated from the motor current (gain error, bias,
noise, optional lag), the axle encoder (eccentricity and tooth errors as harmonics of the
revolution, noise, quantization), the reference speed (radar) on its own clock at a low rate
with a scale error, and the position integrated from it (odometer). The truth is written
once per modulation period: friction at the contact's slip velocity, the curve's peak
(available adhesion), CoA, utilisation, creepage and creep coefficient along the track.
"""

from __future__ import annotations

import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from torquemod import __version__
from torquemod._util.fsutil import atomic_dir, check_output_dir
from torquemod._util.jsonutil import dump_json
from torquemod.errors import ProcessingError
from torquemod.io.truth import adhesion_utilisation, segment_summary
from torquemod.twins.train import dynamics as dyn
from torquemod.twins.train.params import TrainConfig

REFERENCE_CLOCK_OFFSET_S = 0.013  # the radar's first sample after the logger's [s] (assumed)
MDF_NAMES = {"torque": ("Axle1.TorqueEst", "kN*m"), "wheel_speed": ("Axle1.Speed", "rpm"),
             "vehicle_speed": ("Radar.Speed", "km/h"), "position": ("Odometer.Distance", "m")}


def _friction_table(cfg: TrainConfig) -> tuple[np.ndarray, np.ndarray]:
    """Segment starts [m] and their Polach parameters (mu0, A, B, kA, kS), one row each."""
    segs = cfg.track.segments
    starts = np.array([s.start_m for s in segs], dtype=float)
    table = np.array([[s.polach.mu0, s.polach.a_ratio, s.polach.b_s_m, s.polach.k_a,
                       s.polach.k_s] for s in segs], dtype=float)
    return starts, table


def _arrays(cfg: TrainConfig, rng: np.random.Generator) -> dict:
    v, tr, ctl = cfg.vehicle, cfg.track, cfg.controller
    sx = v.stiffness_x_n()
    p = np.zeros(dyn.N_PAR)
    p[dyn.P_R], p[dyn.P_JM], p[dyn.P_JW] = (v.wheel_radius_m, v.motor_inertia_kg_m2,
                                            v.wheelset_inertia_kg_m2)
    p[dyn.P_KC], p[dyn.P_CC], p[dyn.P_M] = (v.coupling_stiffness_nm_rad,
                                            v.coupling_damping_nm_s_rad, v.mass_share_kg)
    p[dyn.P_DA], p[dyn.P_DB], p[dyn.P_DC] = v.davis_a_n, v.davis_b_n_s_m, v.davis_c_n_s2_m2
    p[dyn.P_TAU], p[dyn.P_N0], p[dyn.P_SX] = v.motor_time_constant_s, v.normal_load_n, sx
    p[dyn.P_AMP] = cfg.modulation_amplitude_nm
    p[dyn.P_OMEGA] = 2 * math.pi * cfg.modulation_frequency_hz
    p[dyn.P_TRANS], p[dyn.P_KP] = tr.transition_m, ctl.speed_gain_n_s_m
    p[dyn.P_AS_XI], p[dyn.P_AS_CUT] = ctl.antislip_creepage, ctl.antislip_cut_per_s
    p[dyn.P_AS_FLOOR], p[dyn.P_AS_REST] = ctl.antislip_floor, ctl.antislip_restore_per_s
    starts, table = _friction_table(cfg)
    n_w = len(tr.irregularity_wavelengths_m)
    amp = tr.load_variation_rms * math.sqrt(2.0 / n_w) if n_w else 0.0
    irr = np.array([[amp, 2 * math.pi / lam, rng.uniform(0, 2 * math.pi)]
                    for lam in tr.irregularity_wavelengths_m], dtype=float).reshape(-1, 3)
    peak, _ = dyn.adhesion_peak(cfg.initial_speed_m_s, v.normal_load_n, sx, *table.T)
    legs = ctl.legs
    n_lv = max([len(leg.levels) for leg in legs] + [1])
    levels = np.zeros((len(legs), n_lv))
    for j, leg in enumerate(legs):
        levels[j, :len(leg.levels)] = leg.levels
    return dict(
        p=p, starts=starts, table=table, irr=irr,
        leg_until=np.array([leg.until_m for leg in legs], dtype=float),
        leg_mode=np.array([dyn.MODES[leg.mode] for leg in legs], dtype=np.int64),
        leg_val=np.array([leg.torque_nm if leg.mode == "torque" else leg.speed_m_s
                          for leg in legs], dtype=float),
        leg_others=np.array([leg.others_force_n for leg in legs], dtype=float),
        leg_step=np.array([leg.step_m for leg in legs], dtype=float),
        levels=levels, n_levels=np.array([len(leg.levels) for leg in legs], dtype=np.int64),
        seg_peak=np.asarray(peak, dtype=float).reshape(-1), stiffness_x_n=sx)


def integrate_run(cfg: TrainConfig, *, seed: int = 0, block_s: float = 20.0) -> np.ndarray:
    """The true signals of a run (columns :data:`dynamics.OUT`) at the logger's rate, from
    the start until the train has run ``track.length_m``.

    Parameters
    ----------
    cfg : TrainConfig
        The train twin's configuration.
    seed : int
        Random seed (irregularity phases). Default 0.
    block_s : float
        Time integrated per block [s]. Default 20.

    Returns
    -------
    ndarray
        The true signals (:data:`dynamics.OUT` columns).

    Raises
    ------
    ProcessingError
        The integration diverged, or the train stopped before the end of the track.
    """
    rng = np.random.default_rng([seed, 10])
    a = _arrays(cfg, rng)
    v0 = cfg.initial_speed_m_s
    r = cfg.vehicle.wheel_radius_m
    y = np.array([0.0, v0 / r, v0 / r, v0, 0.0, 0.0])
    fs = cfg.sensors.sample_rate_hz
    dt = 1.0 / fs
    n_block = round(block_s * fs)
    blocks, t0 = [], 0.0
    max_s = 5.0 * cfg.track.length_m / max(v0, 1.0) + 600.0
    while y[4] < cfg.track.length_m and t0 < max_s:
        out = np.empty((n_block, dyn.N_OUT))
        n = dyn.integrate(y, n_block, dt, cfg.substeps, a["p"], a["starts"], a["table"],
                          a["irr"], a["leg_until"], a["leg_mode"], a["leg_val"],
                          a["leg_others"], a["leg_step"], a["levels"], a["n_levels"],
                          a["seg_peak"], out, t0)
        if n < n_block or not np.isfinite(y).all():
            raise ProcessingError(f"the train twin diverged at t = {t0 + n * dt:.3f} s; lower "
                               "the step (run.substeps) or check the configuration")
        if y[3] < 0.5:
            raise ProcessingError(f"the train stopped at {y[4]:.0f} m (speed {y[3]:.2f} m/s); "
                               "give the driver more traction")
        blocks.append(out)
        t0 += n_block * dt
    raw = np.concatenate(blocks)
    return raw[raw[:, 5] <= cfg.track.length_m]


def measure(raw: np.ndarray, cfg: TrainConfig, *, seed: int = 0) -> dict:
    """Logger channels from the true signals: ``torque_nm``, ``wheel_speed_rad_s`` at the
    logger rate, ``reference_time_s``, ``vehicle_speed_m_s``, ``position_m`` at the
    reference's rate (module docstring).

    Parameters
    ----------
    raw : ndarray
        The true signals.
    cfg : TrainConfig
        The train twin's configuration.
    seed : int
        Random seed of the sensor errors. Default 0.

    Returns
    -------
    dict of str to ndarray
        The channels (SI units).
    """
    s = cfg.sensors
    rng = np.random.default_rng([seed, 20])
    fs = s.sample_rate_hz
    n = raw.shape[0]
    tq = raw[:, 1] * (1 + s.torque_gain_error) + s.torque_bias_nm
    if s.torque_lag_s > 0:
        a = math.exp(-1.0 / (fs * s.torque_lag_s))
        from scipy.signal import lfilter  # here: scipy.signal costs ~0.5 s to import
        tq = lfilter([1 - a], [1, -a], tq, zi=[tq[0] * a])[0]
    tq = tq + s.torque_noise_nm * rng.standard_normal(n)
    w = raw[:, 2]
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) / fs)])
    err = s.eccentricity * np.sin(theta + rng.uniform(0, 2 * math.pi))
    k_h = np.arange(2, 9)
    a_h = s.tooth_error_rms * math.sqrt(2.0 / k_h.size)
    for k, ph in zip(k_h, rng.uniform(0, 2 * math.pi, k_h.size), strict=True):
        err += a_h * np.sin(k * theta + ph)
    ws = w * (1 + err) + s.speed_noise_rad_s * rng.standard_normal(n)
    if s.speed_quantum_rad_s > 0:
        ws = np.round(ws / s.speed_quantum_rad_s) * s.speed_quantum_rad_s
    t = raw[:, 0]
    t_ref = np.arange(REFERENCE_CLOCK_OFFSET_S, t[-1], 1.0 / s.reference_rate_hz)
    v_ref = np.interp(t_ref, t, raw[:, 4]) * (1 + s.reference_scale_error)
    v_ref = v_ref + s.reference_noise_m_s * rng.standard_normal(t_ref.size)
    pos = np.interp(t_ref[0], t, raw[:, 5]) + np.concatenate(
        [[0.0], np.cumsum(0.5 * (v_ref[1:] + v_ref[:-1]) * np.diff(t_ref))])
    return {"time_s": t.copy(), "torque_nm": tq, "wheel_speed_rad_s": ws,
            "reference_time_s": t_ref, "vehicle_speed_m_s": v_ref, "position_m": pos}


def truth_table(raw: np.ndarray, cfg: TrainConfig):
    """The truth along the run, one row per modulation period (means of the true signals
    over it, so the modulation averages out), a pandas DataFrame (docs/format.md).

    Parameters
    ----------
    raw : ndarray
        The true signals.
    cfg : TrainConfig
        The train twin's configuration.

    Returns
    -------
    pandas.DataFrame
        Time [s], position [m], speed [m/s], condition, mu [-], available adhesion [-], CoA
        [-], utilisation [-], ...
    """
    import pandas as pd
    fs = cfg.sensors.sample_rate_hz
    m = max(1, round(fs / cfg.modulation_frequency_hz))
    nb = raw.shape[0] // m
    blk = raw[:nb * m].reshape(nb, m, dyn.N_OUT)
    mean = blk.mean(axis=1)
    starts, table = _friction_table(cfg)
    pars = np.array([dyn.friction_params(x, starts, table, cfg.track.transition_m)[0]
                     for x in mean[:, 5]])
    v, n, xi = mean[:, 4], mean[:, 7], mean[:, 8]
    sx = cfg.vehicle.stiffness_x_n()
    peak, xi_peak = dyn.adhesion_peak(v, n, sx, *pars.T)
    h = 1e-3 * np.abs(xi) + 1e-7
    k = (dyn.static_coa(xi + h, v, n, sx, *pars.T)
         - dyn.static_coa(xi - h, v, n, sx, *pars.T)) / (2 * h)
    coa = mean[:, 6] / n
    seg = np.round(mean[:, 12]).astype(int)
    names = [cfg.track.segments[j].condition for j in seg]
    return pd.DataFrame({
        "time_s": mean[:, 0], "position_m": mean[:, 5], "speed_m_s": v,
        "condition": names, "mu": mean[:, 9], "mu0": pars[:, 0], "adhesion_peak": peak,
        "creepage_at_peak": xi_peak, "coa": coa, "utilisation": adhesion_utilisation(coa, peak),
        "creepage": xi, "creep_coefficient": k, "normal_load_n": n,
        "dc_torque_nm": mean[:, 11], "antislip": blk[:, :, 10].min(axis=1) < 1.0})


def _channels_table(fmt: str) -> dict:
    if fmt == "mdf":
        return {key: {"name": name, "unit": unit} for key, (name, unit) in MDF_NAMES.items()}
    return {"time": "time_s", "torque": "torque_nm", "wheel_speed": "wheel_speed_rad_s",
            "vehicle_speed": {"name": "vehicle_speed_m_s", "time": "reference_time_s"},
            "position": {"name": "position_m", "time": "reference_time_s"}}


def vehicle_damping_n_s_m(cfg: TrainConfig) -> float | None:
    """The vehicle's force per unit speed change beyond its inertia [N*s/m] that the twin
    simulates, when one value holds for the whole run: in a probe the other axles hold the
    speed with ``speed_gain_n_s_m`` and cancel the running resistance
    (:func:`~torquemod.twins.train.dynamics._control`), elsewhere the vehicle meets the running
    resistance's slope ``B + 2*C*v`` at the starting speed; None when probes and other legs
    mix (no single value; the estimator then takes the vehicle as an inertia).

    Parameters
    ----------
    cfg : TrainConfig
        The train twin's configuration.

    Returns
    -------
    float or None
        [N*s/m].
    """
    modes = {leg.mode for leg in cfg.controller.legs}
    if modes == {"probe"}:
        return float(cfg.controller.speed_gain_n_s_m)
    if "probe" not in modes:
        v = cfg.vehicle
        return float(v.davis_b_n_s_m + 2.0 * v.davis_c_n_s2_m2 * cfg.initial_speed_m_s)
    return None


def run_manifest(cfg: TrainConfig, file: str, fmt: str) -> dict:
    """The ``run.toml`` document of a simulated run (drive line, the torque signal's lag and
    the vehicle's damping included: the twin knows them).

    Parameters
    ----------
    cfg : TrainConfig
        The train twin's configuration.
    file : str
        The recording's file name.
    fmt : str
        Its format.

    Returns
    -------
    dict
        The run.toml document.
    """
    v = cfg.vehicle
    vehicle = {"vehicle": "torquemod train twin", "wheel_radius_m": v.wheel_radius_m,
               "normal_load_n": v.normal_load_n, "inertia_kg_m2": v.inertia_kg_m2,
               "motor_inertia_kg_m2": v.motor_inertia_kg_m2,
               "coupling_stiffness_nm_rad": v.coupling_stiffness_nm_rad,
               "coupling_damping_nm_s_rad": v.coupling_damping_nm_s_rad}
    if cfg.sensors.torque_lag_s > 0:  # the drive's torque estimate is filtered: declared
        vehicle["torque_lag_s"] = cfg.sensors.torque_lag_s
    damping = vehicle_damping_n_s_m(cfg)
    if damping is not None:
        vehicle["vehicle_damping_n_s_m"] = damping
    return {
        "vehicle": vehicle,
        "test": {"modulation_frequency_hz": cfg.modulation_frequency_hz,
                 "modulation_amplitude_nm": cfg.modulation_amplitude_nm},
        "recording": [{"file": file, "axle": 1}],
        "channels": _channels_table(fmt),
        "truth": {"file": "truth.parquet"},
    }


def _write_mdf(path: Path, ch: dict) -> bool:
    """Write the MDF4 copy of the run; False, and nothing written, when the optional
    package asammdf (``torquemod[mdf]``) is not installed."""
    try:
        from asammdf import MDF, Signal
    except ImportError:
        return False
    t = ch["time_s"]
    mdf = MDF(version="4.10")
    fast = [Signal(ch["torque_nm"] / 1e3, t, name=MDF_NAMES["torque"][0], unit="kN*m"),
            Signal(ch["wheel_speed_rad_s"] * 30 / math.pi, t, name=MDF_NAMES["wheel_speed"][0],
                   unit="rpm")]
    tr = ch["reference_time_s"]
    slow = [Signal(ch["vehicle_speed_m_s"] * 3.6, tr, name=MDF_NAMES["vehicle_speed"][0],
                   unit="km/h"),
            Signal(ch["position_m"], tr, name=MDF_NAMES["position"][0], unit="m")]
    mdf.append(fast, comment="traction drive 1 kHz")
    mdf.append(slow, comment="radar and odometer")
    mdf.save(str(path), overwrite=True)
    mdf.close()
    return True


def _write_h5(path: Path, ch: dict) -> None:
    import h5py
    units = {"time_s": "s", "torque_nm": "N*m", "wheel_speed_rad_s": "rad/s",
             "reference_time_s": "s", "vehicle_speed_m_s": "m/s", "position_m": "m"}
    with h5py.File(path, "w") as f:
        for name, unit in units.items():
            f.create_dataset(name, data=np.asarray(ch[name], dtype=np.float64)).attrs["unit"] = unit


def run_train_simulation(cfg: TrainConfig, out_dir: str | Path, *, seed: int = 0,
                         force: bool = False) -> dict:
    """Simulate ``cfg`` and write the run folder ``out_dir`` (atomically): ``run.toml`` with
    ``run.mf4``, ``run_h5.toml`` with ``run.h5``, ``truth.parquet`` and ``simulation.json``.
    Returns a summary dict (per-segment truth).

    Without the optional package asammdf (``torquemod[mdf]``) no MDF4 copy is written and
    ``run.toml`` names ``run.h5``; the summary's ``"recording"`` says which file it names.

    Parameters
    ----------
    cfg : TrainConfig
        The train twin's configuration.
    out_dir : str or pathlib.Path
        The run folder.
    seed : int
        Random seed. Default 0.
    force : bool
        Replace an existing folder. Default False.

    Returns
    -------
    dict
        Summary (per-segment truth).

    Raises
    ------
    InputError
        An occupied ``out_dir`` without ``force``.
    ProcessingError
        The integration diverged or the train stopped.
    """
    import tomli_w
    check_output_dir(out_dir, force=force)  # an occupied --out: before the simulation
    raw = integrate_run(cfg, seed=seed)
    ch = measure(raw, cfg, seed=seed)
    truth = truth_table(raw, cfg)
    summary = {"kind": "train run", "torquemod_version": __version__, "seed": seed,
               "duration_s": float(raw[-1, 0] - raw[0, 0]), "length_m": float(raw[-1, 5]),
               "samples": int(raw.shape[0]), "segments": segment_summary(truth),
               "antislip_share": float(truth["antislip"].mean())}
    with atomic_dir(Path(out_dir), force=force, kind="train run") as tmp:
        main = ("run.mf4", "mdf") if _write_mdf(tmp / "run.mf4", ch) else ("run.h5", "hdf5")
        summary["recording"] = main[0]
        _write_h5(tmp / "run.h5", ch)
        (tmp / "run.toml").write_text(tomli_w.dumps(run_manifest(cfg, *main)))
        (tmp / "run_h5.toml").write_text(tomli_w.dumps(run_manifest(cfg, "run.h5", "hdf5")))
        truth.to_parquet(tmp / "truth.parquet", index=False)
        (tmp / "simulation.json").write_text(dump_json(dict(summary,
                                                            config=cfg.raw or asdict(cfg))))
    return summary

