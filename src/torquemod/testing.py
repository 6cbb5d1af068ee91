"""Synthetic recordings with a known truth, for tests, benchmarks and the example experiment.

The signals are written down directly (no dynamics): the torque is a DC level plus the
modulation; the wheel speed carries the modulation delayed by a chosen phase lag; encoders
multiply the true speeds by once- and twice-per-revolution eccentricity errors; forces carry
the sleeper-passing tone; every channel gets vibration tones and white noise. What the chain
must recover (phase, creepage, CoA, modulation frequency) is therefore known exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .data import Recording


@dataclass(frozen=True)
class SyntheticSpec:
    """Parameters of one synthetic recording (SI units).

    ``phase_lag_deg`` is the lag of the wheel-speed modulation behind the torque modulation;
    ``wheel_mod_amplitude_rad_s`` its amplitude. ``wheel_eccentricity`` and
    ``platform_eccentricity`` are relative (1x, 2x per revolution) encoder errors.
    """

    fs_hz: float = 16_670.0
    n_revolutions: float = 1.0
    speed_m_s: float = 7.0 / 3.6
    wheel_radius_m: float = 0.0675
    platform_radius_m: float = 2.0
    creepage: float = 2e-3
    normal_load_n: float = 4200.0
    lateral_force_n: float = 40.0
    dc_torque_nm: float = 30.0
    modulation_hz: float = 2.0
    modulation_amplitude_nm: float = 8.0
    modulation_phase_rad: float = 0.3
    phase_lag_deg: float = 20.0
    wheel_mod_amplitude_rad_s: float = 2e-3
    wheel_eccentricity: tuple[float, float] = (7e-3, 3e-3)
    platform_eccentricity: tuple[float, float] = (5e-3, 2e-3)
    torque_noise_nm: float = 0.5
    wheel_noise_rad_s: float = 2e-3
    platform_noise_rad_s: float = 1e-3
    force_noise_n: float = 20.0
    vibration_hz: tuple[float, ...] = (15.5, 37.0, 120.0)
    torque_vibration_nm: float = 0.5
    wheel_vibration_rad_s: float = 1e-3
    sleeper_force_n: float = 60.0
    force_mod_amplitude_n: float = 0.0  # creep-force answer to the modulation, in phase [N]
    seed: int = 0

    @property
    def platform_speed_rad_s(self) -> float:
        return self.speed_m_s / self.platform_radius_m

    @property
    def wheel_speed_rad_s(self) -> float:
        return self.speed_m_s * (1 + self.creepage) / self.wheel_radius_m

    @property
    def coa(self) -> float:
        fx = self.dc_torque_nm / self.wheel_radius_m
        return float(np.hypot(fx, self.lateral_force_n) / self.normal_load_n)


def synthetic_recording(spec: SyntheticSpec) -> Recording:
    """A recording that follows ``spec`` exactly (see the module docstring)."""
    rng = np.random.default_rng(spec.seed)
    omega_p = spec.platform_speed_rad_s
    duration = spec.n_revolutions * 2 * np.pi / omega_p
    n = round(duration * spec.fs_hz)
    t = np.arange(n) / spec.fs_hz
    w_mod = 2 * np.pi * spec.modulation_hz
    arg = w_mod * t + spec.modulation_phase_rad
    torque = spec.dc_torque_nm + spec.modulation_amplitude_nm * np.cos(arg)
    omega_w = spec.wheel_speed_rad_s + spec.wheel_mod_amplitude_rad_s * np.cos(
        arg - np.radians(spec.phase_lag_deg))
    theta_w = spec.wheel_speed_rad_s * t + 0.7
    theta_p = omega_p * t + 1.1
    e1, e2 = spec.wheel_eccentricity
    wheel = omega_w * (1 + e1 * np.cos(theta_w) + e2 * np.cos(2 * theta_w + 0.4))
    p1, p2 = spec.platform_eccentricity
    platform = omega_p * (1 + p1 * np.cos(theta_p) + p2 * np.cos(2 * theta_p + 1.3))
    vib_t = np.zeros(n)
    vib_w = np.zeros(n)
    for k, f in enumerate(spec.vibration_hz):
        vib_t += spec.torque_vibration_nm * np.cos(2 * np.pi * f * t + 0.5 * k)
        vib_w += spec.wheel_vibration_rad_s * np.cos(2 * np.pi * f * t + 1.5 * k)
    sleeper = spec.sleeper_force_n * np.cos(100 * theta_p)
    fx = spec.dc_torque_nm / spec.wheel_radius_m
    channels = {
        "torque_nm": torque + vib_t + spec.torque_noise_nm * rng.standard_normal(n),
        "wheel_speed_rad_s": wheel + vib_w + spec.wheel_noise_rad_s * rng.standard_normal(n),
        "platform_speed_rad_s": platform + spec.platform_noise_rad_s * rng.standard_normal(n),
        "fx_n": fx + spec.force_mod_amplitude_n * np.cos(arg) + 0.2 * sleeper
        + spec.force_noise_n * rng.standard_normal(n),
        "fy_n": spec.lateral_force_n + spec.force_noise_n * rng.standard_normal(n),
        "fz_n": spec.normal_load_n + sleeper + spec.force_noise_n * rng.standard_normal(n),
    }
    return Recording(channels, spec.fs_hz, 0.0, "synthetic")


def write_synthetic_experiment(folder, *, n_steps: int = 6, n_cycles: int = 3,
                               files_per_cycle: bool = True, fmt: str = "csv", seed: int = 0,
                               base: SyntheticSpec | None = None,
                               lags_deg: tuple[float, ...] | None = None) -> dict:
    """Write an experiment folder of synthetic recordings; returns the truth per cycle.

    The phase lag grows with the step (``lags_deg`` per step, default 8..38 deg) and every
    recording has its own modulation phase and a small frequency offset, as a motor
    controller's free-running clock would give. ``files_per_cycle=False`` writes one file per
    step spanning ``n_cycles`` revolutions.
    """
    from pathlib import Path

    from .io import write_manifest, write_recording

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    base = base or SyntheticSpec()
    rng = np.random.default_rng(seed)
    lags = lags_deg or tuple(8.0 + 6.0 * k for k in range(n_steps))
    dc = (0.23, 22.84, 44.47, 55.22, 60.45, 65.82)
    entries, truth = [], {"cycles": []}
    suffix = {"csv": "csv", "hdf5": "h5"}[fmt]
    for k in range(n_steps):
        step = k + 1
        common = dict(phase_lag_deg=lags[k], dc_torque_nm=dc[k % len(dc)],
                      creepage=base.creepage * (1 + 0.5 * k),
                      modulation_hz=base.modulation_hz + float(rng.uniform(-4e-3, 4e-3)))
        chunks = range(1, n_cycles + 1) if files_per_cycle else [None]
        for cyc in chunks:
            spec = SyntheticSpec(**{**base.__dict__, **common,
                                    "n_revolutions": 1.0 if cyc else float(n_cycles),
                                    "modulation_phase_rad": float(rng.uniform(0, 2 * np.pi)),
                                    "seed": int(rng.integers(2**31))})
            rec = synthetic_recording(spec)
            name = f"step{step}_cycle{cyc}.{suffix}" if cyc else f"step{step}.{suffix}"
            write_recording(folder / name, rec, fmt=fmt)
            entry = {"step": step, "dc_torque_nm": spec.dc_torque_nm, "file": name}
            if cyc:
                entry["cycle"] = cyc
            entries.append(entry)
            truth["cycles"].append({"step": step, "cycle": cyc, "phase_deg": spec.phase_lag_deg,
                                    "modulation_hz": spec.modulation_hz,
                                    "creepage": spec.creepage, "coa": spec.coa})
    write_manifest(folder / "experiment.toml",
                   rig={"wheel_radius_m": base.wheel_radius_m,
                        "platform_radius_m": base.platform_radius_m},
                   test={"normal_load_n": base.normal_load_n,
                         "modulation_frequency_hz": 2.0,
                         "modulation_amplitude_nm": base.modulation_amplitude_nm},
                   recordings=entries)
    return truth
