"""The line-plus-tones model of a record: its design matrix, its least-squares fit, and the
model-padded and tone-free forms of a record that the zero-phase filters are run on.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from torquemod.dsp.lstsq import LstsqFactor, lstsq


def tone_design(t_s: np.ndarray, tones_hz, *, line: bool = False) -> np.ndarray:
    """Least-squares design matrix of a constant, optionally a line, and tones.

    ``[1, (t - mean t), cos(2*pi*f_k*t), sin(2*pi*f_k*t), ...]``; the caller chooses which
    tones to keep.

    Parameters
    ----------
    t_s : ndarray
        Sample times [s].
    tones_hz : sequence of float
        Tone frequencies [Hz].
    line : bool
        Include the line column. Default False.

    Returns
    -------
    ndarray
        (n, 1 + line + 2*len(tones)) design matrix.
    """
    t = np.asarray(t_s, dtype=np.float64)
    cols = [np.ones(t.size)] + ([t - t.mean()] if line else [])
    for f in tones_hz:
        cols += [np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)]
    return np.column_stack(cols)


def fit_line_and_tones(x: np.ndarray, fs_hz: float, tones_hz: list[float]
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares ``x ~ c0 + c1*t + sum(a_k*cos + b_k*sin)(2*pi*f_k*t)``.

    Parameters
    ----------
    x : ndarray
        The record, any unit.
    fs_hz : float
        Sample rate [Hz].
    tones_hz : list of float
        Tone frequencies [Hz].

    Returns
    -------
    coef : ndarray
        c0, c1 [unit/s], then (a_k, b_k) per kept tone [unit of x].
    kept : ndarray
        The tone frequencies kept [Hz]: below Nyquist, one resolution apart.
    """
    design, kept = _line_and_tones_design(x.size, fs_hz, tones_hz)
    coef, _ = lstsq(design, x)
    return coef, np.asarray(kept)


def _line_and_tones_design(n: int, fs_hz: float, tones_hz: list[float]
                           ) -> tuple[np.ndarray, list[float]]:
    """The design of :func:`fit_line_and_tones` for ``n`` samples and the tones it keeps
    (:func:`line_and_tones_design_compiled`)."""
    design, kept, _ = line_and_tones_design_compiled(
        int(n), float(fs_hz), np.asarray(tones_hz, dtype=np.float64).reshape(-1))
    return design, kept.tolist()


