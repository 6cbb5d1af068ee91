"""Step 1 of the V-Track chain: the frequency of the strongest spectral line in a band.

A bare FFT bin of a 6.5 s record is 0.15 Hz wide. Here the mean (and linear trend) is removed,
a window is applied, the coarse maximum is taken from a zero-padded FFT and then refined by
maximising the magnitude of the windowed discrete-time Fourier transform (DTFT) itself with a
bounded scalar search (Brent's, as scipy's ``fminbound``), so the result is the exact
maximiser of ``|X_w(f)|`` to ``xtol_hz``.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np
from scipy import signal

from torquemod.dsp import numpyblas
from torquemod.dsp.lstsq import _DPOTRS, LstsqFactor, _solve, lstsq
from torquemod.dsp.tonemodel import tone_design
from torquemod.errors import ProcessingError


def windowed_dtft(x: np.ndarray, fs_hz: float, f_hz: float, window: np.ndarray) -> complex:
    """The windowed discrete-time Fourier transform at one frequency.

    ``X_w(f) = sum_n w[n]*x[n]*exp(-2j*pi*f*n/fs)``.

    Parameters
    ----------
    x : ndarray
        The record, any unit.
    fs_hz : float
        Sample rate [Hz].
    f_hz : float
        Frequency [Hz].
    window : ndarray
        The window, as long as ``x``.

    Returns
    -------
    complex
        X_w(f), unit of x.

    Examples
    --------
    >>> import numpy as np
    >>> abs(windowed_dtft(np.ones(4), 4.0, 0.0, np.ones(4)))
    4.0
    """
    n = np.arange(x.size)
    return complex(np.dot(window * x, np.exp(-2j * np.pi * f_hz / fs_hz * n)))


@functools.lru_cache(maxsize=32)
def _window(name: str, n: int) -> np.ndarray:
    """``get_window(name, n, fftbins=False)``, cached (read-only): the same for every cycle of
    a given length."""
    w = signal.get_window(name, n, fftbins=False)
    w.setflags(write=False)
    return w


@functools.lru_cache(maxsize=32)
def _trend_design(n: int, fs_hz: float, line: bool) -> tuple[np.ndarray, LstsqFactor | None]:
    """The detrending design of :func:`peak_frequency` without extra tones (constant, and the
    line when ``line``) and its least-squares factor, cached (read-only)."""
    design = tone_design(np.arange(n) / fs_hz, [], line=line)
    design.setflags(write=False)
    return design, LstsqFactor.of(design)


@functools.lru_cache(maxsize=32)
def _grid(nfft: int, fs_hz: float, lo: float, hi: float, n: int
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The frequencies [Hz] of an ``nfft``-point real FFT, the indices inside the band
    ``lo..hi`` and the mask of the floor's range (1 Hz beyond the band, above the main lobe
    of an ``n``-sample Hann window, below 0.45 fs) in :func:`peak_frequency`; cached
    (read-only): the same for every record of a given length."""
    freqs = np.fft.rfftfreq(nfft, 1.0 / fs_hz)
    idx = np.flatnonzero((freqs >= lo) & (freqs <= hi))
    lobe = 2.0 * fs_hz / n
    wide = (freqs >= max(lo - 1.0, lobe)) & (freqs <= min(hi + 1.0, 0.45 * fs_hz))
    for a in (freqs, idx, wide):
        a.setflags(write=False)
    return freqs, idx, wide


