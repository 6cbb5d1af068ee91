"""Steps 2-5 of the V-Track chain: resampling, notch, high-pass and band-pass filters.

Design is kept apart from application (as in scipy.signal). Every filter is applied forward
and backward (zero phase) with Gustafsson's initial conditions, ``filtfilt(method="gust")``,
so it shifts no phase and its edge transients are small: with the default padding
``sosfiltfilt`` left ±0.1-0.3 deg of phase-difference error in the middle periods of a 6.5 s
record, Gustafsson's method 0.004 deg (FACTS.md §4).
"""

from __future__ import annotations

import functools
from fractions import Fraction

import numpy as np
from scipy import linalg, signal


def lstsq(design: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, int]:
    """Least-squares coefficients of ``y ~ design @ coef`` (``y`` one or more columns) and the
    design's numerical rank.

    Solved by a Cholesky factorisation of the column-normalised normal equations: for the
    small, well-conditioned designs of the chain (a few hundred rows, tens of columns) it is
    10x faster than ``numpy.linalg.lstsq``, whose threaded SVD costs milliseconds at this size,
    and agrees with it to 1e-14. Falls back to the SVD when the design is (nearly) rank
    deficient (condition number of the normalised normal matrix above 1e10). Two steps of
    iterative refinement bring it to the SVD's accuracy.
    """
    d = np.asarray(design, dtype=np.float64)
    scale = np.sqrt(np.einsum("ij,ij->j", d, d))
    if d.shape[1] and np.all(scale > 0):
        dn = d / scale
        gram = dn.T @ dn
        try:
            factor = linalg.cho_factor(gram, check_finite=False)
            diag = np.diag(factor[0]) ** 2
            if diag.min() > 1e-10 * diag.max():
                coef = linalg.cho_solve(factor, dn.T @ y, check_finite=False)
                for _ in range(2):  # iterative refinement: the normal equations square the
                    # condition number, and a large DC (a wheel speed of 30 rad/s beside a
                    # modulation of 1e-3 rad/s) needs the residual to full precision
                    coef += linalg.cho_solve(factor, dn.T @ (y - dn @ coef), check_finite=False)
                return (coef.T / scale).T, d.shape[1]
        except linalg.LinAlgError:
            pass
    coef, _, rank, _ = np.linalg.lstsq(d, y, rcond=None)
    return coef, int(rank)


def resample_ratio(fs_in_hz: float, fs_target_hz: float, *, max_denominator: int = 1000
                   ) -> tuple[int, int]:
    """Integers (up, down) with ``fs_in*up/down`` closest to ``fs_target`` (16 670 Hz to
    53.344 Hz gives exactly 2/625)."""
    frac = Fraction(fs_target_hz / fs_in_hz).limit_denominator(max_denominator)
    if frac.numerator == 0:
        raise ValueError(f"cannot resample {fs_in_hz} Hz to {fs_target_hz} Hz")
    return frac.numerator, frac.denominator


@functools.lru_cache(maxsize=16)
def _resampling_fir(up: int, down: int, kaiser_beta: float) -> np.ndarray:
    """The FIR ``resample_poly`` designs (10 zero crossings either side, Kaiser window)."""
    max_rate = max(up, down)
    half_len = 10 * max_rate
    h = signal.firwin(2 * half_len + 1, 1.0 / max_rate, window=("kaiser", kaiser_beta))
    return h  # resample_poly scales a given FIR by up itself


def resample(x: np.ndarray, up: int, down: int, *, kaiser_beta: float = 5.0) -> np.ndarray:
    """Polyphase resampling by ``up/down`` along the last axis (MATLAB ``resample``
    equivalent, Kaiser beta 5; the FIR is designed once per ratio and cached).

    Each row's mean is removed before and restored after, and the ends are padded along a
    line, so a DC offset or slow trend does not ring at the edges (FACTS.md §4).
    """
    x = np.asarray(x, dtype=np.float64)
    m = x.mean(axis=-1, keepdims=True)
    y = signal.resample_poly(x - m, up, down, axis=-1,
                             window=_resampling_fir(up, down, float(kaiser_beta)),
                             padtype="line")
    return y + m


