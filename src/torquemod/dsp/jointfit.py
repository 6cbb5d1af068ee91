"""The joint least-squares fit of a tone, a slow basis and further columns to several records
in one compiled call: the tone's columns, the design, its factor and solve
(:func:`torquemod.dsp.lstsq.fit_with_parts`), each record's slow-part mean and the power of
white noise near the tone that the fit's residual keeps, with the numbers of the numpy
routes they replace.

The tone's cosines and sines are evaluated on a time axis centred on the record's middle,
``t_i = (i - (n - 1)/2)/fs``: ``t_{n-1-i} = -t_i`` exactly (a half-integer difference and
one rounded division), so ``k w t`` is odd and each cosine and sine of the record's second
half is the first half's, mirrored (``cos`` even and ``sin`` odd in the C library, checked
by the tests): half the evaluations, the same numbers.

The residual's noise fraction is ``1 - |Q'v|^2/|v|^2`` for the Hann-windowed Fourier vectors
v of the bins near the tone and Q an orthonormal basis of the design (for least squares
``E[r r'] = sigma^2 (I - H)``, Seber and Lee, *Linear Regression Analysis*, 2nd ed., 2003,
section 3.3), from an orthonormal basis of the slow and further columns and the tone's part
orthogonal to it (Frisch-Waugh-Lovell; :func:`torquemod.dsp.projection.powers_in_span`).
"""

from __future__ import annotations

import numba
import numpy as np

from torquemod.dsp import lstsq, numpyblas
from torquemod.dsp.projection import _powers_in_span


@numba.njit(cache=True, nogil=True)
def _fill_tone_columns(out: np.ndarray, first: int, fs_hz: float, modulation_hz: float,
                       orders: np.ndarray) -> None:
    """``out[:, first + 2i]``, ``out[:, first + 2i + 1]`` = ``cos``, ``sin`` of ``(k w) t``
    for the i-th order k, ``w = 2 pi f`` and t from the record's middle (the products and
    the library's ``cos`` and ``sin`` of numpy's expression ``np.cos(k * w * t)``), each
    evaluated on the first half and mirrored to the second."""
    n = out.shape[0]
    w = 2 * np.pi * modulation_hz
    c = (n - 1) / 2
    half = (n + 1) // 2  # the middle sample (odd n) evaluated, not mirrored
    for i in range(orders.size):
        kw = orders[i] * w
        col = first + 2 * i
        for r in range(half):
            x = kw * ((r - c) / fs_hz)
            cv = np.cos(x)
            sv = np.sin(x)
            out[r, col] = cv
            out[r, col + 1] = sv
            if n - 1 - r != r:
                out[n - 1 - r, col] = cv
                out[n - 1 - r, col + 1] = -sv


@numba.njit(cache=True, nogil=True)
def tone_columns(n: int, fs_hz: float, modulation_hz: float, orders: np.ndarray
                 ) -> np.ndarray:
    """The cosine and sine of each order of a tone, time from the record's middle.

    Parameters
    ----------
    n : int
        Samples [-].
    fs_hz : float
        Sample rate [Hz].
    modulation_hz : float
        The tone's frequency f [Hz].
    orders : ndarray
        int64 orders k [-].

    Returns
    -------
    ndarray
        ``(n, 2 len(orders))`` columns ``cos(2 pi k f t)``, ``sin(2 pi k f t)`` [-] with
        ``t = (i - (n - 1)/2)/fs``: numpy's numbers for ``np.cos(k * w * t)``.
    """
    out = np.empty((n, 2 * orders.size))
    _fill_tone_columns(out, 0, fs_hz, modulation_hz, orders)
    return out


@numba.njit(cache=True, nogil=True)
def _noise_kept(design: np.ndarray, end: int, qt_b: np.ndarray, v: np.ndarray,
                v_power: np.ndarray) -> tuple[float, bool]:
    """The mean over the bins of ``1 - |Q'v|^2/|v|^2`` (``v``'s columns: the real parts of
    the bins' vectors, then their imaginary parts), Q spanning ``qt_b``'s rows and the
    design's first two and last columns (from ``end``) by
    :func:`~torquemod.dsp.projection.powers_in_span`; clipped to [0.05, 1] as
    Python's ``min(max(x, 0.05), 1.0)`` (NaN kept); ``(fraction, made)``, not made where
    those columns are (nearly) in the basis's span (the caller then takes another route)."""
    n, m = design.shape
    k = 2 + m - end
    mt = np.empty((k, n))
    for t in range(n):
        mt[0, t] = design[t, 0]
        mt[1, t] = design[t, 1]
        for j in range(end, m):
            mt[2 + j - end, t] = design[t, j]
    qv, ok = _powers_in_span(qt_b, mt, v)
    if not ok:
        return np.nan, False
    nb = v_power.size
    kept = np.empty(nb)
    for b in range(nb):
        kept[b] = 1.0 - (qv[b] + qv[nb + b]) / v_power[b]
    mean = numpyblas.vector_sum(kept) / nb
    if mean != mean:
        return mean, True
    return min(max(mean, 0.05), 1.0), True