def peak_frequency(x: np.ndarray, fs_hz: float, *, band_hz: tuple[float, float] = (1.5, 2.5),
                   window: str = "hann", detrend: str = "linear", zero_pad: int = 8,
                   xtol_hz: float = 1e-6, remove_tones_hz: tuple[float, ...] = (),
                   min_peak_to_floor: float = 20.0) -> float:
    """Frequency of the largest spectral peak of a record inside a band.

    The coarse grid is ``fs/(zero_pad*N)``; the refinement maximises ``|X_w(f)|`` within one
    coarse cell either side.

    Parameters
    ----------
    x : ndarray
        The record, any unit.
    fs_hz : float
        Sample rate [Hz].
    band_hz : tuple of float
        The band searched [Hz]. Default (1.5, 2.5).
    window : str
        Any :func:`scipy.signal.get_window` name. Default "hann".
    detrend : {"linear", "constant"}
        Trend removed first ("constant": mean removal, as the V-Track paper's FFT step
        requires at least). Default "linear".
    zero_pad : int
        Zero-padding factor of the coarse grid [-]. Default 8.
    xtol_hz : float
        Tolerance of the refinement [Hz]. Default 1e-6.
    remove_tones_hz : tuple of float
        Known lines outside the band [Hz] (e.g. encoder eccentricity at the rotation
        harmonics) removed by least squares first, so that their window leakage, 100 times
        the modulation in size, cannot pull the peak. Default ().
    min_peak_to_floor : float
        Smallest ratio of the peak's power to the floor [-]. Default 20, from Monte Carlo on
        a 6.3 s record at 53.344 Hz (6000 draws each): white noise alone reaches it in 0.27 %
        of records; a line at -25 dB per-sample SNR at 16 670 Hz fell below it in none.

    Returns
    -------
    float
        The peak's frequency [Hz].

    Raises
    ------
    ValueError
        The band does not lie within 0..fs/2.
    ProcessingError
        The record is too short for the band, or the band holds no spectral line: the maximum
        is at a band edge, or its power is less than ``min_peak_to_floor`` times the floor
        (the median power from 1 Hz below to 1 Hz above the band, outside the peak's main
        lobe), or a stronger line lies within two main-lobe widths just outside the band.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    lo, hi = band_hz
    if not 0 <= lo < hi <= fs_hz / 2:
        raise ValueError(f"band {band_hz} Hz must lie within 0..fs/2 = {fs_hz / 2} Hz")
    tones = [f for f in remove_tones_hz if not lo - 0.5 <= f <= hi + 0.5 and 0 < f < fs_hz / 2]
    if tones:
        design = tone_design(np.arange(n) / fs_hz, tones, line=detrend == "linear")
        coef, _ = lstsq(design, x)
    else:  # the same design for every record of this length: factored once
        design, fac = _trend_design(n, fs_hz, detrend == "linear")
        coef = fac.solve(x) if fac is not None else lstsq(design, x)[0]
    xd = x - design @ coef
    w = _window(window, n) if isinstance(window, str) else \
        signal.get_window(window, n, fftbins=False)
    m = zero_pad * n  # nfft = 2**ceil(log2(m)), on integers without numpy's scalars
    nfft = 1 << (m - 1).bit_length() if isinstance(m, int) and m > 0 else \
        int(2 ** np.ceil(np.log2(m)))
    spec = np.abs(np.fft.rfft(xd * w, nfft))
    freqs, idx, wide = _grid(nfft, fs_hz, lo, hi, n)
    if idx.size < 3:
        raise ProcessingError(f"record of {n / fs_hz:.3g} s is too short to resolve the band "
                              f"{lo}-{hi} Hz")
    lobe = 2.0 * fs_hz / n  # Hann main-lobe half-width: 2 bins of the unpadded record
    k, j, floor = _line_search(spec, freqs, idx, wide, lobe)
    if k in (idx[0], idx[-1]) or spec[k] <= 0:
        raise ProcessingError(f"no spectral peak inside {lo}-{hi} Hz (the largest value is at "
                              f"the band edge, {freqs[k]:.4f} Hz)")
    df = freqs[1] - freqs[0]
    if spec[j] > spec[k]:
        raise ProcessingError(f"no spectral line inside {lo}-{hi} Hz (the largest value, at "
                              f"{freqs[k]:.4f} Hz, is leakage from a stronger line at "
                              f"{freqs[j]:.4f} Hz outside the band)")
    if floor > 0 and spec[k] ** 2 < min_peak_to_floor * floor:
        raise ProcessingError(f"no spectral line inside {lo}-{hi} Hz (the largest peak, at "
                              f"{freqs[k]:.4f} Hz, is only {spec[k] ** 2 / floor:.1f} times "
                              f"the noise floor's median power; needs "
                              f"{min_peak_to_floor:g})")

    return float(_dtft_peak(w * xd, float(fs_hz), float(freqs[k] - df), float(freqs[k] + df),
                            float(xtol_hz), 500))


def peak_frequencies(records: np.ndarray, fs_hz: float, *,
                     band_hz: tuple[float, float] = (1.5, 2.5), window: str = "hann",
                     detrend: str = "linear", zero_pad: int = 8, xtol_hz: float = 1e-6,
                     min_peak_to_floor: float = 20.0) -> list[float]:
    """:func:`peak_frequency` of each column of ``records``, the search in one call for all.

    Each column detrended and windowed, one FFT of all columns, then the bin search and the
    refinement by Brent's search of ``|X_w(f)|`` for all columns in one compiled call: the
    steps and parameters of :func:`peak_frequency`. A column is detrended as a contiguous
    record (:meth:`~torquemod.dsp.lstsq.LstsqFactor.solve`'s compiled route), so the
    frequencies equal :func:`peak_frequency`'s on each column as a contiguous array
    (tests/dsp/test_spectrum_batch.py). A column whose checks fail, and other windows or
    detrending designs, go through :func:`peak_frequency` itself, which raises its error.

    Parameters
    ----------
    records : ndarray
        ``(n, k)`` records, one a column, any unit.
    fs_hz : float
        Sample rate [Hz].
    band_hz, window, detrend, zero_pad, xtol_hz, min_peak_to_floor
        As :func:`peak_frequency` (band [Hz], refinement tolerance [Hz], power ratio [-]).

    Returns
    -------
    list of float
        The peak frequency of each column [Hz].

    Raises
    ------
    ValueError, ProcessingError
        As :func:`peak_frequency`, for the first column that fails.
    """
    x = np.asarray(records, dtype=np.float64)
    if x.ndim != 2:
        raise ValueError(f"records must be (n, k), not of shape {x.shape}")
    n = x.shape[0]
    lo, hi = band_hz
    kw = dict(band_hz=band_hz, window=window, detrend=detrend, zero_pad=zero_pad,
              xtol_hz=xtol_hz, min_peak_to_floor=min_peak_to_floor)
    design, fac = _trend_design(n, fs_hz, detrend == "linear") if n >= 3 else (None, None)
    if fac is None or not fac.dn.flags.c_contiguous or not isinstance(window, str) \
            or not isinstance(zero_pad, int) or zero_pad < 1 or not 0 <= lo < hi <= fs_hz / 2:
        return [peak_frequency(np.ascontiguousarray(x[:, i]), fs_hz, **kw)
                for i in range(x.shape[1])]
    w = _window(window, n)
    m = zero_pad * n
    nfft = 1 << (m - 1).bit_length()
    blas = numpyblas.addresses()
    if blas is not None and design.flags.c_contiguous:
        # detrended and windowed in one compiled call: the solve below and numpy's dgemv
        # for the trend (numpyblas.matvec), the same numbers
        wx = _detrended_windowed(x, fac.dn, np.asfortranarray(fac.factor), fac.scale, design,
                                 w, blas[2], _DPOTRS)
    else:
        wx = np.empty((x.shape[1], n))
        for i in range(x.shape[1]):  # detrended and windowed (the compiled solve of a
            col = np.ascontiguousarray(x[:, i])  # contiguous record)
            np.multiply(col - design @ fac.solve(col), w, out=wx[i])
    freqs, idx, wide = _grid(nfft, fs_hz, lo, hi, n)
    if idx.size >= 3:
        # the magnitudes of only the bins the checks read, by Goertzel's recurrence in the
        # same compiled call (the FFT's values to rounding: the same bins chosen; the
        # frequency itself is Brent's, from the record)
        k_lo, k_hi = _bins_read(nfft, fs_hz, lo, hi, n)
        peaks, ok = _peaks_of_records(wx, nfft, k_lo, k_hi, freqs, idx, wide,
                                      2.0 * fs_hz / n, float(fs_hz), float(xtol_hz),
                                      float(min_peak_to_floor), 500)
        if ok.all():
            return peaks.tolist()
    return [peak_frequency(np.ascontiguousarray(x[:, i]), fs_hz, **kw)
            for i in range(x.shape[1])]


@numba.njit(cache=True, nogil=True)
def _detrended_windowed(x: np.ndarray, dn: np.ndarray, factor: np.ndarray, scale: np.ndarray,
                        design: np.ndarray, w: np.ndarray, gemv: int, potrs: int
                        ) -> np.ndarray:
    """Each column of ``x`` less its least-squares fit on ``design`` (the compiled solve of
    :meth:`~torquemod.dsp.lstsq.LstsqFactor.solve` of a contiguous record; the fit by
    numpy's ``dgemv``, :func:`~torquemod.dsp.numpyblas.matvec`), times the window ``w``:
    ``(k, n)`` rows, numpy's numbers."""
    n, k = x.shape
    out = np.empty((k, n))
    for i in range(k):
        col = np.ascontiguousarray(x[:, i])
        fit = numpyblas.matvec(design, _solve(dn, factor, scale, col, potrs), gemv)
        for t in range(n):
            out[i, t] = (col[t] - fit[t]) * w[t]
    return out


@functools.lru_cache(maxsize=32)
def _bins_read(nfft: int, fs_hz: float, lo: float, hi: float, n: int) -> tuple[int, int]:
    """The first and last bin of an ``nfft``-point spectrum that :func:`_line_search` can
    read for the band ``lo..hi`` [Hz] (:func:`_grid`): the floor's range and every bin
    within two main lobes of a bin of the band; cached."""
    freqs, idx, wide = _grid(nfft, fs_hz, lo, hi, n)
    reach = 2.0 * (2.0 * fs_hz / n)  # 2*lobe [Hz]
    near = np.flatnonzero((freqs >= freqs[idx[0]] - reach) & (freqs <= freqs[idx[-1]] + reach))
    read = np.concatenate([near, np.flatnonzero(wide), idx])
    return int(read.min()), int(read.max())


@numba.njit(cache=True, nogil=True)
def _band_magnitudes(x: np.ndarray, nfft: int, k_lo: int, k_hi: int, out: np.ndarray) -> None:
    """``|X[k]|`` of the ``nfft``-point DFT of the zero-padded record ``x`` for the bins
    ``k_lo..k_hi`` into ``out[k]``, by Goertzel's recurrence (``s_t = x_t + 2 cos(w) s_(t-1)
    - s_(t-2)``, ``|X| = |s_(n-1) - exp(-iw) s_(n-2)|``, w = 2*pi*k/nfft), all bins advancing
    together over the samples (they vectorise)."""
    m = k_hi - k_lo + 1
    coef = np.empty(m)
    cw = np.empty(m)
    sw = np.empty(m)
    for b in range(m):
        w = 2.0 * math.pi * (k_lo + b) / nfft
        cw[b] = math.cos(w)
        sw[b] = math.sin(w)
        coef[b] = 2.0 * cw[b]
    s1 = np.zeros(m)
    s2 = np.zeros(m)
    for t in range(x.size):
        xt = x[t]
        for b in range(m):
            s0 = xt + coef[b] * s1[b] - s2[b]
            s2[b] = s1[b]
            s1[b] = s0
    for b in range(m):
        re = s1[b] - cw[b] * s2[b]
        im = sw[b] * s2[b]
        out[k_lo + b] = math.sqrt(re * re + im * im)


@numba.njit(cache=True, nogil=True)
def _peaks_of_records(wx: np.ndarray, nfft: int, k_lo: int, k_hi: int, freqs: np.ndarray,
                      idx: np.ndarray, wide: np.ndarray, lobe: float, fs_hz: float,
                      xtol_hz: float, min_ratio: float, maxfun: int
                      ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`peak_frequency`'s checks (:func:`_line_search` on the magnitudes of each
    row's ``nfft``-point spectrum, by :func:`_band_magnitudes` over the bins the checks
    read: zeros elsewhere, never read) and its refinement (:func:`_dtft_peak` of the
    windowed record) for each row of ``wx``: the frequencies [Hz] and whether each row
    passed the checks (NaN where not)."""
    rows = wx.shape[0]
    out = np.full(rows, np.nan)
    ok = np.zeros(rows, dtype=np.bool_)
    df = freqs[1] - freqs[0]
    for r in range(rows):
        mag = np.zeros(nfft // 2 + 1)
        _band_magnitudes(wx[r], nfft, k_lo, k_hi, mag)
        k, j, floor = _line_search(mag, freqs, idx, wide, lobe)
        if k == idx[0] or k == idx[-1] or not mag[k] > 0 or mag[j] > mag[k]:
            continue
        if floor > 0 and mag[k] ** 2 < min_ratio * floor:
            continue
        out[r] = _dtft_peak(wx[r], fs_hz, freqs[k] - df, freqs[k] + df, xtol_hz, maxfun)
        ok[r] = True
    return out, ok


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
