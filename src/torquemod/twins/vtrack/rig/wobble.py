"""The platform speed loop's wobble: its table of lines, drawn once per run, and how the
integrator (:mod:`torquemod.twins.vtrack.rig.dynamics`) and the ground truth evaluate it.

The wobble ``W_ref - W0`` of the speed reference is a sum of sines: band rows (kind 0) at a
rate in time and revolution rows (kind 1) at an order of the platform angle
(:func:`wobble_table`). Moved out of :mod:`torquemod.twins.vtrack.rig.dynamics` (which re-exports
these
names) to keep modules small.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from torquemod.twins.vtrack.params import DisturbanceParams
from torquemod.twins.vtrack.rig.kernels import FLAGS, SMALL
from torquemod.twins.vtrack.rig.kernels import cos_small as _cos_small
from torquemod.twins.vtrack.rig.kernels import sin_small as _sin_small

_FAST = {"fastmath": FLAGS, "cache": True}
_SMALL = SMALL


@numba.njit(**_FAST)
def _wobble(t, th_p, wob):
    """Wobble of the platform's speed reference [rad/s] at time ``t`` [s] and platform angle
    ``th_p`` [rad]: ``sum amp*sin(rate*t + phase)`` over the rows of ``wob`` whose kind is 0
    (a speed loop's slow oscillation) and ``amp*sin(order*th_p + phase)`` over those of kind 1
    (once- and twice-per-revolution terms). The plain form of what the integrator
    (:mod:`torquemod.twins.vtrack.rig.lanes`) evaluates by :func:`_wob_step`."""
    out = 0.0
    for j in range(wob.shape[0]):
        arg = wob[j, 1] * (th_p if wob[j, 3] > 0.5 else t) + wob[j, 2]
        out += wob[j, 0] * math.sin(arg)
    return out


@numba.njit(**_FAST)
def _band_sines(t, wob, out):
    """``out[j] = sin(rate*t + phase)`` for the band rows ``j`` of ``wob`` (kind 0) at time
    ``t`` [s], each as :func:`_wobble` evaluates it; the other rows of ``out`` are left."""
    for j in range(wob.shape[0]):
        if not wob[j, 3] > 0.5:
            out[j] = math.sin(wob[j, 1] * t + wob[j, 2])


@numba.njit(**_FAST)
def _wobble_banded(th_p, wob, band):
    """:func:`_wobble` with the band rows' sines given (``band``, :func:`_band_sines` at the
    same time): the same terms added in the same order, so the same value."""
    out = 0.0
    for j in range(wob.shape[0]):
        if wob[j, 3] > 0.5:
            s = math.sin(wob[j, 1] * th_p + wob[j, 2])
        else:
            s = band[j]
        out += wob[j, 0] * s
    return out


@numba.njit(inline="always", **_FAST)
def _wob_set(t, th_p, wob, l, nw, ws, wc):
    """Lane ``l``'s wobble rows (``wob[l, :nw[l]]``, tables stacked (lanes, rows, 4)): each
    row's argument at ``(t, th_p)`` into its phasor, ``ws[l]`` sin and ``wc[l]`` cos."""
    for j in range(nw[l]):
        arg = wob[l, j, 1] * (th_p if wob[l, j, 3] > 0.5 else t) + wob[l, j, 2]
        ws[l, j] = math.sin(arg)
        wc[l, j] = math.cos(arg)


@numba.njit(inline="always", **_FAST)
def _wob_step(wob, l, nw, ws, wc, rc, rs, dth, s):
    """One RK4 step's wobble of lane ``l`` (tables and phasors as in :func:`_wob_set`) from
    the phasors ``ws[l]``, ``wc[l]`` (sin, cos of every row's argument at the step's start,
    the revolution rows still at the previous start, ``dth`` [rad] behind). Band rows are
    rotated by half a step (``rc[l]``, ``rs[l]``: cos, sin of ``rate*h/2``) to the step's
    middle and end: ``s[l, 0]``, ``s[l, 1]`` their sum there [rad/s]; their phasors are left
    at the end. Revolution rows are advanced by ``order*dth``, then ``s[l, 2:6]`` are the
    Taylor coefficients of their sum in the angle increment from the step's start
    (:func:`_wob_rev`): within a step ``order*dth`` < 1e-3 rad, so the cubic's truncation
    (x^4/24) is below 1e-13 of the term, i.e. at rounding."""
    s0 = s1 = s2 = s3 = s4 = s5 = 0.0
    for j in range(nw[l]):
        amp, sn, cs = wob[l, j, 0], ws[l, j], wc[l, j]
        if wob[l, j, 3] > 0.5:
            o = wob[l, j, 1]
            u = o * dth
            if abs(u) <= _SMALL:
                cu, su = _cos_small(u), _sin_small(u)
            else:
                cu, su = math.cos(u), math.sin(u)
            sn, cs = sn * cu + cs * su, cs * cu - sn * su
            ws[l, j], wc[l, j] = sn, cs
            ao = amp * o
            s2 += amp * sn
            s3 += ao * cs
            s4 -= 0.5 * ao * o * sn
            s5 -= ao * o * o * cs / 6.0
        else:
            sm, cm = sn * rc[l, j] + cs * rs[l, j], cs * rc[l, j] - sn * rs[l, j]
            se, ce = sm * rc[l, j] + cm * rs[l, j], cm * rc[l, j] - sm * rs[l, j]
            s0 += amp * sm
            s1 += amp * se
            ws[l, j], wc[l, j] = se, ce
    s[l, 0], s[l, 1], s[l, 2], s[l, 3], s[l, 4], s[l, 5] = s0, s1, s2, s3, s4, s5