@numba.njit(cache=True, nogil=True)
def fit_tone_model(y, fs_hz, modulation_hz, tone_orders, slow, further, bounds, wanted,
                   qt_b, v, v_power, syrk, gemm, gemv, potrf, potrs):
    """The joint least-squares fit of ``[cos, sin, slow, further, harmonics]`` to every
    column of ``y`` and its statistics, in one call.

    Parameters
    ----------
    y : ndarray
        ``(n, k)`` C-ordered records (n >= 2), any units.
    fs_hz : float
        Sample rate [Hz].
    modulation_hz : float
        The tone's frequency [Hz].
    tone_orders : ndarray
        int64 orders of the tone, the first 1 [-]: its cosine and sine are the design's
        first two columns, the others' its last ones (:func:`tone_columns`).
    slow, further : ndarray
        ``(n, p)`` and ``(n, q)`` columns of the design between them.
    bounds, wanted : ndarray
        The parts of :func:`~torquemod.dsp.lstsq.fit_with_parts` (the first: the slow part,
        whose mean is taken).
    qt_b : ndarray
        ``(p + q, n)`` C-ordered orthonormal rows spanning ``[slow, further]``, or an empty
        array: no noise fraction.
    v, v_power : ndarray
        ``(n, 2b)`` Hann-windowed Fourier vectors of b bins (real parts, then imaginary) and
        their ``(b,)`` squared norms.
    syrk, gemm, gemv, potrf, potrs : int
        numpy's BLAS and LAPACK's routines (:func:`~torquemod.dsp.numpyblas.addresses`,
        :func:`~torquemod.dsp.lstsq.lapack_addresses`).

    Returns
    -------
    design : ndarray
        The ``(n, m)`` design.
    dn, scale, gram, factor, coef, parts, ratio, status
        As :func:`~torquemod.dsp.lstsq.fit_with_parts`.
    means : ndarray
        ``(k,)`` means of each record's slow part (numpy's pairwise sum over n) [its unit].
    noise_kept : float
        The residual's fraction of white noise near the tone (:func:`_noise_kept`).
    noise_made : bool
        Whether ``noise_kept`` was made: not when not asked for (an empty ``qt_b`` or fewer
        than two bins) or where :func:`_noise_kept` declines.
    """
    n, k = y.shape
    n_s, n_f = slow.shape[1], further.shape[1]
    n_h = 2 * (tone_orders.size - 1)
    end = 2 + n_s + n_f
    design = np.empty((n, end + n_h))
    tones = tone_columns(n, fs_hz, modulation_hz, tone_orders)
    for t in range(n):
        design[t, 0] = tones[t, 0]
        design[t, 1] = tones[t, 1]
        for j in range(n_s):
            design[t, 2 + j] = slow[t, j]
        for j in range(n_f):
            design[t, 2 + n_s + j] = further[t, j]
        for j in range(n_h):
            design[t, end + j] = tones[t, 2 + j]
    dn, scale, gram, factor, coef, parts, ratio, status = lstsq.fit_with_parts(
        design, y, bounds, wanted, syrk, gemm, gemv, potrf, potrs)
    means = np.full(k, np.nan)
    noise, made = np.nan, False
    if status != 0:
        return (design, dn, scale, gram, factor, coef, parts, ratio, status, means, noise,
                made)
    for j in range(k):
        if wanted[0, j]:
            means[j] = numpyblas.vector_sum(parts[0, j]) / n
    if qt_b.shape[0] == n_s + n_f and qt_b.shape[1] == n and v_power.size >= 2:
        noise, made = _noise_kept(design, end, qt_b, v, v_power)
    return design, dn, scale, gram, factor, coef, parts, ratio, status, means, noise, made
