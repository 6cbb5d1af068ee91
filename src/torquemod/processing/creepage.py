"""Step 8's creepage of the V-Track chain from the speed model's slow speeds: the ratio of
platform to wheel speed fitted with a line and the platform's revolution orders
(:func:`creepage_and_drift`), in one compiled call per cycle.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

from torquemod.dsp import filters
from torquemod.dsp.basis import order_columns
from torquemod.dsp.lstsq import lapack_addresses, lstsq_compiled
from torquemod.processing.speedmodel import SpeedModel


def creepage_and_drift(model: SpeedModel, fs_hz: float, *, wheel_radius_m: float,
                       platform_radius_m: float, platform_harmonics: tuple[int, ...]
                       ) -> tuple[float, float]:
    """Creepage of Eq. (3) [1]_ and its change over the record, from the slow speeds.

    The ratio ``q(t) = W(t)*Rp/(w(t)*Rw) = (1 + e(theta_p))/(1 + xi(t))`` is free of any
    speed variation that wheel and platform share; the platform encoder's eccentricity ``e``
    (at its revolution harmonics) enters it linearly. A least-squares fit
    ``q ~ c0 + c1*(t - mean t) + sum(a_k*cos + b_k*sin)(k*theta_p)`` gives ``xi = 1/c0 - 1``
    and the drift ``-c1*T/c0^2``: a wheel that follows a moving platform keeps its creepage;
    a wheel that starts to slip shows a creepage rising within the cycle.

    One compiled call (:func:`_creepage_fit`); where its least squares would need the SVD
    (a design rank deficient to rounding), the same fit by
    :func:`torquemod.dsp.lstsq.lstsq` (:func:`creepage_and_drift_reference`). The two agree
    to rounding (~1e-14 relative, tests/processing/test_creepage.py).

    Parameters
    ----------
    model : SpeedModel
        The joint speed model of the cycle.
    fs_hz : float
        Sample rate [Hz].
    wheel_radius_m : float
        Rw [m].
    platform_radius_m : float
        Rp [m].
    platform_harmonics : tuple of int
        The platform's revolution harmonics fitted.

    Returns
    -------
    creepage : float
        xi [-]; NaN when the model has no platform speed.
    drift : float
        Its change over the record [-].

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (3).
    """
    w = model.part("wheel_speed_rad_s", "slow")
    p = model.part("platform_speed_rad_s", "slow")
    harmonics, positive = _harmonics_array(tuple(platform_harmonics))
    if w.size >= 2 and positive \
            and w.flags.c_contiguous and p.flags.c_contiguous:
        xi, drift, status = _creepage_fit(w, p, float(fs_hz), float(wheel_radius_m),
                                          float(platform_radius_m), harmonics,
                                          *lapack_addresses())
        if status == 0:
            return xi, drift
    return creepage_and_drift_reference(model, fs_hz, wheel_radius_m=wheel_radius_m,
                                        platform_radius_m=platform_radius_m,
                                        platform_harmonics=platform_harmonics)


@functools.lru_cache(maxsize=16)
def _harmonics_array(platform_harmonics: tuple[int, ...]) -> tuple[np.ndarray, bool]:
    """The harmonics as a read-only int64 array and whether there are some, all positive
    (the compiled fit's condition); configuration, so cached."""
    out = np.array([int(k) for k in platform_harmonics], dtype=np.int64)
    out.setflags(write=False)
    return out, bool(out.size and out.min() > 0)


def creepage_and_drift_reference(model: SpeedModel, fs_hz: float, *, wheel_radius_m: float,
                                 platform_radius_m: float, platform_harmonics: tuple[int, ...]
                                 ) -> tuple[float, float]:
    """:func:`creepage_and_drift` by numpy and :func:`torquemod.dsp.lstsq.lstsq` step by
    step: the route before the compiled one, and its fallback.

    Parameters
    ----------
    model : SpeedModel
        The joint speed model of the cycle.
    fs_hz : float
        Sample rate [Hz].
    wheel_radius_m : float
        Rw [m].
    platform_radius_m : float
        Rp [m].
    platform_harmonics : tuple of int
        The platform's revolution harmonics fitted.

    Returns
    -------
    creepage : float
        xi [-].
    drift : float
        Its change over the record [-].
    """
    w = model.part("wheel_speed_rad_s", "slow")
    p = model.part("platform_speed_rad_s", "slow")
    if np.any(w == 0):
        return float("nan"), float("nan")
    q = p * platform_radius_m / (w * wheel_radius_m)
    n = q.size
    t = np.arange(n) / fs_hz
    c0 = float(q.sum()) / n  # np.mean's numbers
    design = np.empty((n, 2 + 2 * len(platform_harmonics)))  # [1, t - mean t, orders]
    design[:, 0] = 1.0
    design[:, 1] = t - t.mean()
    for _ in range(2):
        # the platform's true angle from the wheel's speed (free of the platform encoder's
        # own error, whose square would otherwise bias c0 by e^2/2)
        theta = filters.unwrapped_angle(w * c0 * wheel_radius_m / platform_radius_m, fs_hz)
        kept = [k for k in platform_harmonics if k * abs(theta[-1]) / (2 * np.pi) > 0.5]
        design[:, 2:2 + 2 * len(kept)] = filters.order_design(theta, kept)
        coef, _ = filters.lstsq(design[:, :2 + 2 * len(kept)], q)
        c0, c1 = float(coef[0]), float(coef[1])
    return 1.0 / c0 - 1.0, -c1 * (n / fs_hz) / c0**2


@numba.njit(cache=True, nogil=True)
def _creepage_fit(w: np.ndarray, p: np.ndarray, fs_hz: float, rw: float, rp: float,
                  harmonics: np.ndarray, potrf: int, potrs: int) -> tuple[float, float, int]:
    """:func:`creepage_and_drift_reference`'s steps in one call on the slow wheel and
    platform speeds ``w``, ``p`` [rad/s]: ``(xi, drift, status)``, status 0, or that of
    :func:`~torquemod.dsp.lstsq.lstsq_compiled` where the fit needs the SVD (then the
    caller takes the reference route). NaN creepage and drift where ``w`` is 0 somewhere."""
    n = w.size
    for i in range(n):
        if w[i] == 0:
            return math.nan, math.nan, 0
    q = p * rp / (w * rw)
    c0 = q.sum() / n
    t_mean = 0.0
    for i in range(n):
        t_mean += i / fs_hz
    t_mean /= n
    design = np.empty((n, 2 + 2 * harmonics.size))
    for i in range(n):
        design[i, 0] = 1.0
        design[i, 1] = i / fs_hz - t_mean
    theta = np.empty(n)
    c1 = 0.0
    for _ in range(2):
        # the platform's angle from the wheel's speed (trapezoids), as the reference
        speed = w * c0 * rw / rp
        theta[0] = 0.0
        for i in range(1, n):
            theta[i] = theta[i - 1] + 0.5 * (speed[i] + speed[i - 1]) / fs_hz
        n_kept = 0
        for k in harmonics:
            if k * abs(theta[-1]) / (2 * math.pi) > 0.5:
                n_kept += 1
        kept = np.empty(n_kept, dtype=np.int64)
        j = 0
        for k in harmonics:
            if k * abs(theta[-1]) / (2 * math.pi) > 0.5:
                kept[j] = k
                j += 1
        m = 2 + 2 * n_kept
        if n_kept:
            design[:, 2:m] = order_columns(theta, kept)
        coef, status = lstsq_compiled(np.ascontiguousarray(design[:, :m]), q, potrf, potrs)
        if status != 0:
            return math.nan, math.nan, status
        c0, c1 = coef[0], coef[1]
    return 1.0 / c0 - 1.0, -c1 * (n / fs_hz) / c0 ** 2, 0