@numba.njit(inline="always", **_FAST)
def _wob_rev(s, l, x):
    """Lane ``l``'s revolution rows' wobble at angle increment ``x`` [rad]
    (:func:`_wob_step`)."""
    return s[l, 2] + x * (s[l, 3] + x * (s[l, 4] + x * s[l, 5]))


def wobble_table(dist: DisturbanceParams, platform_speed_rad_s: float,
                 rng: np.random.Generator) -> np.ndarray:
    """The rows ``(amplitude [rad/s], rate [rad/s] or order, phase [rad], kind)`` of one
    run's speed-reference wobble ``W_ref - W0`` (:func:`_wobble`): ``speed_wobble_components``
    sines (kind 0) of equal amplitude ``rms*sqrt(2/k)*W0`` -- so that their RMS together is
    ``speed_wobble_rms`` of the set speed ``W0`` -- at frequencies drawn uniformly in
    ``speed_wobble_band_hz``, and the revolution terms (kind 1) ``speed_wobble_rev1*W0`` at
    order 1 and ``rev2*W0`` at order 2 of the platform angle; every phase uniform in
    [0, 2*pi). Empty when ``enabled`` or ``speed_wobble_enabled`` is off.

    Why the reference: the twin's platform loop is stiff (bandwidth ~500 Hz), so it rejects a
    slow disturbance torque almost entirely, while a real loop's slow wobble (tachometer or
    encoder ripple, set-point and drive-gain drift, runout) shows in its speed as if its
    reference wobbled. The equivalent disturbance torque on the platform is
    ``Kp*dW + Ki*integral(dW dt)``, ``dW = W_ref - W0``.

    Parameters
    ----------
    dist : DisturbanceParams
        The disturbances.
    platform_speed_rad_s : float
        The set speed W0 [rad/s].
    rng : numpy.random.Generator
        Draws frequencies and phases.

    Returns
    -------
    ndarray
        (n, 4) rows.
    """
    rows = []
    if not (dist.enabled and dist.speed_wobble_enabled):
        return np.zeros((0, 4))
    if dist.speed_wobble_rms > 0 and dist.speed_wobble_components > 0:
        k = dist.speed_wobble_components
        amp = dist.speed_wobble_rms * np.sqrt(2.0 / k) * platform_speed_rad_s
        lo, hi = dist.speed_wobble_band_hz
        for _ in range(k):
            rows.append((amp, 2 * np.pi * rng.uniform(lo, hi), rng.uniform(0, 2 * np.pi), 0.0))
    for order, rel in ((1.0, dist.speed_wobble_rev1), (2.0, dist.speed_wobble_rev2)):
        if rel > 0:
            rows.append((rel * platform_speed_rad_s, order, rng.uniform(0, 2 * np.pi), 1.0))
    return np.array(rows, dtype=np.float64).reshape(-1, 4)


def wobble_reference(wobble: np.ndarray, t_s: np.ndarray, theta_rad: np.ndarray) -> np.ndarray:
    """The speed reference's wobble [rad/s] (rows of :func:`wobble_table`) at times ``t_s``
    [s] and platform angles ``theta_rad`` [rad]: :func:`_wobble` on arrays.

    Parameters
    ----------
    wobble : ndarray
        The rows.
    t_s : ndarray
        Times [s].
    theta_rad : ndarray
        Platform angles [rad].

    Returns
    -------
    ndarray
        The wobble [rad/s].
    """
    out = np.zeros(np.shape(t_s))
    for amp, rate, ph, kind in wobble:
        out += amp * np.sin(rate * (theta_rad if kind > 0.5 else t_s) + ph)
    return out


def wobble_basis(wobble: np.ndarray, t_s: np.ndarray, theta_rad: np.ndarray) -> np.ndarray:
    """Columns cos and sin of every wobble row's argument without its phase (``rate*t_s`` or
    ``order*theta_rad``): the lines a linear fit needs to take the wobble out of a signal.

    Parameters
    ----------
    wobble : ndarray
        The rows.
    t_s : ndarray
        Times [s].
    theta_rad : ndarray
        Platform angles [rad].

    Returns
    -------
    ndarray
        (n, 2*rows) columns [-].
    """
    cols = []
    for _amp, rate, _ph, kind in wobble:
        arg = rate * (theta_rad if kind > 0.5 else t_s)
        cols += [np.cos(arg), np.sin(arg)]
    return np.column_stack(cols) if cols else np.empty((np.size(t_s), 0))
