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
The same residuals give the price in variance of fitting the tone beside the other columns:
with ``G = R'R`` for R the tone's and its harmonics' residuals on that basis, the tone's
residual on all the other columns has the normal matrix ``G_MM - G_MH G_HH^-1 G_HM``, the
Schur complement (Frisch-Waugh-Lovell again), a few small products instead of a refined
least-squares fit on the whole design.
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
def _tone_rows(design: np.ndarray, end: int) -> np.ndarray:
    """The design's first two and last columns (from ``end``: the tone and its harmonics)
    as C-ordered rows."""
    n, m = design.shape
    mt = np.empty((2 + m - end, n))
    for t in range(n):
        mt[0, t] = design[t, 0]
        mt[1, t] = design[t, 1]
        for j in range(end, m):
            mt[2 + j - end, t] = design[t, j]
    return mt


@numba.njit(cache=True, nogil=True)
def _residual_powers(qt_b: np.ndarray, mt: np.ndarray, v: np.ndarray
                     ) -> tuple[np.ndarray, bool, np.ndarray]:
    """:func:`~torquemod.dsp.projection.powers_in_span` of ``v`` for the basis ``qt_b`` and
    the rows ``mt`` (its kernel, so the same numbers), and the normal matrix ``G = R'R`` of
    the rows' residuals ``R = M - Q_B Q_B'M`` it forms: ``(powers, made, G)``, not made
    where ``v`` has no columns (or not ``mt``'s length), a row keeps less than 1e-5 of its
    norm or a pivot of G's Cholesky factorisation falls below 1e-10 of its diagonal
    element."""
    if v.shape[1] == 0 or v.shape[0] != mt.shape[1]:
        rt = mt - np.dot(np.dot(mt, qt_b.T), qt_b)
        return np.empty(0), False, np.dot(rt, rt.T)
    return _powers_in_span(qt_b, mt, v)


@numba.njit(cache=True, nogil=True)
def _noise_kept(qv: np.ndarray, v_power: np.ndarray) -> float:
    """The mean over the bins of ``1 - |Q'v|^2/|v|^2`` from the powers ``qv``
    (:func:`_residual_powers`: the real parts of the bins' vectors, then their imaginary
    parts), clipped to [0.05, 1] as Python's ``min(max(x, 0.05), 1.0)`` (NaN kept)."""
    nb = v_power.size
    kept = np.empty(nb)
    for b in range(nb):
        kept[b] = 1.0 - (qv[b] + qv[nb + b]) / v_power[b]
    mean = numpyblas.vector_sum(kept) / nb
    if mean != mean:
        return mean
    return min(max(mean, 0.05), 1.0)


@numba.njit(cache=True, nogil=True)
def _schur_ratio(design: np.ndarray, mt: np.ndarray, g: np.ndarray, syrk: int) -> float:
    """``trace((R'R)^-1)/trace((M'M)^-1)`` for M the design's first two columns and R their
    least-squares residual on all its other columns, from the normal matrix ``g`` of the
    residuals of the rows ``mt`` (:func:`_tone_rows`: M and the harmonics H) on the basis
    (:func:`_residual_powers`): ``R'R`` is the Schur complement of its H block. ``M'M`` by
    numpy's ``syrk`` call, as :func:`~torquemod.dsp.lstsq.fit_with_parts`. NaN where a row
    keeps less than 1e-5 of its norm or a pivot falls below 1e-10 of its diagonal element
    (the caller then takes the refined fit)."""
    k = mt.shape[0]
    norms2 = lstsq._row_sums_of_squares(mt)
    for i in range(k):
        norm2 = norms2[i]
        if not g[i, i] > 1e-10 * norm2:
            return np.nan
    h = k - 2
    low = np.zeros((h, h))  # G_HH = L L'
    for i in range(h):
        for c in range(i + 1):
            acc = g[2 + i, 2 + c]
            for q in range(c):
                acc -= low[i, q] * low[c, q]
            if i == c:
                if not acc > 1e-10 * g[2 + i, 2 + i]:
                    return np.nan
                low[i, i] = np.sqrt(acc)
            else:
                low[i, c] = acc / low[c, c]
    x = np.empty((h, 2))  # L^-1 G_HM
    for col in range(2):
        for i in range(h):
            acc = g[2 + i, col]
            for q in range(i):
                acc -= low[i, q] * x[q, col]
            x[i, col] = acc / low[i, i]
    s = np.empty((2, 2))
    for a in range(2):
        for b in range(2):
            acc = g[a, b]
            for i in range(h):
                acc -= x[i, a] * x[i, b]
            s[a, b] = acc
    det = s[0, 0] * s[1, 1] - s[0, 1] * s[1, 0]
    if not det > 0.0:
        return np.nan
    mm = numpyblas.gram_t(design[:, :2], syrk)
    t_m = (mm[0, 0] + mm[1, 1]) / (mm[0, 0] * mm[1, 1] - mm[0, 1] * mm[1, 0])
    return (s[0, 0] + s[1, 1]) / det / t_m


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
        ``(p + q, n)`` C-ordered orthonormal rows spanning ``[slow, further]`` (the noise
        fraction and the variance ratio by :func:`_schur_ratio` are made on them), or an
        empty array: no noise fraction, the ratio by the refined fit of
        :func:`~torquemod.dsp.lstsq.fit_with_parts`.
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
        As :func:`~torquemod.dsp.lstsq.fit_with_parts` (``ratio`` by :func:`_schur_ratio`
        with ``qt_b``, where it is made).
    means : ndarray
        ``(k,)`` means of each record's slow part (numpy's pairwise sum over n) [its unit].
    noise_kept : float
        The residual's fraction of white noise near the tone (:func:`_noise_kept`).
    noise_made : bool
        Whether ``noise_kept`` was made: not when not asked for (an empty ``qt_b`` or fewer
        than two bins) or where :func:`_residual_powers` declines.
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
    # with the basis, the variance ratio from the tone's residuals on it (_schur_ratio)
    use_basis = n_s + n_f > 0 and qt_b.shape[0] == n_s + n_f and qt_b.shape[1] == n
    dn, scale, gram, factor, coef, parts, ratio, status = lstsq.fit_with_parts_and_ratio(
        design, y, bounds, wanted, syrk, gemm, gemv, potrf, potrs, not use_basis)
    means = np.full(k, np.nan)
    noise, made = np.nan, False
    if status != 0:
        return (design, dn, scale, gram, factor, coef, parts, ratio, status, means, noise,
                made)
    for j in range(k):
        if wanted[0, j]:
            means[j] = numpyblas.vector_sum(parts[0, j]) / n
    if use_basis:
        mt = _tone_rows(design, end)
        qv, made, g = _residual_powers(qt_b, mt, v)
        made = made and v_power.size >= 2
        if made:
            noise = _noise_kept(qv, v_power)
        ratio = _schur_ratio(design, mt, g, syrk)
        if ratio != ratio and design.shape[1] > 3:
            ratio = lstsq.leading_variance_ratio(design, gram, dn, scale, potrf, potrs, syrk,
                                                 gemm)
    return design, dn, scale, gram, factor, coef, parts, ratio, status, means, noise, made
