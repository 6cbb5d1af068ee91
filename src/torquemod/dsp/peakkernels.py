"""The compiled kernels of the spectral peak search (:mod:`torquemod.dsp.spectrum`).

The bins of a zero-padded DFT by Goertzel's recurrence (G. Goertzel, "An algorithm for the
evaluation of finite trigonometric series", Amer. Math. Monthly 65(1), 1958), the checks on
them (the largest bin of the band, its neighbourhood, the floor's median) and the refinement
of the peak by Brent's bounded search of the windowed DTFT's magnitude (R. P. Brent,
"Algorithms for Minimization without Derivatives", Prentice-Hall 1973, ch. 5); and all of it,
detrending and windowing included, for the columns of a record in one call.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from torquemod.dsp import numpyblas
from torquemod.dsp.lstsq import _solve


@numba.njit(cache=True, nogil=True)
def _goertzel_coefficients(nfft: int, k_lo: int, k_hi: int) -> tuple[np.ndarray, np.ndarray]:
    """``cos(w)`` and ``sin(w)`` of the bins ``k_lo..k_hi`` of an ``nfft``-point DFT,
    ``w = 2*pi*k/nfft`` [rad per sample]: the constants of :func:`_goertzel_magnitudes`."""
    m = k_hi - k_lo + 1
    cw = np.empty(m)
    sw = np.empty(m)
    for b in range(m):
        w = 2.0 * math.pi * (k_lo + b) / nfft
        cw[b] = math.cos(w)
        sw[b] = math.sin(w)
    return cw, sw


@numba.njit(cache=True, nogil=True, fastmath={"contract"})
def _goertzel_magnitudes(x: np.ndarray, cw: np.ndarray, sw: np.ndarray, out: np.ndarray
                         ) -> None:
    """``|X(w_b)| = |sum_t x_t exp(-i w_b t)|`` for the bins whose ``cos(w_b)``, ``sin(w_b)``
    are ``cw``, ``sw`` (:func:`_goertzel_coefficients`) into ``out[b]``, by Goertzel's
    recurrence ``s_t = x_t + 2 cos(w) s_(t-1) - s_(t-2)``, ``|X| = |s_(n-1) - exp(-iw)
    s_(n-2)|``. Four samples a pass over the bins, the states held in registers between
    them; the bins advance together (they vectorise), each product and sum fused into one
    rounding (FMA). The FFT's magnitudes to rounding (measured: 7e-15 of the largest from
    the unfused recurrence, 2.4e-13 from numpy's FFT on 300 records with a DC offset): they
    only choose bins, the same ones."""
    m = cw.size
    n = x.size
    coef = np.empty(m)
    for b in range(m):
        coef[b] = 2.0 * cw[b]
    s1 = np.zeros(m)  # s_(t-1)
    s2 = np.zeros(m)  # s_(t-2)
    t = 0
    while t + 4 <= n:
        x0, x1, x2, x3 = x[t], x[t + 1], x[t + 2], x[t + 3]
        for b in range(m):
            c = coef[b]
            u0 = x0 + c * s1[b] - s2[b]
            u1 = x1 + c * u0 - s1[b]
            u2 = x2 + c * u1 - u0
            u3 = x3 + c * u2 - u1
            s2[b] = u2
            s1[b] = u3
        t += 4
    while t < n:
        xt = x[t]
        for b in range(m):
            s0 = xt + coef[b] * s1[b] - s2[b]
            s2[b] = s1[b]
            s1[b] = s0
        t += 1
    for b in range(m):
        re = s1[b] - cw[b] * s2[b]
        im = sw[b] * s2[b]
        out[b] = math.sqrt(re * re + im * im)


@numba.njit(cache=True, nogil=True)
def _band_magnitudes(x: np.ndarray, nfft: int, k_lo: int, k_hi: int, out: np.ndarray) -> None:
    """``|X[k]|`` of the ``nfft``-point DFT of the zero-padded record ``x`` for the bins
    ``k_lo..k_hi`` into ``out[k]`` (:func:`_goertzel_magnitudes`)."""
    cw, sw = _goertzel_coefficients(nfft, k_lo, k_hi)
    _goertzel_magnitudes(x, cw, sw, out[k_lo:k_hi + 1])


@numba.njit(cache=True, nogil=True)
def _median(vals: np.ndarray) -> float:
    """``np.median`` of a 1-D float array (NaN-free), which it reorders: the middle order
    statistic, or the mean of the two middle ones, by Hoare's selection (C. A. R. Hoare,
    "Algorithm 65: Find", Comm. ACM 4(7), 1961) instead of a sort (the same values)."""
    m = vals.size
    half = m // 2
    _select(vals, half)
    if m % 2:
        return vals[half]
    below = vals[0]
    for i in range(1, half):  # the largest of the lower part: the order statistic half-1
        if vals[i] > below:
            below = vals[i]
    return (below + vals[half]) / 2


@numba.njit(cache=True, nogil=True)
def _select(a: np.ndarray, kth: int) -> None:
    """Reorder ``a`` so that ``a[kth]`` is its ``kth`` order statistic, everything before it
    no larger and everything after it no smaller (Hoare's selection, middle pivot)."""
    lo, hi = 0, a.size - 1
    while lo < hi:
        pivot = a[(lo + hi) // 2]
        i, j = lo, hi
        while i <= j:
            while a[i] < pivot:
                i += 1
            while a[j] > pivot:
                j -= 1
            if i <= j:
                a[i], a[j] = a[j], a[i]
                i += 1
                j -= 1
        if kth <= j:
            hi = j
        elif kth >= i:
            lo = i
        else:
            return


@numba.njit(cache=True, nogil=True)
def _bin_checks(mag: np.ndarray, k_lo: int, freqs: np.ndarray, band: tuple[int, int],
                wide: tuple[int, int], lobe: float) -> tuple[int, int, float]:
    """:func:`_line_search` on the bins ``k_lo..k_lo + mag.size - 1`` of a spectrum whose
    magnitudes are ``mag`` (zeros elsewhere), the band's bins ``band[0]..band[1]`` and the
    floor's ``wide[0]..wide[1]`` (ranges of bins, within those given): the same ``k``,
    ``j`` and floor, the spectrum's other bins being never more than the largest of
    these."""
    k = band[0]
    for i in range(band[0], band[1] + 1):
        if mag[i - k_lo] > mag[k - k_lo]:
            k = i
    j = -1
    for i in range(k_lo, k_lo + mag.size):
        if abs(freqs[i] - freqs[k]) <= 2 * lobe and (j < 0 or mag[i - k_lo] > mag[j - k_lo]):
            j = i
    sel = np.empty(wide[1] - wide[0] + 1)
    m = 0
    for i in range(wide[0], wide[1] + 1):
        if abs(freqs[i] - freqs[k]) > lobe:
            sel[m] = mag[i - k_lo] ** 2
            m += 1
    if m == 0:
        return k, j, np.nan
    return k, j, _median(sel[:m])


@numba.njit(cache=True, nogil=True)
def _peaks_of_records(x: np.ndarray, xtol_hz: float, min_ratio: float, maxfun: int,
                      dn: np.ndarray, factor: np.ndarray, scale: np.ndarray,
                      design: np.ndarray, w: np.ndarray, trig: np.ndarray, freqs: np.ndarray,
                      bins: np.ndarray, lobe: float, fs_hz: float
                      ) -> tuple[list[float], bool]:
    """:func:`~torquemod.dsp.spectrum.peak_frequency` of each column of ``x`` (``(n, k)``)
    in one call: the column less its least-squares fit on ``design`` (the compiled solve of
    :meth:`~torquemod.dsp.lstsq.LstsqFactor.solve` of a contiguous record, the fit by
    numpy's ``dgemv``: numpy's numbers), times the window ``w``; the magnitudes of the
    bins the checks read (:func:`_goertzel_magnitudes` with the rows of ``trig``, ``cos``
    and ``sin`` of the bins from ``k_lo``), the checks (:func:`_bin_checks`) and Brent's
    refinement of the windowed record (:func:`_dtft_peak`). ``bins`` holds ``k_lo``, the
    band's first and last bin, the floor's first and last bin and the addresses of numpy's
    ``dgemv`` and LAPACK's ``dpotrs``. The frequencies [Hz] (NaN where a column failed the
    checks) and whether every column passed them."""
    n, cols = x.shape
    k_lo, band, wide = bins[0], (bins[1], bins[2]), (bins[3], bins[4])
    gemv, potrs = bins[5], bins[6]
    cw, sw = trig[0], trig[1]
    out = [np.nan] * cols
    passed = 0
    df = freqs[1] - freqs[0]
    mag = np.empty(cw.size)
    wx = np.empty(n)
    for r in range(cols):
        col = np.ascontiguousarray(x[:, r])
        fit = numpyblas.matvec(design, _solve(dn, factor, scale, col, potrs), gemv)
        for t in range(n):
            wx[t] = (col[t] - fit[t]) * w[t]
        _goertzel_magnitudes(wx, cw, sw, mag)
        k, j, floor = _bin_checks(mag, k_lo, freqs, band, wide, lobe)
        pk, pj = mag[k - k_lo], mag[j - k_lo]
        if k == band[0] or k == band[1] or not pk > 0 or pj > pk:
            continue
        if floor > 0 and pk ** 2 < min_ratio * floor:
            continue
        out[r] = _dtft_peak(wx, fs_hz, freqs[k] - df, freqs[k] + df, xtol_hz, maxfun)
        passed += 1
    return out, passed == cols


@numba.njit(cache=True, nogil=True)
def _line_search(spec: np.ndarray, freqs: np.ndarray, idx: np.ndarray, wide: np.ndarray,
                 lobe: float) -> tuple[int, int, float]:
    """The FFT bins :func:`peak_frequency` judges, in one pass: ``k``, the largest of
    ``spec`` among the band's bins ``idx`` (the first on a tie, as ``np.argmax``); ``j``,
    the largest within ``2*lobe`` [Hz] of it; and the floor, the median of ``spec**2`` over
    the bins of ``wide`` farther than ``lobe`` from it (NaN when there are none), the
    median as ``np.median`` takes it (the middle value, or the mean of the two middle
    ones; the same numbers, tests/processing/test_chain_kernels.py)."""
    k = idx[0]
    for i in idx:
        if spec[i] > spec[k]:
            k = i
    j = -1
    sel = np.empty(spec.size)
    m = 0
    for i in range(spec.size):
        off = abs(freqs[i] - freqs[k])
        if off <= 2 * lobe and (j < 0 or spec[i] > spec[j]):
            j = i
        if wide[i] and off > lobe:
            sel[m] = spec[i] ** 2
            m += 1
    if m == 0:
        return k, j, np.nan
    vals = np.sort(sel[:m])
    if m % 2:
        return k, j, vals[m // 2]
    return k, j, (vals[m // 2 - 1] + vals[m // 2]) / 2


@numba.njit(cache=True, nogil=True)
def _dtft_magnitude(wx: np.ndarray, step_rad: float) -> float:
    """``|sum_n wx[n] exp(-1j*step_rad*n)|``: the phasors by the angle-addition formulas
    over blocks of 32 samples (about n/16 + 64 sines and cosines instead of n complex
    exponentials; a few units in the last place from the direct evaluation), summed in
    order. 10x faster than numpy's complex ``exp`` and ``dot`` on a cycle's ~330 samples."""
    n = wx.size
    block = 32
    cb = np.empty(block)
    sb = np.empty(block)
    for i in range(block):
        cb[i] = math.cos(step_rad * i)
        sb[i] = math.sin(step_rad * i)
    re = 0.0
    im = 0.0
    for start in range(0, n, block):
        c0 = math.cos(step_rad * start)
        s0 = math.sin(step_rad * start)
        for i in range(min(block, n - start)):
            v = wx[start + i]
            re += v * (c0 * cb[i] - s0 * sb[i])
            im -= v * (s0 * cb[i] + c0 * sb[i])
    return math.hypot(re, im)


@numba.njit(cache=True, nogil=True)
def _dtft_peak(wx: np.ndarray, fs_hz: float, lo: float, hi: float, xatol: float,
               maxfun: int) -> float:
    """The frequency [Hz] in ``[lo, hi]`` that maximises ``|X_w(f)|``
    (:func:`_dtft_magnitude` of the windowed record ``wx`` at ``2*pi*f/fs_hz`` rad per
    sample), by Brent's bounded search (Brent 1973, ch. 5: golden-section steps with
    parabolic interpolation) with the same steps and the same arithmetic as
    ``scipy.optimize.fminbound(lambda f: -|X_w(f)|, lo, hi, xtol=xatol, maxfun=maxfun)``,
    so the same result bit for bit (tests/processing/test_chain_kernels.py), in one compiled
    call."""
    sqrt_eps = 1.4832396974191326e-08  # math.sqrt(2.2e-16), as scipy's
    golden = 0.3819660112501051  # 0.5*(3 - sqrt(5))
    two_pi = 2.0 * math.pi
    a, b = lo, hi
    fulc = a + golden * (b - a)
    nfc = xf = fulc
    rat = e = 0.0
    fx = -_dtft_magnitude(wx, two_pi * xf / fs_hz)
    num = 1
    ffulc = fnfc = fx
    xm = 0.5 * (a + b)
    tol1 = sqrt_eps * abs(xf) + xatol / 3.0
    tol2 = 2.0 * tol1
    while abs(xf - xm) > (tol2 - 0.5 * (b - a)):
        use_golden = True
        if abs(e) > tol1:  # try a parabolic step
            use_golden = False
            r = (xf - nfc) * (fx - ffulc)
            q = (xf - fulc) * (fx - fnfc)
            p = (xf - fulc) * q - (xf - nfc) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            r = e
            e = rat
            if abs(p) < abs(0.5 * q * r) and q * (a - xf) < p < q * (b - xf):
                rat = (p + 0.0) / q
                x = xf + rat
                if (x - a) < tol2 or (b - x) < tol2:
                    rat = tol1 * (_sign(xm - xf) + (1.0 if xm - xf == 0 else 0.0))
            else:
                use_golden = True
        if use_golden:
            e = (a - xf) if xf >= xm else (b - xf)
            rat = golden * e
        step = abs(rat)
        x = xf + (_sign(rat) + (1.0 if rat == 0 else 0.0)) * (
            step if (step >= tol1 or step != step) else tol1)
        fu = -_dtft_magnitude(wx, two_pi * x / fs_hz)
        num += 1
        if fu <= fx:
            if x >= xf:
                a = xf
            else:
                b = xf
            fulc, ffulc = nfc, fnfc
            nfc, fnfc = xf, fx
            xf, fx = x, fu
        else:
            if x < xf:
                a = x
            else:
                b = x
            if fu <= fnfc or nfc == xf:
                fulc, ffulc = nfc, fnfc
                nfc, fnfc = x, fu
            elif fu <= ffulc or fulc == xf or fulc == nfc:
                fulc, ffulc = x, fu
        xm = 0.5 * (a + b)
        tol1 = sqrt_eps * abs(xf) + xatol / 3.0
        tol2 = 2.0 * tol1
        if num >= maxfun:
            break
    return xf


@numba.njit(cache=True, nogil=True)
def _sign(v: float) -> float:
    """``numpy.sign`` of a float (NaN stays NaN)."""
    return 1.0 if v > 0 else -1.0 if v < 0 else v * 0.0 if v != v else 0.0
