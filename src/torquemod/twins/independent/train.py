"""An independent train run for checking the on-board estimator on data that the
project's own twin (:mod:`torquemod.twins.train`) did not make.

Written from scratch on purpose: it imports nothing of ``torquemod.twins.train``,
``torquemod.twins.vtrack.rig``
or ``torquemod.analysis.contact``, and it differs from the twin where a hidden run could differ:

* **Creep law**: not Polach. Either a saturating constant-friction curve
  ``CoA = mu*tanh(k0*xi/mu)`` (``law="tanh"``) or the Burckhardt form
  ``CoA = mu_B*(1 - exp(-c*xi)) - d*xi`` (``law="burckhardt"``; Burckhardt 1993, as used in
  road-tyre ABS models), parametrised here by its initial slope ``k0``, its peak ``mu`` and
  the fall ``d = d_over_mu*mu`` beyond the peak: ``c = (k0 - d*ln(1 + k0/d))/mu`` and
  ``mu_B = (k0 + d)/c`` put the maximum exactly at ``mu`` (derived by setting dCoA/dxi = 0).
  The truth's ``mu`` is the available adhesion: the curve's maximum (its asymptote for tanh).
  A control, ``law="polach"``: Polach's constant-friction curve (Polach 2005 Eq. 8, written
  here in reduced form) ``CoA = mu*(2/pi)*(r*x/(1 + (r*x)^2) + arctan(x))`` with
  ``x = xi*k0*pi/(2*mu*(1 + r))`` (so that dCoA/dxi = k0 at zero creepage) and
  ``r = kA/kS = polach_ratio``: the shape the estimator's model family contains, so that a
  failure on tanh/Burckhardt runs can be told from a failure of the run itself.
* **Vehicle**: one powered axle, a rigid drive line (or, optionally, a compliant coupling
  between the motor and the wheelset, the encoder then seeing the motor), a first-order
  traction motor (its torque
  follows the command with ``motor_time_constant_s``), the vehicle's share of mass; the other
  axles cancel this axle's DC tractive force and the running resistance (a measurement train
  shifting torque between axles) with only a weak speed-holding term, so the speed stays
  near ``speed_m_s``. Axle load varies with a few track-irregularity wavelengths.
* **Friction map**: segments of (name, start, mu, k0) with linear transitions.
* **Probe**: a DC torque staircase ``levels`` x the available adhesion (the smallest mu a
  little behind and ahead of the axle), a step every ``step_m`` metres, rate-limited, plus
  the modulation ``amplitude_nm*sin(2*pi*f*t)`` at the axle; or a constant demand
  ``constant_torque_nm`` (a driver's, blind to the friction), with a simple anti-slip cut
  when the creepage exceeds 0.03.
* **Sensors**: torque and speed recorded at the MOTOR (axle torque / gear ratio, axle speed x
  gear ratio, in rpm), the torque with a first-order lag, a gain error and white noise; the
  speed from an encoder with once-per-motor-revolution eccentricity, a once-per-axle ripple,
  a short counting gate and quantisation; a radar speed in km/h at ``radar_rate_hz`` with its
  own clock offset, scale error and noise, in its own MDF4 channel group; NO position
  channel; logger names ``EM1_Trq``, ``EM1_Spd``, ``Radar_v``; logger time starting at ``t0_s``.

:func:`write_independent_run` writes ``run.mf4`` (or a logger-style ``run.h5``), ``run.toml``
(docs/format.md) and
``truth.parquet`` (one row per modulation period, on the logger's clock; NOT named in
run.toml, as a hidden run would not name it).

Integration: fixed-step classical RK4 (``substeps`` steps per logger sample) compiled with
numba; the stiffest mode is the contact damping, ``R^2*N*k0/(V*J)`` ~ 600 1/s, far inside
RK4's stability limit at the default 1/8 ms step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from torquemod.twins.independent.vehicle import (
    IndependentRunSpec,
    creep_slope,
    friction_map,
    segment_names,
    simulate_vehicle,
)


@dataclass(frozen=True)
class IndependentRun:
    """A simulated independent run: the true signals and what the sensors recorded.

    Attributes
    ----------
    spec : IndependentRunSpec
        The run's specification.
    t_s : ndarray
        Logger clock [s].
    torque_nm : ndarray
        True axle torque [N*m].
    wheel_speed_rad_s : ndarray
        True axle speed [rad/s].
    speed_m_s : ndarray
        Vehicle speed [m/s].
    position_m : ndarray
        Position [m].
    coa : ndarray
        CoA [-].
    mu : ndarray
        Available adhesion [-].
    k0 : ndarray
        Initial slope of the creep curve [-].
    normal_load_n : ndarray
        Axle load [N].
    dc_torque_nm : ndarray
        DC torque demand [N*m].
    motor_torque_nm : ndarray
        Recorded torque, at the motor [N*m].
    motor_speed_rpm : ndarray
        Recorded speed, at the motor [rpm].
    radar_t_s : ndarray
        Radar sample times, logger clock [s].
    radar_km_h : ndarray
        Radar speed [km/h].
    """

    spec: IndependentRunSpec
    t_s: np.ndarray
    torque_nm: np.ndarray
    wheel_speed_rad_s: np.ndarray
    speed_m_s: np.ndarray
    position_m: np.ndarray
    coa: np.ndarray
    mu: np.ndarray
    k0: np.ndarray
    normal_load_n: np.ndarray
    dc_torque_nm: np.ndarray
    motor_torque_nm: np.ndarray      # recorded, at the motor [N*m]
    motor_speed_rpm: np.ndarray      # recorded, at the motor [rpm]
    radar_t_s: np.ndarray
    radar_km_h: np.ndarray

    @property
    def creepage(self) -> np.ndarray:
        return (self.wheel_speed_rad_s * self.spec.wheel_radius_m - self.speed_m_s) \
            / self.speed_m_s


def _mu_around(spec: IndependentRunSpec, xs, mus) -> np.ndarray:
    """Smallest mu within [x - look_behind, x + look_ahead] on a 1-m grid."""
    grid = np.arange(0.0, spec.length_m + spec.look_ahead_m + 2.0)
    mu = np.interp(grid, xs, mus)
    out = np.empty_like(mu)
    b, a = int(spec.look_behind_m), int(spec.look_ahead_m)
    for i in range(grid.size):
        out[i] = mu[max(0, i - b):i + a + 1].min()
    return out


def simulate_independent(spec: IndependentRunSpec) -> IndependentRun:
    """Integrate the run and apply the sensors (module docstring).

    Parameters
    ----------
    spec : IndependentRunSpec
        The run.

    Returns
    -------
    IndependentRun
        True signals and recordings.
    """
    rng = np.random.default_rng(spec.seed)
    xs, mus, ks = friction_map(spec)
    fs = spec.sample_rate_hz
    n = math.ceil(spec.length_m / spec.speed_m_s * fs)
    lam = np.array([w for w, _ in spec.load_variation], dtype=float)
    lama = np.array([a for _, a in spec.load_variation], dtype=float)
    lamp = rng.uniform(0, 2 * np.pi, lam.size)
    p = np.array([spec.wheel_radius_m, spec.normal_load_n, spec.inertia_kg_m2, spec.mass_kg,
                  spec.motor_time_constant_s, spec.modulation_frequency_hz,
                  spec.modulation_amplitude_nm, float(spec.law_code),
                  spec.shape, spec.speed_gain_n_s_m, spec.speed_m_s,
                  spec.coupling_stiffness_nm_rad or 0.0, spec.coupling_damping_nm_s_rad,
                  spec.motor_inertia_kg_m2])
    if spec.constant_torque_nm is None:
        levels, mu_around = np.asarray(spec.levels, dtype=float), _mu_around(spec, xs, mus)
    else:  # the demand as one "level" of a friction of 1
        levels = np.array([spec.constant_torque_nm / (spec.normal_load_n * spec.wheel_radius_m)])
        mu_around = np.ones(int(spec.length_m) + 2)
    out = simulate_vehicle(n, fs, spec.substeps, p, xs, mus, ks, lam, lamp, lama, levels,
                    spec.step_m, mu_around, spec.torque_rate_nm_s, 0.03)
    tm, w, v, x, coa, mu, nl, tdc, wm = out
    t = spec.t0_s + np.arange(n) / fs
    # torque sensor: first-order lag (exact discretisation), gain, noise; at the motor
    g = spec.gear_ratio
    a = math.exp(-1.0 / (fs * spec.torque_lag_s)) if spec.torque_lag_s > 0 else 0.0
    from scipy.signal import lfilter
    lagged = lfilter([1 - a], [1, -a], tm, zi=[a * tm[0]])[0]
    motor_torque = spec.torque_gain * lagged / g + rng.normal(0, spec.torque_noise_nm, n)
    # encoder on the motor shaft: its angle, ripple, a counting gate, quantisation
    theta_axle = np.concatenate([[0.0], np.cumsum(0.5 * (wm[1:] + wm[:-1]) / fs)])
    theta_m = g * theta_axle + rng.uniform(0, 2 * np.pi)
    ripple_phase = rng.uniform(0, 2 * np.pi)
    angle = theta_m + spec.encoder_eccentricity * np.sin(theta_m) \
        + g * spec.axle_ripple * np.sin(theta_axle + ripple_phase)
    gate = max(1, spec.encoder_gate_samples)
    omega_m = np.empty(n)
    omega_m[gate:] = (angle[gate:] - angle[:-gate]) * fs / gate
    omega_m[:gate] = omega_m[gate]
    rpm = omega_m * 60 / (2 * np.pi)
    rpm = np.round(rpm / spec.speed_quantum_rpm) * spec.speed_quantum_rpm
    # radar: own clock, own rate, scale error and noise, km/h
    t_r = np.arange(t[0] + spec.radar_offset_s, t[-1] + 0.2, 1.0 / spec.radar_rate_hz)
    v_r = np.interp(t_r, t, v) * spec.radar_scale + rng.normal(0, spec.radar_noise_m_s,
                                                                t_r.size)
    k0 = np.interp(x, xs, ks)
    return IndependentRun(spec, t, tm, w, v, x, coa, mu, k0, nl, tdc, motor_torque, rpm,
                          t_r, v_r * 3.6)


def truth_table(run: IndependentRun):
    """One row per modulation period: ``time_s`` (centre, logger clock), ``position_m``,
    ``speed_m_s``, ``condition``, ``mu`` (available adhesion), ``coa`` (period mean),
    ``utilisation`` (coa/mu), ``creepage`` and ``creep_coefficient`` (slope of the law at the
    period's mean creepage), ``normal_load_n``, ``dc_torque_nm``.

    Parameters
    ----------
    run : IndependentRun
        The run.

    Returns
    -------
    pandas.DataFrame
        One row per modulation period (SI units; mu, coa, utilisation, creepage and creep
        coefficient dimensionless).
    """
    import pandas as pd
    s = run.spec
    per = round(s.sample_rate_hz / s.modulation_frequency_hz)
    m = run.t_s.size // per
    cut = slice(0, m * per)

    def mean(a):
        return a[cut].reshape(m, per).mean(axis=1)

    xi = mean(run.creepage)
    mu, k0 = mean(run.mu), mean(run.k0)
    coa = mean(run.coa)
    pos = mean(run.position_m)
    return pd.DataFrame({
        "time_s": mean(run.t_s), "position_m": pos, "speed_m_s": mean(run.speed_m_s),
        "condition": segment_names(s, pos), "mu": mu, "coa": coa, "utilisation": coa / mu,
        "creepage": xi,
        "creep_coefficient": creep_slope(xi, mu, k0, s.law, s.shape),
        "normal_load_n": mean(run.normal_load_n), "dc_torque_nm": mean(run.dc_torque_nm)})


def _toml_value(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(float(v)) if isinstance(v, float) else str(v)


def _write_mdf4(run: IndependentRun, path: Path) -> None:
    from asammdf import MDF, Signal
    mdf = MDF(version="4.10")
    mdf.append([Signal(run.motor_torque_nm, run.t_s, name="EM1_Trq", unit="Nm"),
                Signal(run.motor_speed_rpm, run.t_s, name="EM1_Spd", unit="rpm")],
               comment="traction motor 1")
    mdf.append([Signal(run.radar_km_h, run.radar_t_s, name="Radar_v", unit="km/h")],
               comment="Doppler radar")
    mdf.save(path, overwrite=True)
    mdf.close()


def _write_hdf5(run: IndependentRun, path: Path) -> None:
    """A logger export: groups ``logger`` (time ``t`` in ms, EM1_Trq, EM1_Spd) and ``radar``
    (its own time ``t`` in ms, ``v``); no unit attributes (the manifest gives them)."""
    import h5py
    with h5py.File(path, "w") as f:
        f["logger/t"] = run.t_s * 1e3
        f["logger/EM1_Trq"] = run.motor_torque_nm
        f["logger/EM1_Spd"] = run.motor_speed_rpm
        f["radar/t"] = run.radar_t_s * 1e3
        f["radar/v"] = run.radar_km_h


def write_independent_run(spec: IndependentRunSpec, folder: str | Path, *, fmt: str = "mdf4"
                          ) -> tuple[Path, IndependentRun]:
    """Simulate ``spec`` and write the recording, ``run.toml`` and ``truth.parquet`` into
    ``folder``. ``fmt="mdf4"``: ``run.mf4``, channel group 0 EM1_Trq [Nm] and EM1_Spd [rpm]
    at ``sample_rate_hz``, group 1 Radar_v [km/h] at ``radar_rate_hz`` (each group with its
    own master); ``fmt="hdf5"``: ``run.h5`` as :func:`_write_hdf5` (times in ms, the radar's
    own time vector named in ``[channels]``). Returns (run.toml path, the run).

    Parameters
    ----------
    spec : IndependentRunSpec
        The run.
    folder : str or pathlib.Path
        The folder.
    fmt : {"mdf4", "hdf5"}
        Recording format. Default "mdf4".

    Returns
    -------
    path : pathlib.Path
        The run.toml.
    run : IndependentRun
        The run.

    Raises
    ------
    ValueError
        An unknown ``fmt``.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    run = simulate_independent(spec)
    if fmt == "mdf4":
        name = "run.mf4"
        _write_mdf4(run, folder / name)
        channels = ['torque = { name = "EM1_Trq", unit = "N*m" }',
                    'wheel_speed = { name = "EM1_Spd", unit = "rpm" }',
                    'vehicle_speed = { name = "Radar_v", unit = "km/h" }']
    elif fmt == "hdf5":
        name = "run.h5"
        _write_hdf5(run, folder / name)
        channels = ['time = { name = "logger/t", unit = "ms" }',
                    'torque = { name = "logger/EM1_Trq", unit = "N*m" }',
                    'wheel_speed = { name = "logger/EM1_Spd", unit = "rpm" }',
                    'vehicle_speed = { name = "radar/v", unit = "km/h", '
                    'time = { name = "radar/t", unit = "ms" } }']
    else:
        raise ValueError(f"fmt must be 'mdf4' or 'hdf5', not {fmt!r}")
    truth_table(run).to_parquet(folder / "truth.parquet", index=False)
    lines = ["# independent test run (torquemod.twins.independent.train): "
             "not made by torquemod's twin",
             "[vehicle]",
             f"wheel_radius_m = {spec.wheel_radius_m!r}",
             f"normal_load_n = {spec.normal_load_n!r}",
             f"inertia_kg_m2 = {spec.inertia_kg_m2!r}",
             f"gear_ratio = {spec.gear_ratio!r}",
             'vehicle = "independent test loco"',
             *([f"motor_inertia_kg_m2 = {spec.motor_inertia_kg_m2!r}",
                f"coupling_stiffness_nm_rad = {spec.coupling_stiffness_nm_rad!r}",
                f"coupling_damping_nm_s_rad = {spec.coupling_damping_nm_s_rad!r}"]
               if spec.declare_drive_line and spec.coupling_stiffness_nm_rad else []),
             *([f"torque_lag_s = {spec.torque_lag_s!r}",
                f"speed_delay_s = {spec.encoder_gate_samples / (2 * spec.sample_rate_hz)!r}"]
               if spec.declare_sensor_dynamics else []),
             "", "[test]",
             f"modulation_frequency_hz = {spec.modulation_frequency_hz!r}",
             f"modulation_amplitude_nm = {spec.modulation_amplitude_nm!r}",
             "", "[[recording]]", f'file = "{name}"', "axle = 1",
             "", "[channels]", *channels]
    for table, body in spec.extra_toml.items():
        lines += ["", f"[{table}]"] + [f"{k} = {_toml_value(v)}" for k, v in body.items()]
    path = folder / "run.toml"
    path.write_text("\n".join(lines) + "\n")
    return path, run


__all__ = ["IndependentRun", "simulate_independent", "truth_table", "write_independent_run"]
