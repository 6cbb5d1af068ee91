"""Step 1 of the V-Track chain: the frequency of the strongest spectral line in a band.

A bare FFT bin of a 6.5 s record is 0.15 Hz wide. Here the mean (and linear trend) is removed,
a window is applied, the coarse maximum is taken from a zero-padded FFT and then refined by
maximising the magnitude of the windowed discrete-time Fourier transform (DTFT) itself with a
bounded scalar search, so the result is the exact maximiser of ``|X_w(f)|`` to ``xtol_hz``.
"""

from __future__ import annotations

import numpy as np
from scipy import optimize, signal

from ..errors import ProcessingError


def windowed_dtft(x: np.ndarray, fs_hz: float, f_hz: float, window: np.ndarray) -> complex:
    """``X_w(f) = sum_n w[n] x[n] exp(-2j*pi*f*n/fs)`` at one frequency ``f_hz`` [Hz]."""
    n = np.arange(x.size)
    return complex(np.dot(window * x, np.exp(-2j * np.pi * f_hz / fs_hz * n)))


def peak_frequency(x: np.ndarray, fs_hz: float, *, band_hz: tuple[float, float] = (1.5, 2.5),
                   window: str = "hann", detrend: str = "linear", zero_pad: int = 8,
                   xtol_hz: float = 1e-6, remove_tones_hz: tuple[float, ...] = ()) -> float:
    """Frequency [Hz] of the largest spectral peak of ``x`` inside ``band_hz``.

    ``detrend`` is ``"linear"`` or ``"constant"`` (mean removal, as the paper's FFT step
    requires at least). ``window`` is any :func:`scipy.signal.get_window` name. The coarse grid
    is ``fs/(zero_pad*N)``; the refinement maximises ``|X_w(f)|`` within one coarse cell either
    side. ``remove_tones_hz`` are known lines outside the band (e.g. encoder eccentricity
    at the rotation harmonics) removed by least squares first, so that their window leakage,
    100 times the modulation in size, cannot pull the peak. Raises :class:`ProcessingError`
    when the band holds no interior maximum (no line).
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    lo, hi = band_hz
    if not 0 <= lo < hi <= fs_hz / 2:
        raise ValueError(f"band {band_hz} Hz must lie within 0..fs/2 = {fs_hz / 2} Hz")
    xd = signal.detrend(x, type=detrend)
    tones = [f for f in remove_tones_hz if not lo - 0.5 <= f <= hi + 0.5 and 0 < f < fs_hz / 2]
    if tones:
        t = np.arange(n) / fs_hz
        cols = np.column_stack([g(2 * np.pi * f * t) for f in tones for g in (np.cos, np.sin)])
        coef, *_ = np.linalg.lstsq(cols, xd, rcond=None)
        xd = xd - cols @ coef
    w = signal.get_window(window, n, fftbins=False)
    nfft = int(2 ** np.ceil(np.log2(zero_pad * n)))
    spec = np.abs(np.fft.rfft(xd * w, nfft))
    freqs = np.fft.rfftfreq(nfft, 1.0 / fs_hz)
    idx = np.flatnonzero((freqs >= lo) & (freqs <= hi))
    if idx.size < 3:
        raise ProcessingError(f"record of {n / fs_hz:.3g} s is too short to resolve the band "
                              f"{lo}-{hi} Hz")
    k = int(idx[np.argmax(spec[idx])])
    if k in (idx[0], idx[-1]) or spec[k] <= 0:
        raise ProcessingError(f"no spectral peak inside {lo}-{hi} Hz (the largest value is at "
                              f"the band edge, {freqs[k]:.4f} Hz)")
    df = freqs[1] - freqs[0]

    def neg_mag(f: float) -> float:
        return -abs(windowed_dtft(xd, fs_hz, f, w))

    res = optimize.minimize_scalar(neg_mag, bounds=(freqs[k] - df, freqs[k] + df),
                                   method="bounded", options={"xatol": xtol_hz})
    return float(res.x)
