"""Sensor models: what the torque sensor, the encoders and the dynamometer record.

Encoder eccentricity: the measured angle is ``theta + e1*sin(theta+phi1) + e2*sin(2*theta+phi2)``
so the measured speed is ``w*(1 + e1*cos(theta+phi1) + 2*e2*cos(2*theta+phi2))``: tones at
once and twice the shaft's rotation frequency, proportional to the speed.
"""

from __future__ import annotations

import numpy as np

from .dynamics import OUT_COLUMNS
from .params import DisturbanceParams, SensorParams

_COL = {name: i for i, name in enumerate(OUT_COLUMNS)}


def encoder_speed(speed_rad_s: np.ndarray, angle_rad: np.ndarray, *, ecc1_rad: float,
                  ecc2_rad: float, phase1_rad: float, phase2_rad: float) -> np.ndarray:
    """Speed [rad/s] seen by an eccentric encoder (derivative of the angle error above)."""
    err = ecc1_rad * np.cos(angle_rad + phase1_rad) + 2.0 * ecc2_rad * np.cos(
        2.0 * angle_rad + phase2_rad)
    return speed_rad_s * (1.0 + err)


def measure(raw: np.ndarray, *, disturbances: DisturbanceParams, sensors: SensorParams,
            rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Sensor channels (names of :data:`torquemod.data.CHANNELS`) from the true signals
    ``raw`` (columns :data:`torquemod.rig.dynamics.OUT_COLUMNS`). Forces keep the contact
    sign convention: ``fx_n`` > 0 is traction for positive drive torque."""
    d, s = disturbances, sensors
    n = raw.shape[0]
    ch = {
        "torque_nm": raw[:, _COL["torque_nm"]].copy(),
        "wheel_speed_rad_s": raw[:, _COL["wheel_speed_rad_s"]].copy(),
        "platform_speed_rad_s": raw[:, _COL["platform_speed_rad_s"]].copy(),
        "fx_n": raw[:, _COL["fx_n"]].copy(),
        "fy_n": raw[:, _COL["fy_n"]].copy(),
        "fz_n": raw[:, _COL["fz_n"]].copy(),
    }
    if not d.enabled:
        return ch
    ch["wheel_speed_rad_s"] = encoder_speed(
        ch["wheel_speed_rad_s"], raw[:, _COL["wheel_angle_rad"]], ecc1_rad=d.wheel_encoder_ecc1_rad,
        ecc2_rad=d.wheel_encoder_ecc2_rad, phase1_rad=d.wheel_encoder_phase1_rad,
        phase2_rad=d.wheel_encoder_phase2_rad)
    ch["platform_speed_rad_s"] = encoder_speed(
        ch["platform_speed_rad_s"], raw[:, _COL["platform_angle_rad"]],
        ecc1_rad=d.platform_encoder_ecc1_rad, ecc2_rad=d.platform_encoder_ecc2_rad,
        phase1_rad=d.platform_encoder_phase1_rad, phase2_rad=d.platform_encoder_phase2_rad)
    sigma = {"torque_nm": s.torque_noise_nm, "wheel_speed_rad_s": s.wheel_speed_noise_rad_s,
             "platform_speed_rad_s": s.platform_speed_noise_rad_s, "fx_n": s.force_noise_n,
             "fy_n": s.force_noise_n, "fz_n": s.force_noise_n}
    for name, sd in sigma.items():
        if sd > 0:
            ch[name] = ch[name] + rng.normal(0.0, sd, n)
    return ch
