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
    (once- and twice-per-revolution terms). The plain form of what :func:`_integrate`
    evaluates by :func:`_wob_step`."""
    out = 0.0
    for j in range(wob.shape[0]):
        arg = wob[j, 1] * (th_p if wob[j, 3] > 0.5 else t) + wob[j, 2]
        out += wob[j, 0] * math.sin(arg)
    return out


@numba.njit(**_FAST)
def _wob_set(t, th_p, wob, ws, wc):
    """Each wobble row's argument at ``(t, th_p)`` into its phasor: ``ws`` sin, ``wc`` cos."""
    for j in range(wob.shape[0]):
        arg = wob[j, 1] * (th_p if wob[j, 3] > 0.5 else t) + wob[j, 2]
        ws[j] = math.sin(arg)
        wc[j] = math.cos(arg)


@numba.njit(**_FAST)
def _wob_step(wob, ws, wc, rc, rs, dth, s):
    """One RK4 step's wobble from the phasors ``ws``, ``wc`` (sin, cos of every row's argument
    at the step's start, the revolution rows still at the previous start, ``dth`` [rad]
    behind). Band rows are rotated by half a step (``rc``, ``rs``: cos, sin of ``rate*h/2``)
    to the step's middle and end: ``s[0]``, ``s[1]`` their sum there [rad/s]; their phasors
    are left at the end. Revolution rows are advanced by ``order*dth``, then ``s[2:6]`` are
    the Taylor coefficients of their sum in the angle increment from the step's start
    (:func:`_wob_rev`): within a step ``order*dth`` < 1e-3 rad, so the cubic's truncation
    (x^4/24) is below 1e-13 of the term, i.e. at rounding."""
    for k in range(6):
        s[k] = 0.0
    for j in range(wob.shape[0]):
        amp, sn, cs = wob[j, 0], ws[j], wc[j]
        if wob[j, 3] > 0.5:
            o = wob[j, 1]
            u = o * dth
            if abs(u) <= _SMALL:
                cu, su = _cos_small(u), _sin_small(u)
            else:
                cu, su = math.cos(u), math.sin(u)
            sn, cs = sn * cu + cs * su, cs * cu - sn * su
            ws[j], wc[j] = sn, cs
            ao = amp * o
            s[2] += amp * sn
            s[3] += ao * cs
            s[4] -= 0.5 * ao * o * sn
            s[5] -= ao * o * o * cs / 6.0
        else:
            sm, cm = sn * rc[j] + cs * rs[j], cs * rc[j] - sn * rs[j]
            se, ce = sm * rc[j] + cm * rs[j], cm * rc[j] - sm * rs[j]
            s[0] += amp * sm
            s[1] += amp * se
            ws[j], wc[j] = se, ce


@numba.njit(**_FAST)
def _wob_rev(s, x):
    """The revolution rows' wobble at angle increment ``x`` [rad] (:func:`_wob_step`)."""
    return s[2] + x * (s[3] + x * (s[4] + x * s[5]))


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
