"""Sensor models: what the torque sensor, the encoders and the dynamometer record.

Encoder eccentricity: the measured angle is ``theta + e1*sin(theta+phi1) + e2*sin(2*theta+phi2)``
so the measured speed is ``w*(1 + e1*cos(theta+phi1) + 2*e2*cos(2*theta+phi2))``: tones at
once and twice the shaft's rotation frequency, proportional to the speed.

numba caches :func:`_encoder_noise_kernel` under this file's name and time stamp only: the
generator it compiles in from :mod:`~torquemod.twins.vtrack.rig.noise` (``_splitmix``,
``_normal_rest``) does not invalidate it, so a change there must come with an edit of this
file (or a cleared ``__pycache__``) to take effect here.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from torquemod.twins.vtrack.params import DisturbanceParams, SensorParams
from torquemod.twins.vtrack.rig.dynamics import OUT_COLUMNS
from torquemod.twins.vtrack.rig.kernels import FLAGS as _FLAGS
from torquemod.twins.vtrack.rig.kernels import cos_small as _cos_small
from torquemod.twins.vtrack.rig.kernels import sin_small as _sin_small
from torquemod.twins.vtrack.rig.noise import (
    _LOW8,
    _ONE,
    _S8,
    _S12,
    _ZF,
    _ZK,
    _ZW,
    _normal_rest,
    _splitmix,
    add_normal,
    add_normal_pair,
)

_COL = {name: i for i, name in enumerate(OUT_COLUMNS)}
#: the recorded channels, in the order their noise is drawn
_NOISY = ("torque_nm", "wheel_speed_rad_s", "platform_speed_rad_s", "fx_n", "fy_n", "fz_n")
#: speed channel -> the angle its encoder reads
_ENCODER = {"wheel_speed_rad_s": "wheel_angle_rad", "platform_speed_rad_s": "platform_angle_rad"}


def encoder_speed(speed_rad_s: np.ndarray, angle_rad: np.ndarray, *, ecc1_rad: float,
                  ecc2_rad: float, phase1_rad: float, phase2_rad: float) -> np.ndarray:
    """Speed [rad/s] seen by an eccentric encoder (derivative of the angle error above).
    :func:`measure` evaluates the same formula sample by sample (``_encoder_kernel``).

    Parameters
    ----------
    speed_rad_s : ndarray
        True angular speed [rad/s].
    angle_rad : ndarray
        True angle [rad].
    ecc1_rad, ecc2_rad : float
        Once- and twice-per-revolution angle errors [rad].
    phase1_rad, phase2_rad : float
        Their phases [rad].

    Returns
    -------
    ndarray
        Measured speed [rad/s].
    """
    err = ecc1_rad * np.cos(angle_rad + phase1_rad) + 2.0 * ecc2_rad * np.cos(
        2.0 * angle_rad + phase2_rad)
    return speed_rad_s * (1.0 + err)


@numba.njit(cache=True, fastmath=_FLAGS)
def _encoder_step(k, a, prev, c, s, e1, e2, ph1, cd, sd, speed_k):
    """Sample ``k`` of :func:`_encoder_kernel`: the phasor ``(c, s)`` of ``angle + ph1``
    carried from the previous angle ``prev`` to ``a`` and the measured speed; returns
    ``(c, s, speed)``."""
    d = a - prev
    if k % 256 == 0 or not abs(d) <= 0.05:
        c, s = math.cos(a + ph1), math.sin(a + ph1)
    else:
        cr, sr = _cos_small(d), _sin_small(d)
        c, s = c * cr - s * sr, s * cr + c * sr
    # cos(2*a + ph2) = cos(2*(a + ph1) + (ph2 - 2*ph1))
    c2 = (2.0 * c * c - 1.0) * cd - 2.0 * s * c * sd
    return c, s, speed_k * (1.0 + e1 * c + 2.0 * e2 * c2)


@numba.njit(cache=True, nogil=True, fastmath=_FLAGS)
def _encoder_kernel(speed, angle, e1, e2, ph1, ph2, out):
    """:func:`encoder_speed` sample by sample. ``cos(angle + ph1)`` is carried along by rotating
    through each sample's small angle increment (exact sin/cos every 256 samples and after
    any jump larger than 0.05 rad); the second harmonic follows from the double angle
    (:func:`_encoder_step`)."""
    cd, sd = math.cos(ph2 - 2.0 * ph1), math.sin(ph2 - 2.0 * ph1)
    c = 1.0
    s = 0.0
    prev = 0.0
    for k in range(speed.size):
        a = angle[k]
        c, s, out[k] = _encoder_step(k, a, prev, c, s, e1, e2, ph1, cd, sd, speed[k])
        prev = a


@numba.njit(cache=True, nogil=True)
def _encoder_noise_kernel(speed, angle, e1, e2, ph1, ph2, sigma, state, zk, zw, zf, out):
    """:func:`_encoder_kernel` followed by :func:`~torquemod.twins.vtrack.rig.noise.add_normal`
    in one pass: ``out[k]`` is the encoder's speed plus ``sigma`` times the stream's next
    normal number, the same operations as the two passes (the encoder's with fast-math, the
    noise's addition without), so the same values; the encoder's floating-point chain and
    the generator's integer work overlap. Returns the stream's state."""
    cd, sd = math.cos(ph2 - 2.0 * ph1), math.sin(ph2 - 2.0 * ph1)
    c = 1.0
    s = 0.0
    prev = 0.0
    for k in range(speed.size):
        a = angle[k]
        c, s, v = _encoder_step(k, a, prev, c, s, e1, e2, ph1, cd, sd, speed[k])
        prev = a
        state, r = _splitmix(state)  # add_normal's draw, written out as there
        i = np.intp(r & _LOW8)
        m = np.int64(r >> _S12)
        if m < zk[i]:
            z = (1.0 - 2.0 * float(np.int64((r >> _S8) & _ONE))) * (float(m) * zw[i])
        else:
            state, z = _normal_rest(state, r, zk, zw, zf)
        out[k] = v + sigma * z
    return state


def measure(raw: np.ndarray, *, disturbances: DisturbanceParams, sensors: SensorParams,
            rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Sensor channels (names of :data:`torquemod.io.experiment.CHANNELS`) from the true signals
    ``raw`` (columns :data:`torquemod.twins.vtrack.rig.dynamics.OUT_COLUMNS`). Forces keep the
    contact
    sign convention: ``fx_n`` > 0 is traction for positive drive torque.

    The channels are the contiguous rows of one new float64 array. White Gaussian noise of
    each channel's standard deviation comes from its own splitmix64 stream
    (:mod:`torquemod.twins.vtrack.rig.noise`), whose 64-bit start states are drawn from ``rng`` in
    the
    order of :data:`_NOISY` (one word per channel, drawn whether or not it has noise), and is
    added in the same pass that copies the channel out of ``raw``.

    Parameters
    ----------
    raw : ndarray
        The true signals.
    disturbances : DisturbanceParams
        Encoder eccentricities.
    sensors : SensorParams
        Noise levels.
    rng : numpy.random.Generator
        Draws the noise streams' start states.

    Returns
    -------
    dict of str to ndarray
        The channels (SI units).
    """
    d, s = disturbances, sensors
    n = raw.shape[0]
    block = np.empty((len(_NOISY), n))
    ch = {name: block[k] for k, name in enumerate(_NOISY)}
    if not d.enabled:
        for k, name in enumerate(_NOISY):
            block[k] = raw[:, _COL[name]]
        return ch
    states = rng.integers(0, np.iinfo(np.uint64).max, size=len(_NOISY), dtype=np.uint64,
                          endpoint=True)
    encs = {"wheel_speed_rad_s": (d.wheel_encoder_ecc1_rad, d.wheel_encoder_ecc2_rad,
                                  d.wheel_encoder_phase1_rad, d.wheel_encoder_phase2_rad),
            "platform_speed_rad_s": (d.platform_encoder_ecc1_rad, d.platform_encoder_ecc2_rad,
                                     d.platform_encoder_phase1_rad,
                                     d.platform_encoder_phase2_rad)}
    sigma = {"torque_nm": s.torque_noise_nm, "wheel_speed_rad_s": s.wheel_speed_noise_rad_s,
             "platform_speed_rad_s": s.platform_speed_noise_rad_s, "fx_n": s.force_noise_n,
             "fy_n": s.force_noise_n, "fz_n": s.force_noise_n}
    # the channels with noise only, two per pass (their streams' work overlaps)
    plain = [k for k, name in enumerate(_NOISY) if name not in encs and sigma[name] > 0]
    for k1, k2 in zip(plain[0::2], plain[1::2], strict=False):
        n1, n2 = _NOISY[k1], _NOISY[k2]
        add_normal_pair(raw[:, _COL[n1]], sigma[n1], int(states[k1]), ch[n1],
                        raw[:, _COL[n2]], sigma[n2], int(states[k2]), ch[n2])
    paired = set(plain) if len(plain) % 2 == 0 else set(plain[:-1])
    for k, name in enumerate(_NOISY):
        if k in paired:
            continue
        src = raw[:, _COL[name]]
        if name in encs and sigma[name] > 0:  # the encoder and its noise in one pass
            _encoder_noise_kernel(src, raw[:, _COL[_ENCODER[name]]], *encs[name],
                                  float(sigma[name]), np.uint64(int(states[k])), _ZK, _ZW,
                                  _ZF, ch[name])
            continue
        if name in encs:
            _encoder_kernel(src, raw[:, _COL[_ENCODER[name]]], *encs[name], ch[name])
            src = ch[name]
        if sigma[name] > 0:
            add_normal(src, sigma[name], int(states[k]), ch[name])
        elif name not in encs:
            ch[name][:] = src
    return ch
