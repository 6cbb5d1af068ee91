"""The V-Track paper's phase estimator (Eq. 2 of its Section 2.4): the times of the
band-passed signals' peaks and valleys, each refined by the vertex of a parabola through
three samples, paired between torque and wheel speed and averaged
(:func:`peak_valley_phase`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import signal

from torquemod.errors import ProcessingError


def parabolic_vertex(y_m1: np.ndarray, y_0: np.ndarray, y_p1: np.ndarray) -> np.ndarray:
    """Offset of the vertex of the parabola through three equally spaced samples.

    Parameters
    ----------
    y_m1, y_0, y_p1 : array_like
        The samples before, at and after the extremum.

    Returns
    -------
    ndarray
        Vertex offset from the middle sample [samples], clipped to [-0.5, 0.5]; 0 where the
        three samples are collinear.

    Examples
    --------
    >>> round(float(parabolic_vertex(0.0, 1.0, 0.5)), 4)
    0.1667
    >>> float(parabolic_vertex(0.0, 1.0, 1.0))
    0.5
    """
    den = y_m1 - 2.0 * y_0 + y_p1
    d = np.zeros(np.broadcast(y_m1, y_0, y_p1).shape)
    np.divide(0.5 * (y_m1 - y_p1), den, out=d, where=den != 0)  # 0 where den == 0
    return np.minimum(np.maximum(d, -0.5), 0.5)


def extrema_times(x: np.ndarray, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Times of the local maxima and minima of a signal, refined by parabolic interpolation.

    Whole-sample peaks at 53 Hz are 13.5 deg apart at 2 Hz, hence the refinement.

    Parameters
    ----------
    x : ndarray
        The signal, any unit.
    fs_hz : float
        Sample rate [Hz].

    Returns
    -------
    peaks : ndarray
        Times of the maxima [s from the first sample].
    valleys : ndarray
        Times of the minima [s from the first sample].
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == 1 and x.size >= 3:  # find_peaks's strict local extrema, compiled
        pk, vl, flat = _strict_extrema_times(x, float(fs_hz))
        if not flat:
            return pk, vl
    out = []
    dx = np.diff(x)
    flat = bool(np.any(dx == 0))  # a plateau: find_peaks's own handling (its middle sample)
    for sgn in (1.0, -1.0):
        if flat:
            idx, _ = signal.find_peaks(sgn * x)
            idx = idx[(idx > 0) & (idx < x.size - 1)]
        else:  # find_peaks's strict local extrema without its per-call overhead
            rise = dx > 0 if sgn > 0 else dx < 0
            idx = np.flatnonzero(rise[:-1] & ~rise[1:]) + 1
        # the vertex of -x is the same number as that of x (negation is exact in IEEE
        # arithmetic, and so symmetric in its rounding)
        d = parabolic_vertex(x[idx - 1], x[idx], x[idx + 1])
        out.append((idx + d) / fs_hz)
    return out[0], out[1]


@njit(cache=True, nogil=True)
def _strict_extrema_times(x: np.ndarray, fs_hz: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """:func:`extrema_times` of a record without plateaus in one pass: the samples above
    (below) both neighbours, each moved to the vertex of the parabola through it and its
    neighbours with :func:`parabolic_vertex`'s arithmetic (so the same bits,
    tests/processing/test_chain_kernels.py). The third value is True, and the times empty, when two
    neighbouring samples are equal (a plateau: left to ``find_peaks``)."""
    n = x.size
    for i in range(n - 1):
        if x[i + 1] - x[i] == 0:
            return np.empty(0), np.empty(0), True
    peaks = np.empty(n)
    valleys = np.empty(n)
    n_pk = 0
    n_vl = 0
    for i in range(1, n - 1):
        d0 = x[i] - x[i - 1]
        d1 = x[i + 1] - x[i]
        if (d0 > 0 and not d1 > 0) or (d0 < 0 and not d1 < 0):
            den = x[i - 1] - 2.0 * x[i] + x[i + 1]
            d = 0.5 * (x[i - 1] - x[i + 1]) / den if den != 0 else 0.0
            d = min(max(d, -0.5), 0.5)
            if d0 > 0:
                peaks[n_pk] = (i + d) / fs_hz
                n_pk += 1
            else:
                valleys[n_vl] = (i + d) / fs_hz
                n_vl += 1
    return peaks[:n_pk].copy(), valleys[:n_vl].copy(), False


def _closest(times: np.ndarray, center_s: float, count: int) -> np.ndarray:
    order = np.argsort(np.abs(times - center_s))[:count]
    return np.sort(times[order])


@dataclass(frozen=True)
class PeakValleyResult:
    """The phase from peak and valley times (the V-Track paper's method).

    Attributes
    ----------
    phase_deg : float
        Mean phase lag of the wheel speed behind the torque [deg].
    pair_phases_deg : ndarray
        The phase of each matched extremum pair [deg].
    torque_times_s : ndarray
        The torque's extremum times [s].
    wheel_times_s : ndarray
        The wheel speed's matched extremum times [s].
    """

    phase_deg: float
    pair_phases_deg: np.ndarray
    torque_times_s: np.ndarray
    wheel_times_s: np.ndarray


def peak_valley_phase(torque: np.ndarray, wheel: np.ndarray, fs_hz: float, f_mod_hz: float, *,
                      center_s: float, n_periods: int = 3) -> PeakValleyResult:
    """Phase lag of the wheel speed behind the torque from paired peaks and valleys,
    ``phi_pair = 360*f_mod*(t_wheel - t_torque)``, averaged over the pairs.

    The ``n_periods`` torque peaks and valleys nearest ``center_s`` are each paired with the
    wheel-speed extremum of the same kind nearest to it (within half a period); extrema are
    located to a fraction of a sample by :func:`parabolic_vertex`.

    Parameters
    ----------
    torque, wheel : ndarray
        Band-passed torque [N*m] and wheel angular velocity [rad/s] (any units: only the
        times of their extrema matter), sampled together.
    fs_hz : float
        Sampling rate [Hz].
    f_mod_hz : float
        Modulation frequency [Hz].
    center_s : float
        Centre of the cycle [s from the first sample].
    n_periods : int, default 3
        Peaks (and valleys) used.

    Returns
    -------
    PeakValleyResult
        Mean phase [deg], per-pair phases [deg] and the paired times [s].

    Raises
    ------
    ProcessingError
        Too few extrema, or no wheel-speed extremum within half a period of a torque one.

    Notes
    -----
    One compiled call (:func:`_paired_extrema`) finds the extrema and pairs them with
    numpy's arithmetic, so the same numbers as the step-by-step route,
    :func:`peak_valley_phase_reference` (tests/dsp/test_extrema.py); that route runs where
    the kernel cannot decide as it would (plateaus, a tie at the cut of the nearest
    extrema) and raises the errors.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (2).
    """
    torque = np.ascontiguousarray(torque, dtype=np.float64)
    wheel = np.ascontiguousarray(wheel, dtype=np.float64)
    if torque.ndim == 1 and wheel.ndim == 1 and min(torque.size, wheel.size) >= 3 \
            and n_periods >= 1:
        status, pair, t_sel, w_sel, mean = _paired_extrema(torque, wheel, float(fs_hz),
                                                           float(f_mod_hz), float(center_s),
                                                           int(n_periods))
        if status == 0:
            return PeakValleyResult(mean, pair, t_sel, w_sel)
    return peak_valley_phase_reference(torque, wheel, fs_hz, f_mod_hz, center_s=center_s,
                                       n_periods=n_periods)


def peak_valley_phase_reference(torque: np.ndarray, wheel: np.ndarray, fs_hz: float,
                                f_mod_hz: float, *, center_s: float, n_periods: int = 3
                                ) -> PeakValleyResult:
    """:func:`peak_valley_phase` step by step in numpy: its reference and its route where
    the compiled one cannot decide.

    Parameters
    ----------
    torque, wheel : ndarray
        Band-passed torque [N*m] and wheel angular velocity [rad/s], sampled together.
    fs_hz : float
        Sampling rate [Hz].
    f_mod_hz : float
        Modulation frequency [Hz].
    center_s : float
        Centre of the cycle [s from the first sample].
    n_periods : int, default 3
        Peaks (and valleys) used.

    Returns
    -------
    PeakValleyResult
        Mean phase [deg], per-pair phases [deg] and the paired times [s].

    Raises
    ------
    ProcessingError
        Too few extrema, or no wheel-speed extremum within half a period of a torque one.
    """
    t_pk, t_vl = extrema_times(torque, fs_hz)
    w_pk, w_vl = extrema_times(wheel, fs_hz)
    period = 1.0 / f_mod_hz
    t_sel, w_sel = [], []
    for t_all, w_all, kind in ((t_pk, w_pk, "peaks"), (t_vl, w_vl, "valleys")):
        if t_all.size < n_periods or w_all.size == 0:
            raise ProcessingError(f"fewer than {n_periods} torque {kind} in the cycle")
        ts = _closest(t_all, center_s, n_periods)
        gaps = np.abs(w_all[None, :] - ts[:, None])  # each torque extremum's distance to
        nearest = gaps.argmin(axis=1)  # every wheel extremum; the first nearest on a tie
        for t, j, gap in zip(ts.tolist(), nearest.tolist(),
                             gaps[np.arange(ts.size), nearest].tolist(), strict=True):
            if gap > period / 2:
                raise ProcessingError(f"no wheel-speed extremum within half a period of the "
                                      f"torque extremum at {t:.3f} s")
            t_sel.append(t)
            w_sel.append(w_all[j])
    t_sel, w_sel = np.asarray(t_sel), np.asarray(w_sel)
    pair = 360.0 * f_mod_hz * (w_sel - t_sel)
    return PeakValleyResult(float(pair.mean()), pair, t_sel, w_sel)


@njit(cache=True, nogil=True)
def _paired_extrema(torque: np.ndarray, wheel: np.ndarray, fs_hz: float, f_mod_hz: float,
                    center_s: float, n_periods: int
                    ) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, float]:
    """:func:`peak_valley_phase_reference`'s pairs in one call: ``(status, pair_deg,
    torque_times_s, wheel_times_s, mean_deg)`` with status 0, or 1 where that route must decide (a
    plateau; too few extrema; a tie in distance at the cut of the ``n_periods`` nearest,
    where ``np.argsort``'s order of ties would choose; no wheel extremum within half a
    period). The extrema by :func:`_strict_extrema_times`; each torque extremum's nearest
    wheel extremum, the first on a tie (``argmin``); the pairs as ``360*f*(t_w - t_T)``, and
    their mean as ``np.mean`` forms it (:func:`_numpy_sum`)."""
    empty = np.empty(0)
    t_pk, t_vl, flat = _strict_extrema_times(torque, fs_hz)
    if flat:
        return 1, empty, empty, empty, math.nan
    w_pk, w_vl, flat = _strict_extrema_times(wheel, fs_hz)
    if flat:
        return 1, empty, empty, empty, math.nan
    half_period = (1.0 / f_mod_hz) / 2
    t_sel = np.empty(2 * n_periods)
    w_sel = np.empty(2 * n_periods)
    for kind in range(2):
        t_all = t_pk if kind == 0 else t_vl
        w_all = w_pk if kind == 0 else w_vl
        if t_all.size < n_periods or w_all.size == 0:
            return 1, empty, empty, empty, math.nan
        dist = np.abs(t_all - center_s)
        order = np.argsort(dist)
        if t_all.size > n_periods and dist[order[n_periods - 1]] == dist[order[n_periods]]:
            return 1, empty, empty, empty, math.nan
        ts = np.sort(t_all[order[:n_periods]])
        for i in range(n_periods):
            best = 0
            gap = abs(w_all[0] - ts[i])
            for j in range(1, w_all.size):
                g = abs(w_all[j] - ts[i])
                if g < gap:
                    best, gap = j, g
            if gap > half_period:
                return 1, empty, empty, empty, math.nan
            t_sel[kind * n_periods + i] = ts[i]
            w_sel[kind * n_periods + i] = w_all[best]
    pair = (360.0 * f_mod_hz) * (w_sel - t_sel)
    return 0, pair, t_sel, w_sel, _numpy_sum(pair, 0, pair.size) / pair.size


@njit(cache=True, nogil=True)
def _numpy_sum(a: np.ndarray, lo: int, n: int) -> float:
    """The sum of ``a[lo:lo + n]`` as numpy's ``add.reduce`` forms it for a contiguous
    float64 record (pairwise summation: blocks of up to 128 in eight running sums
    (:func:`_block_sum`), halves above, the left half's sum plus the right's), so
    ``np.mean``'s numbers (tests/dsp/test_extrema.py). The halving runs on an explicit
    stack (numba's cache does not keep recursive kernels)."""
    if n <= 128:
        return _block_sum(a, lo, n)
    kind = np.empty(128, dtype=np.int64)  # 0: sum a segment, 1: add the top two sums
    seg_lo = np.empty(128, dtype=np.int64)
    seg_n = np.empty(128, dtype=np.int64)
    sums = np.empty(128)
    kind[0], seg_lo[0], seg_n[0] = 0, lo, n
    top, n_sums = 1, 0
    while top:
        top -= 1
        if kind[top] == 1:
            n_sums -= 1
            sums[n_sums - 1] = sums[n_sums - 1] + sums[n_sums]
        elif seg_n[top] <= 128:
            sums[n_sums] = _block_sum(a, seg_lo[top], seg_n[top])
            n_sums += 1
        else:  # the left half first, then the right, then their sum
            m, start = seg_n[top], seg_lo[top]
            half = m // 2
            half -= half % 8
            kind[top] = 1
            kind[top + 1], seg_lo[top + 1], seg_n[top + 1] = 0, start + half, m - half
            kind[top + 2], seg_lo[top + 2], seg_n[top + 2] = 0, start, half
            top += 3
    return sums[0]


@njit(cache=True, nogil=True)
def _block_sum(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise-summation leaf for ``n <= 128`` values from ``a[lo]``: a plain
    running sum below 8, else eight running sums over blocks of 8, added as
    ``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))``, then the remainder."""
    if n < 8:
        res = -0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r = np.empty(8)
    for j in range(8):
        r[j] = a[lo + j]
    i = 8
    while i < n - n % 8:
        for j in range(8):
            r[j] += a[lo + i + j]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[lo + i]
        i += 1
    return res
