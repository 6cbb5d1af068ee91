"""Step 1 of the V-Track chain: the frequency of the strongest spectral line in a band.

A bare FFT bin of a 6.5 s record is 0.15 Hz wide. Here the mean (and linear trend) is removed,
a window is applied, the coarse maximum is taken from a zero-padded FFT and then refined by
maximising the magnitude of the windowed discrete-time Fourier transform (DTFT) itself with a
bounded scalar search (Brent's, as scipy's ``fminbound``), so the result is the exact
maximiser of ``|X_w(f)|`` to ``xtol_hz``.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy import signal

from torquemod.dsp import numpyblas
from torquemod.dsp.lstsq import _DPOTRS, LstsqFactor, lstsq
from torquemod.dsp.peakkernels import (  # the first two as spectrum's names: tests use them
    _band_magnitudes,  # noqa: F401
    _dtft_magnitude,  # noqa: F401
    _dtft_peak,
    _goertzel_coefficients,
    _line_search,
    _peaks_of_records,
)
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

    The steps and parameters of :func:`peak_frequency` for all columns in one compiled call
    (:func:`~torquemod.dsp.peakkernels._peaks_of_records`): each column detrended as a
    contiguous record (:meth:`~torquemod.dsp.lstsq.LstsqFactor.solve`'s compiled route)
    and windowed, the magnitudes of only the FFT bins the checks read by Goertzel's
    recurrence (the FFT's to rounding: the same bins chosen), the checks, and the refinement
    by Brent's search of ``|X_w(f)|``; what depends only on the records' length, the rate
    and the settings is made once (:func:`_batch_plan`). The frequencies equal
    :func:`peak_frequency`'s on each column as a contiguous array
    (tests/dsp/test_spectrum_batch.py). A column whose checks fail, other windows than a
    name, and numpy builds whose BLAS the kernels cannot reach go through
    :func:`peak_frequency` itself, which raises its error.

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
    plan = _batch_plan(x.shape[0], fs_hz, *band_hz, window, detrend == "linear", zero_pad) \
        if isinstance(window, str) and type(zero_pad) is int else None
    if plan is not None:
        peaks, ok = _peaks_of_records(x, float(xtol_hz), float(min_peak_to_floor), 500,
                                      *plan)
        if ok:
            return peaks
    kw = dict(band_hz=band_hz, window=window, detrend=detrend, zero_pad=zero_pad,
              xtol_hz=xtol_hz, min_peak_to_floor=min_peak_to_floor)
    return [peak_frequency(np.ascontiguousarray(x[:, i]), fs_hz, **kw)
            for i in range(x.shape[1])]


@functools.lru_cache(maxsize=32)
def _batch_plan(n: int, fs_hz: float, lo: float, hi: float, window: str, line: bool,
                zero_pad: int) -> tuple | None:
    """What :func:`peak_frequencies`' compiled search needs besides the records, for records
    of ``n`` samples at ``fs_hz`` [Hz], the band ``lo..hi`` [Hz], a window, a detrending
    design (``line``: constant and line, else the constant) and a zero-padding factor:
    the design's factor, the window, the bins' Goertzel constants, the grid and the ranges
    of bins the checks read. None where :func:`peak_frequency` goes another way (no factor
    of the design, a band outside 0..fs/2, too short a record for the band, numpy's BLAS
    not reachable): then each column goes through it. Cached, read-only: the same for every
    cycle of a given length."""
    blas = numpyblas.addresses()
    if n < 3 or zero_pad < 1 or not 0 <= lo < hi <= fs_hz / 2 or blas is None:
        return None
    design, fac = _trend_design(n, fs_hz, line)
    if fac is None or not fac.dn.flags.c_contiguous or not design.flags.c_contiguous:
        return None
    nfft = 1 << (zero_pad * n - 1).bit_length()
    freqs, idx, wide = _grid(nfft, fs_hz, lo, hi, n)
    if idx.size < 3:
        return None
    k_lo, k_hi = _bins_read(nfft, fs_hz, lo, hi, n)
    cw, sw = _goertzel_coefficients(nfft, k_lo, k_hi)
    wide_bins = np.flatnonzero(wide)
    factor = np.asfortranarray(fac.factor)
    trig = np.vstack([cw, sw])
    bins = np.array([k_lo, idx[0], idx[-1], wide_bins[0], wide_bins[-1], blas[2], _DPOTRS],
                    dtype=np.int64)
    for a in (factor, trig, bins):
        a.setflags(write=False)
    return (fac.dn, factor, fac.scale, design, _window(window, n), trig, freqs, bins,
            2.0 * fs_hz / n, float(fs_hz))


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