def design_notch(f0_hz: float, q: float, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Second-order IIR notch at ``f0_hz`` with quality factor ``q`` (bandwidth f0/q)."""
    return signal.iirnotch(f0_hz, q, fs=fs_hz)


def design_highpass(cutoff_hz: float, order: int, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Butterworth high-pass of ``order`` (applied twice by :func:`zero_phase`)."""
    return signal.butter(order, cutoff_hz, "highpass", fs=fs_hz)


def design_bandpass(center_hz: float, width_hz: float, order: int, fs_hz: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Butterworth band-pass from ``center-width/2`` to ``center+width/2`` [Hz]; ``order`` is
    the prototype's, the band-pass has twice that (scipy's convention)."""
    lo, hi = center_hz - width_hz / 2, center_hz + width_hz / 2
    if lo <= 0 or hi >= fs_hz / 2:
        raise ValueError(f"band-pass {lo:.3f}-{hi:.3f} Hz does not fit in 0..{fs_hz / 2} Hz")
    return signal.butter(order, [lo, hi], "bandpass", fs=fs_hz)


def zero_phase(ba: tuple[np.ndarray, np.ndarray], x: np.ndarray, *, method: str = "gust"
               ) -> np.ndarray:
    """Apply a filter forward and backward: ``method="gust"`` uses Gustafsson's initial
    conditions; ``"none"`` filters the record as it is, for records already padded (see
    :func:`model_padded`)."""
    b, a = ba
    if method == "none":
        return signal.filtfilt(b, a, x, padlen=0)
    return signal.filtfilt(b, a, x, method="gust")


def notch_frequencies(rotation_hz: float, harmonics: tuple[int, ...], fs_hz: float
                      ) -> list[float]:
    """The harmonics of a rotation frequency that lie strictly below Nyquist."""
    return [h * rotation_hz for h in harmonics if 0 < h * rotation_hz < fs_hz / 2]


def settling_samples(ba: tuple[np.ndarray, np.ndarray], *, tol: float = 1e-6,
                     max_samples: int = 1_000_000) -> int:
    """Samples after which the filter's impulse response stays below ``tol`` times its peak
    (derived from the design; used as the padding length)."""
    b, a = ba
    n = 256
    while n <= max_samples:
        h = signal.lfilter(b, a, np.r_[1.0, np.zeros(n - 1)])
        above = np.flatnonzero(np.abs(h) > tol * np.abs(h).max())
        if above[-1] < n - n // 4:
            return int(above[-1]) + 1
        n *= 2
    return max_samples


def resampler_edge_samples(up: int, down: int) -> int:
    """Output samples at each end touched by the zero padding of :func:`resample`'s FIR.

    ``resample_poly`` uses ``10*max(up, down)`` taps either side of the centre at the
    upsampled rate; one output sample is ``down`` upsampled samples, so the FIR reaches
    ``ceil(10*max(up, down)/down)`` output samples into the padding (plus one of margin).
    """
    half_taps = 10 * max(up, down)
    return int(np.ceil(half_taps / down)) + 1


def tone_design(t_s: np.ndarray, tones_hz, *, line: bool = False) -> np.ndarray:
    """Least-squares design matrix ``[1, (t - mean t), cos(2 pi f_k t), sin(2 pi f_k t), ...]``
    over sample times ``t_s`` [s] for the tones ``tones_hz`` [Hz] (the caller chooses which
    tones to keep); the column of ones comes first, then the line when ``line``."""
    t = np.asarray(t_s, dtype=np.float64)
    cols = [np.ones(t.size)] + ([t - t.mean()] if line else [])
    for f in tones_hz:
        cols += [np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)]
    return np.column_stack(cols)


def fit_line_and_tones(x: np.ndarray, fs_hz: float, tones_hz: list[float]
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares ``x ~ c0 + c1*t + sum(a_k cos + b_k sin)(2 pi f_k t)``; returns the
    coefficients and the tone frequencies kept (those below Nyquist, one resolution apart)."""
    n = x.size
    res = fs_hz / n
    kept: list[float] = []
    for f in tones_hz:
        if 0 < f < fs_hz / 2 and all(abs(f - g) > res for g in kept):
            kept.append(f)
    design = tone_design(np.arange(n) / fs_hz, kept, line=True)
    coef, _ = lstsq(design, x)
    return coef, np.asarray(kept)


def model_padded(x: np.ndarray, fs_hz: float, tones_hz: list[float], pad: int
                 ) -> tuple[np.ndarray, float, float]:
    """``x`` less its least-squares line, extended by ``pad`` samples at each end with the
    least-squares model of its stationary tones (:func:`fit_line_and_tones`).

    A zero-phase filter run over the padded record starts and ends its transients in the
    padding, where the signal continues smoothly, instead of inside the data. Returns the
    padded record, the line's mean value and slope [per s] (to restore it later).
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    coef, kept = fit_line_and_tones(x, fs_hz, tones_hz)
    t = np.arange(-pad, n + pad) / fs_hz
    t_mid = (n - 1) / (2 * fs_hz)
    out = np.zeros(n + 2 * pad)
    for k, f in enumerate(kept):
        out += coef[2 + 2 * k] * np.cos(2 * np.pi * f * t)
        out += coef[3 + 2 * k] * np.sin(2 * np.pi * f * t)
    out[pad:pad + n] = x - coef[0] - coef[1] * (t[pad:pad + n] - t_mid)
    return out, float(coef[0]), float(coef[1])


def tone_free_mean(x: np.ndarray, fs_hz: float, tones_hz: list[float]) -> float:
    """Mean of ``x`` with the given tones removed: the constant term of a least-squares fit
    ``c0 + sum(a_k cos + b_k sin)(2 pi f_k t)``.

    This is the value a notch at each tone followed by averaging converges to, without a
    notch's edge transients and also when the record is shorter than the tones' beat period
    (a notch at the platform's 1st and 2nd rotation harmonics cannot separate them within one
    revolution). Over whole periods of every tone it equals the plain mean.
    """
    x = np.asarray(x, dtype=np.float64)
    tones = [f for f in tones_hz if 0 < f < fs_hz / 2]
    if not tones:
        return float(x.mean())
    m = x.mean()
    coef, _ = lstsq(tone_design(np.arange(x.size) / fs_hz, tones), x - m)
    return float(coef[0] + m)


# --------------------------------------------------------------------------------------------
# Slow speed variation and rotation orders (issue 8: a chain that is right on a moving speed)
# --------------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=64)
def _slow_basis_cached(n: int, nw: float, k: int, degree: int) -> np.ndarray:
    from numpy.polynomial import legendre
    from scipy.signal.windows import dpss
    x = np.linspace(-1.0, 1.0, n)
    cols = [legendre.legvander(x, degree)]
    if k > 0:
        cols.append(np.atleast_2d(dpss(n, nw, k)).T)
    basis = np.column_stack(cols)
    basis.setflags(write=False)
    return basis


def slow_basis(n_samples: int, fs_hz: float, max_hz: float, *, extra: int = 2,
               degree: int = 5) -> np.ndarray:
    """Basis ``(n_samples, m)`` of slowly varying signals: Legendre polynomials up to
    ``degree`` and the first ``round(2*T*max_hz) + extra`` discrete prolate spheroidal
    (Slepian) sequences of half-bandwidth ``max_hz`` [Hz] over the record's duration T [s].

    The Slepian sequences are the signals of length T most concentrated in ``|f| < max_hz``
    (Slepian 1978), so any variation below ``max_hz`` is nearly in their span while they stay
    nearly orthogonal to a modulation above it; they are small at the record's ends, where the
    polynomials give the basis its freedom. Measured over a 6.05 s record at 53.3 Hz with
    ``max_hz = 1.2``, ``extra = 2``, ``degree = 5``: a unit sinusoid anywhere in 0.2-1.0 Hz
    leaks < 1e-5 into a jointly fitted 2 Hz modulation (2e-4 at 1.2 Hz), and the joint fit
    costs the modulation 23 % of variance (:meth:`torquemod.chain.SpeedModel.variance_factor`).
    ``max_hz = 0`` gives the polynomials alone.
    """
    duration = n_samples / fs_hz
    nw = duration * max_hz
    k = 0 if nw < 0.5 else max(0, min(n_samples // 2, round(2 * nw) + extra))
    degree = max(0, min(degree, n_samples // 4))
    return _slow_basis_cached(int(n_samples), float(nw), int(k), int(degree))


def unwrapped_angle(speed_rad_s: np.ndarray, fs_hz: float) -> np.ndarray:
    """Angle [rad] turned since the first sample: the trapezoidal integral of an angular speed
    [rad/s] sampled at ``fs_hz`` (used to follow rotation orders whose frequency moves)."""
    w = np.asarray(speed_rad_s, dtype=np.float64)
    out = np.empty_like(w)
    out[0] = 0.0
    np.cumsum(0.5 * (w[1:] + w[:-1]) / fs_hz, out=out[1:])
    return out


def order_design(angle_rad: np.ndarray, orders) -> np.ndarray:
    """Columns ``cos(k*theta), sin(k*theta)`` for each rotation order k at the angle
    ``theta`` [rad]: an encoder's eccentricity error follows the angle, so when the speed moves
    its tones move with it (order tracking); fixed-frequency tones would leave sidebands."""
    theta = np.asarray(angle_rad, dtype=np.float64)
    cols = []
    for k in orders:
        cols += [np.cos(k * theta), np.sin(k * theta)]
    return np.column_stack(cols) if cols else np.empty((theta.size, 0))
