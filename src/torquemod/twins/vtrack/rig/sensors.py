"""Sensor models: what the torque sensor, the encoders and the dynamometer record.

Encoder eccentricity: the measured angle is ``theta + e1*sin(theta+phi1) + e2*sin(2*theta+phi2)``
so the measured speed is ``w*(1 + e1*cos(theta+phi1) + 2*e2*cos(2*theta+phi2))``: tones at
once and twice the shaft's rotation frequency, proportional to the speed.

numba caches :func:`_measure_kernel` and :func:`_encoder_noise_kernel` under this file's name
and time stamp only: the generator they compile in from
:mod:`~torquemod.twins.vtrack.rig.noise` (``_splitmix``, ``_normal_rest``) does not invalidate
them, so a change there must come with an edit of this file (or a cleared ``__pycache__``)
to take effect here.
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
#: the columns of ``raw`` the sensors read: the channels of :data:`_NOISY`, then the wheel's
#: and the platform's angle
_COLS = np.array([_COL[name] for name in (*_NOISY, *_ENCODER.values())], dtype=np.int64)
#: the normal number's sign from its word's sign bit (0, 1)
_SIGN = np.array([1.0, -1.0])


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


@numba.njit(cache=True, nogil=True)
def _measure_kernel(raw, cols, sd, states, enc, zk, zw, zf, sgn, out):
    """The six channels of :func:`measure`, every one with noise, in one pass over the rows of
    ``raw``: row ``c`` of ``out`` is column ``cols[c]`` of ``raw`` plus ``sd[c]`` times the
    normal numbers of the splitmix64 stream at ``states[c]``, rows 1 and 2 (wheel and
    platform speed) after their encoders (:func:`_encoder_step`; angles in columns
    ``cols[6]`` and ``cols[7]``; ``enc[j]`` = e1, e2, phase1, phase2). Each channel gets
    the operations of its own passes (:func:`_encoder_kernel` with fast-math, then
    :func:`~torquemod.twins.vtrack.rig.noise.add_normal` without), so the same values
    (tested); each row of ``raw`` is read once and the eight independent chains (six
    generators, two encoder phasors) overlap. The generator's common case is written out
    per channel as in :func:`~torquemod.twins.vtrack.rig.noise.add_normal` (a call per draw
    costs ~5x here), its sign ``1 - 2*b`` of the word's bit ``b`` taken from ``sgn =
    (1.0, -1.0)`` instead of computed (the same product: a multiplication by +-1 is exact,
    signed zeros included; ~20 % less time a draw)."""
    e1w, e2w, p1w, p2w = enc[0, 0], enc[0, 1], enc[0, 2], enc[0, 3]
    e1p, e2p, p1p, p2p = enc[1, 0], enc[1, 1], enc[1, 2], enc[1, 3]
    cdw, sdw = math.cos(p2w - 2.0 * p1w), math.sin(p2w - 2.0 * p1w)
    cdp, sdp = math.cos(p2p - 2.0 * p1p), math.sin(p2p - 2.0 * p1p)
    cw, sw, prevw = 1.0, 0.0, 0.0
    cp, sp, prevp = 1.0, 0.0, 0.0
    s0, s1, s2, s3, s4, s5 = (states[0], states[1], states[2], states[3], states[4],
                              states[5])
    sd0, sd1, sd2, sd3, sd4, sd5 = sd[0], sd[1], sd[2], sd[3], sd[4], sd[5]
    c0, c1, c2, c3, c4, c5 = cols[0], cols[1], cols[2], cols[3], cols[4], cols[5]
    c6, c7 = cols[6], cols[7]
    for k in range(raw.shape[0]):
        aw = raw[k, c6]
        cw, sw, vw = _encoder_step(k, aw, prevw, cw, sw, e1w, e2w, p1w, cdw, sdw, raw[k, c1])
        prevw = aw
        ap = raw[k, c7]
        cp, sp, vp = _encoder_step(k, ap, prevp, cp, sp, e1p, e2p, p1p, cdp, sdp, raw[k, c2])
        prevp = ap
        s0, r = _splitmix(s0)
        i = np.intp(r & _LOW8)
        m = np.int64(r >> _S12)
        if m < zk[i]:
            z = sgn[np.intp((r >> _S8) & _ONE)] * (float(m) * zw[i])
        else:
            s0, z = _normal_rest(s0, r, zk, zw, zf)
        out[0, k] = raw[k, c0] + sd0 * z
        s1, r = _splitmix(s1)
        i = np.intp(r & _LOW8)
        m = np.int64(r >> _S12)
        if m < zk[i]:
            z = sgn[np.intp((r >> _S8) & _ONE)] * (float(m) * zw[i])
        else:
            s1, z = _normal_rest(s1, r, zk, zw, zf)
        out[1, k] = vw + sd1 * z
        s2, r = _splitmix(s2)
        i = np.intp(r & _LOW8)
        m = np.int64(r >> _S12)
        if m < zk[i]:
            z = sgn[np.intp((r >> _S8) & _ONE)] * (float(m) * zw[i])
        else:
            s2, z = _normal_rest(s2, r, zk, zw, zf)
        out[2, k] = vp + sd2 * z
        s3, r = _splitmix(s3)
        i = np.intp(r & _LOW8)
        m = np.int64(r >> _S12)
        if m < zk[i]:
            z = sgn[np.intp((r >> _S8) & _ONE)] * (float(m) * zw[i])
        else:
            s3, z = _normal_rest(s3, r, zk, zw, zf)
        out[3, k] = raw[k, c3] + sd3 * z
        s4, r = _splitmix(s4)
        i = np.intp(r & _LOW8)
        m = np.int64(r >> _S12)
        if m < zk[i]:
            z = sgn[np.intp((r >> _S8) & _ONE)] * (float(m) * zw[i])
        else:
            s4, z = _normal_rest(s4, r, zk, zw, zf)
        out[4, k] = raw[k, c4] + sd4 * z
        s5, r = _splitmix(s5)
        i = np.intp(r & _LOW8)
        m = np.int64(r >> _S12)
        if m < zk[i]:
            z = sgn[np.intp((r >> _S8) & _ONE)] * (float(m) * zw[i])
        else:
            s5, z = _normal_rest(s5, r, zk, zw, zf)
        out[5, k] = raw[k, c5] + sd5 * z


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
    enc = np.array([[d.wheel_encoder_ecc1_rad, d.wheel_encoder_ecc2_rad,
                     d.wheel_encoder_phase1_rad, d.wheel_encoder_phase2_rad],
                    [d.platform_encoder_ecc1_rad, d.platform_encoder_ecc2_rad,
                     d.platform_encoder_phase1_rad, d.platform_encoder_phase2_rad]],
                   dtype=np.float64)
    sd = np.array([s.torque_noise_nm, s.wheel_speed_noise_rad_s, s.platform_speed_noise_rad_s,
                   s.force_noise_n, s.force_noise_n, s.force_noise_n], dtype=np.float64)
    if np.all(sd > 0):  # every channel noisy (the default): one pass
        _measure_kernel(raw, _COLS, sd, states, enc, _ZK, _ZW, _ZF, _SIGN, block)
    else:
        _measure_passes(raw, states, enc, sd, block)
    return ch


def _measure_passes(raw: np.ndarray, states: np.ndarray, enc: np.ndarray, sd: np.ndarray,
                    block: np.ndarray) -> None:
    """:func:`measure`'s channels into the rows of ``block`` channel by channel (two noisy
    plain channels per pass, each encoder with its noise in one): any channel may be
    without noise (``sd[c] == 0``: no number drawn from its stream). ``states``, ``enc``
    and ``sd`` as for :func:`_measure_kernel`, which gives the same values when every
    channel is noisy."""
    # the channels with noise only, two per pass (their streams' work overlaps)
    encs = {1: (0, 6), 2: (1, 7)}  # encoder channel -> (row of enc, its angle in _COLS)
    plain = [k for k in range(len(_NOISY)) if k not in encs and sd[k] > 0]
    for k1, k2 in zip(plain[0::2], plain[1::2], strict=False):
        add_normal_pair(raw[:, _COLS[k1]], sd[k1], int(states[k1]), block[k1],
                        raw[:, _COLS[k2]], sd[k2], int(states[k2]), block[k2])
    paired = set(plain) if len(plain) % 2 == 0 else set(plain[:-1])
    for k in range(len(_NOISY)):
        if k in paired:
            continue
        src = raw[:, _COLS[k]]
        if k in encs:
            e, angle = encs[k]
            if sd[k] > 0:  # the encoder and its noise in one pass
                _encoder_noise_kernel(src, raw[:, _COLS[angle]], *enc[e], float(sd[k]),
                                      np.uint64(int(states[k])), _ZK, _ZW, _ZF, block[k])
                continue
            _encoder_kernel(src, raw[:, _COLS[angle]], *enc[e], block[k])
        elif sd[k] > 0:
            add_normal(src, sd[k], int(states[k]), block[k])
        else:
            block[k] = src