@numba.njit(cache=True, nogil=True)
def line_and_tones_design_compiled(n: int, fs_hz: float, tones_hz: np.ndarray
                                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The design of :func:`fit_line_and_tones`: ones, ``t - mean(t)`` [s], then cos and sin
    of each tone kept (below Nyquist, more than one frequency resolution ``fs/n`` from
    every tone kept before it, in order), their columns by :func:`fill_tones_together`.
    ``(design, kept [Hz], omegas [rad per sample])``."""
    res = fs_hz / n
    kept = np.empty(tones_hz.size)
    k = 0
    for f in tones_hz:
        if 0 < f < fs_hz / 2:
            far = True
            for g in kept[:k]:
                if not abs(f - g) > res:
                    far = False
            if far:
                kept[k] = f
                k += 1
    kept = kept[:k].copy()
    omegas = np.empty(k)
    for m in range(k):
        omegas[m] = 2 * np.pi * kept[m] / fs_hz
    design = np.empty((n, 2 + 2 * k))
    for i in range(n):
        design[i, 0] = 1.0
        design[i, 1] = (i - (n - 1) / 2) / fs_hz  # t - mean t
    fill_tones_together(design, 2, omegas, 0.0, 1.0)
    return design, kept, omegas


def model_padded(x: np.ndarray, fs_hz: float, tones_hz: list[float], pad: int
                 ) -> tuple[np.ndarray, float, float]:
    """A record less its line, extended at each end by the model of its stationary tones.

    A zero-phase filter run over the padded record starts and ends its transients in the
    padding, where the signal continues smoothly, instead of inside the data.

    Parameters
    ----------
    x : ndarray
        The record, any unit.
    fs_hz : float
        Sample rate [Hz].
    tones_hz : list of float
        The stationary tones [Hz] (:func:`fit_line_and_tones`).
    pad : int
        Samples added at each end [-].

    Returns
    -------
    padded : ndarray
        The padded record less the line.
    mean : float
        The line's mean value [unit of x].
    slope : float
        The line's slope [unit of x per s].
    """
    return model_padded_rows([x], fs_hz, tones_hz, pad)[0]


def _cos_sin(omega: float, start: int, count: int) -> tuple[np.ndarray, np.ndarray]:
    """``cos`` and ``sin`` of ``omega*(start + i)`` [rad] for ``i = 0..count-1``
    (:func:`_fill_cos_sin` with one tone)."""
    out = np.empty((count, 2))
    _fill_cos_sin(out, 0, np.array([float(omega)]), int(start))
    return out[:, 0].copy(), out[:, 1].copy()


@numba.njit(cache=True, nogil=True)
def _fill_cos_sin(out: np.ndarray, col0: int, omegas: np.ndarray, start: int) -> None:
    """``cos`` and ``sin`` of ``omegas[m]*(start + i)`` [rad] into ``out[i, col0 + 2m]`` and
    ``out[i, col0 + 2m + 1]`` for every row i: the exact values every 64 samples and a
    rotation by one sample between (``cos(a + w) = cos a cos w - sin a sin w``, and the
    sine's): two evaluations per 64 samples instead of 128. The rotation adds ~1e-16 of
    the amplitude per step (< 1e-14 here; tests/dsp/test_decimate_kernels.py compares with the
    direct evaluation, whose own argument is rounded to that order)."""
    n = out.shape[0]
    for m in range(omegas.size):
        om = omegas[m]
        cd, sd = math.cos(om), math.sin(om)
        for blk in range(0, n, 64):
            arg = om * (start + blk)
            c, s = math.cos(arg), math.sin(arg)
            for i in range(blk, min(n, blk + 64)):
                out[i, col0 + 2 * m] = c
                out[i, col0 + 2 * m + 1] = s
                c, s = c * cd - s * sd, s * cd + c * sd


def model_padded_rows(rows, fs_hz: float, tones_hz: list[float], pad: int
                      ) -> list[tuple[np.ndarray, float, float]]:
    """:func:`model_padded` of each record (equal lengths; the same numbers).

    The least-squares design is factored once, the tones' cosines and sines over the padded
    times evaluated once, each padding their product with the record's coefficients.

    Parameters
    ----------
    rows : sequence of ndarray
        Records of equal length, any unit.
    fs_hz : float
        Sample rate [Hz].
    tones_hz : list of float
        The stationary tones [Hz].
    pad : int
        Samples added at each end [-].

    Returns
    -------
    list of tuple
        (padded record, mean, slope [per s]) of each row.
    """
    rows = [np.asarray(x, dtype=np.float64) for x in rows]
    n = rows[0].size
    design, kept = _line_and_tones_design(n, fs_hz, tones_hz)
    fac = LstsqFactor.of(design)
    trig = np.empty((n + 2 * pad, 2 * len(kept)))
    _fill_cos_sin(trig, 0, 2 * np.pi * np.array(kept, dtype=np.float64) / fs_hz, -pad)
    line = design[:, 1]  # t - mean t over the record [s]
    result = []
    for x in rows:
        coef = fac.solve(x) if fac is not None else lstsq(design, x)[0]
        out = trig @ coef[2:] if kept else np.zeros(n + 2 * pad)
        out[pad:pad + n] = x - coef[0] - coef[1] * line
        result.append((out, float(coef[0]), float(coef[1])))
    return result


def tone_free_mean(x: np.ndarray, fs_hz: float, tones_hz: list[float]) -> float:
    """Mean of a record with given tones removed.

    The constant term of a least-squares fit ``c0 + sum(a_k*cos + b_k*sin)(2*pi*f_k*t)``:
    the value a notch at each tone followed by averaging converges to, without a notch's edge
    transients and also when the record is shorter than the tones' beat period (a notch at
    the platform's 1st and 2nd rotation harmonics cannot separate them within one
    revolution). Over whole periods of every tone it equals the plain mean.

    Parameters
    ----------
    x : ndarray
        The record, any unit.
    fs_hz : float
        Sample rate [Hz].
    tones_hz : list of float
        The tones [Hz]; none: the plain mean.

    Returns
    -------
    float
        The mean, unit of x.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(150) / 100.0
    >>> round(tone_free_mean(2.0 + np.sin(2 * np.pi * 1.0 * t), 100.0, [1.0]), 9)
    2.0
    """
    x = np.asarray(x, dtype=np.float64)
    tones = [f for f in tones_hz if 0 < f < fs_hz / 2]
    if not tones:
        return float(x.mean())
    m = x.mean()
    coef, _ = lstsq(tone_design(np.arange(x.size) / fs_hz, tones), x - m)
    return float(coef[0] + m)


@numba.njit(cache=True, nogil=True)
def fill_tones_together(out: np.ndarray, col0: int, omegas: np.ndarray, origin: float,
                        scale: float) -> None:
    """Columns ``cos`` and ``sin`` of up to four tones at a time, advancing together, into
    ``out[:, col0:col0 + 2*len(omegas)]``: sample ``i`` of tone ``m`` at the angle
    ``omegas[m] * ((i + origin) / scale)`` [rad], exact (libm) every 64 samples and rotated
    by one sample's angle ``omegas[m] / scale`` between (the angle-addition recurrence,
    e.g. Oppenheim and Schafer, Discrete-Time Signal Processing, 3rd ed., Sec. 6.7). Each
    tone's values come from the same operations as it alone would, so the same bits; the
    tones' rotations are independent chains the processor overlaps.

    ``omegas`` are per sample with ``scale = 1`` (and ``origin`` the first sample's index),
    or in rad/s with ``scale`` the sample rate [Hz] (and ``origin`` the time origin in
    samples)."""
    n = out.shape[0]
    k = omegas.size
    for g in range(0, k, 4):
        cnt = min(4, k - g)
        om0 = omegas[g]
        om1 = omegas[g + 1] if cnt > 1 else 0.0
        om2 = omegas[g + 2] if cnt > 2 else 0.0
        om3 = omegas[g + 3] if cnt > 3 else 0.0
        cd0, sd0 = math.cos(om0 / scale), math.sin(om0 / scale)
        cd1, sd1 = math.cos(om1 / scale), math.sin(om1 / scale)
        cd2, sd2 = math.cos(om2 / scale), math.sin(om2 / scale)
        cd3, sd3 = math.cos(om3 / scale), math.sin(om3 / scale)
        j0 = col0 + 2 * g
        for blk in range(0, n, 64):
            tb = (blk + origin) / scale
            c0, s0 = math.cos(om0 * tb), math.sin(om0 * tb)
            c1 = s1 = c2 = s2 = c3 = s3 = 0.0  # (the slots beyond the tones: not stored)
            if cnt > 1:
                c1, s1 = math.cos(om1 * tb), math.sin(om1 * tb)
            if cnt > 2:
                c2, s2 = math.cos(om2 * tb), math.sin(om2 * tb)
            if cnt > 3:
                c3, s3 = math.cos(om3 * tb), math.sin(om3 * tb)
            for i in range(blk, min(n, blk + 64)):
                out[i, j0] = c0
                out[i, j0 + 1] = s0
                if cnt > 1:
                    out[i, j0 + 2] = c1
                    out[i, j0 + 3] = s1
                if cnt > 2:
                    out[i, j0 + 4] = c2
                    out[i, j0 + 5] = s2
                if cnt > 3:
                    out[i, j0 + 6] = c3
                    out[i, j0 + 7] = s3
                c0, s0 = c0 * cd0 - s0 * sd0, s0 * cd0 + c0 * sd0
                c1, s1 = c1 * cd1 - s1 * sd1, s1 * cd1 + c1 * sd1
                c2, s2 = c2 * cd2 - s2 * sd2, s2 * cd2 + c2 * sd2
                c3, s3 = c3 * cd3 - s3 * sd3, s3 * cd3 + c3 * sd3
