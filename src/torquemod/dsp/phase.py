"""Step 7 of the V-Track chain: the phase lag of the wheel angular velocity behind the torque.

Two estimators:

* :func:`peak_valley_phase`, the paper's: paired peaks and valleys of the band-passed signals,
  each located to a fraction of a sample by a parabola through the three highest samples,
  ``phi_pair = 360*f_mod*dt_pair`` (Eq. 2 of the V-Track paper), averaged.
* :func:`sinefit_phase`: a linear least-squares fit of ``c*cos(wt) + s*sin(wt)`` plus nuisance
  terms at the common frequency over whole modulation periods, time referenced to the window
  centre (IEEE Std 1057 three-parameter fit, extended). It reaches the Cramér-Rao bound
  ``var(dphi) = (1/N)(1/eta1 + 1/eta2)`` (Rife and Boorstyn 1974, IEEE Trans. Inf. Theory 20(5)).

Sign convention of the project: the phase is positive when the wheel speed lags the torque.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import signal

from torquemod.dsp.extrema import (  # noqa: F401  (re-exported: the paper's estimator)
    PeakValleyResult,
    _numpy_sum,
    extrema_times,
    parabolic_vertex,
    peak_valley_phase,
)
from torquemod.dsp.lstsq import LstsqFactor, lapack_addresses, lstsq, lstsq_compiled
from torquemod.dsp.tonemodel import fill_tones_together, tone_design
from torquemod.errors import ProcessingError

#: Degrees per radian, ``180/pi``: numpy's ``degrees`` multiplies by this double, so a
#: product with it is ``np.degrees``'s number (tests/dsp/test_phase.py).
DEG_PER_RAD = 180.0 / math.pi


@dataclass(frozen=True)
class SineFitResult:
    """The phase from a least-squares sine fit at the modulation frequency.

    Attributes
    ----------
    phase_deg : float
        Lag of the wheel speed behind the torque [deg].
    phase_stderr_deg : float
        Its standard error [deg] (Cramér-Rao bound with the local noise density).
    torque_amplitude : float
        Fitted torque amplitude [N*m] (unit of the torque signal).
    wheel_amplitude : float
        Fitted wheel-speed amplitude [rad/s] (unit of the speed signal).
    torque_phase_rad : float
        Phase of the torque's fitted cosine [rad].
    wheel_phase_rad : float
        Phase of the wheel speed's fitted cosine [rad].
    n_samples : int
        Samples fitted.
    window_s : tuple of float
        Start and end of the fitted window [s].
    """

    phase_deg: float
    phase_stderr_deg: float
    torque_amplitude: float
    wheel_amplitude: float
    torque_phase_rad: float
    wheel_phase_rad: float
    n_samples: int
    window_s: tuple[float, float]


def whole_period_window(n_samples: int, fs_hz: float, f_hz: float, center_s: float | None = None
                        ) -> tuple[int, int]:
    """Index range of the largest whole number of periods of ``f_hz`` that fits in a record.

    Parameters
    ----------
    n_samples : int
        Record length [samples].
    fs_hz : float
        Sampling rate [Hz].
    f_hz : float
        Frequency whose periods are counted [Hz].
    center_s : float, optional
        Centre of the window [s from the first sample], as far as the record allows;
        default the record's middle.

    Returns
    -------
    tuple of (int, int)
        ``[start, stop)`` [samples].

    Raises
    ------
    ProcessingError
        The record is shorter than one period.

    Examples
    --------
    >>> whole_period_window(1050, 100.0, 1.0)
    (25, 1025)
    """
    duration = n_samples / fs_hz
    n_per = math.floor(duration * f_hz + 1e-9)
    if n_per < 1:
        raise ProcessingError("record shorter than one modulation period")
    length = round(n_per * fs_hz / f_hz)
    length = min(length, n_samples)
    c = n_samples / 2 if center_s is None else center_s * fs_hz
    start = round(c - length / 2)
    start = min(max(start, 0), n_samples - length)
    return start, start + length


@functools.lru_cache(maxsize=32)
def _window_times(n: int, fs_hz: float, trend: bool) -> tuple[np.ndarray, np.ndarray]:
    """The window's sample times t [s] from its centre and the columns that depend on them
    alone (ones, and the line when ``trend``), read-only: the same for every cycle of a
    given length, whatever its modulation frequency."""
    t = (np.arange(n) - (n - 1) / 2) / fs_hz
    rest = tone_design(t, (), line=trend)
    for a in (t, rest):
        a.setflags(write=False)
    return t, rest


@functools.lru_cache(maxsize=32)
def _fixed_columns(n: int, fs_hz: float, f_hz: float, trend: bool) -> np.ndarray:
    """The design's columns that depend only on the window: cos and sin at ``f_hz``, ones,
    and the line when ``trend`` (read-only; t from the window centre)."""
    t, rest = _window_times(n, fs_hz, trend)
    wt = 2 * np.pi * f_hz * t
    cols = np.empty((n, 2 + rest.shape[1]))
    cols[:, 0] = np.cos(wt)  # (each on its own contiguous array, as numpy's column_stack
    cols[:, 1] = np.sin(wt)  # of them had it)
    cols[:, 2:] = rest
    cols.setflags(write=False)
    return cols


@njit(cache=True, nogil=True)
def _fill_tones(out: np.ndarray, col0: int, fs_hz: float, tones_hz: np.ndarray) -> None:
    """cos and sin of ``2*pi*f*t`` for each tone into ``out[:, col0 + 2m]`` and ``+ 1``,
    t = (i - (n-1)/2)/fs: exact values every 64 samples, a rotation by one sample between
    (the rounding error grows by ~1e-16 a step: < 1e-14 of the amplitude)."""
    n = out.shape[0]
    for m in range(tones_hz.size):
        om = 2.0 * math.pi * tones_hz[m]
        cd, sd = math.cos(om / fs_hz), math.sin(om / fs_hz)
        for b in range(0, n, 64):
            tb = (b - (n - 1) / 2) / fs_hz
            c, s = math.cos(om * tb), math.sin(om * tb)
            for i in range(b, min(n, b + 64)):
                out[i, col0 + 2 * m] = c
                out[i, col0 + 2 * m + 1] = s
                c, s = c * cd - s * sd, s * cd + c * sd


@njit(cache=True, nogil=True)
def _fill_tones_together(out: np.ndarray, col0: int, fs_hz: float, tones_hz: np.ndarray
                         ) -> None:
    """:func:`_fill_tones` with up to four tones advancing together
    (:func:`~torquemod.dsp.tonemodel.fill_tones_together`, the same bits): t [s] from the
    window's centre."""
    fill_tones_together(out, col0, 2.0 * math.pi * tones_hz, -((out.shape[0] - 1) / 2), fs_hz)


def _design(n: int, fs_hz: float, f_hz: float, nuisance_hz: tuple[float, ...], trend: bool
            ) -> np.ndarray:
    """Columns cos and sin at ``f_hz`` first (the fitted signal), then the nuisance terms
    (ones, the line when ``trend``, cos and sin of each nuisance tone), over the window's n
    samples at ``fs_hz`` with t from its centre."""
    fixed = _fixed_columns(n, float(fs_hz), float(f_hz), bool(trend))
    out = np.empty((n, fixed.shape[1] + 2 * len(nuisance_hz)), order="F")
    out[:, :fixed.shape[1]] = fixed
    if nuisance_hz:
        _fill_tones(out, fixed.shape[1], float(fs_hz), np.asarray(nuisance_hz, dtype=float))
    return out


def sinefit_phase(torque: np.ndarray, wheel: np.ndarray, fs_hz: float, f_mod_hz: float, *,
                  nuisance_hz: tuple[float, ...] = (), trend: bool = True,
                  center_s: float | None = None, noise_from: tuple[np.ndarray, np.ndarray]
                  | None = None) -> SineFitResult:
    """Phase lag of the wheel speed behind the torque by a least-squares sine fit at the
    common frequency over whole modulation periods.

    Model per channel: ``c*cos(w t) + s*sin(w t) + d (+ e*t) + sum(nuisance tones)`` with t
    from the window centre; phase ``phi = atan2(-s, c)``; lag ``phi_T - phi_W`` wrapped to
    (-180, 180] deg. Nuisance tones closer than one frequency resolution to ``f_mod_hz``
    are dropped (they would alias the signal).

    Parameters
    ----------
    torque, wheel : ndarray
        Torque [N*m] and wheel angular velocity [rad/s] (any consistent units), sampled
        together.
    fs_hz : float
        Sampling rate [Hz].
    f_mod_hz : float
        Modulation frequency [Hz].
    nuisance_hz : tuple of float
        Other tones fitted alongside [Hz] (e.g. wheel rotation, mains hum).
    trend : bool, default True
        Fit a linear trend as well as an offset.
    center_s : float, optional
        Centre of the whole-period window [s] (:func:`whole_period_window`).
    noise_from : tuple of (ndarray, ndarray), optional
        Other versions of the two channels (e.g. before a band-pass) whose fit residual
        gives the noise density instead.

    Returns
    -------
    SineFitResult
        Lag [deg] and its standard error [deg], both amplitudes (input units) and phases
        [rad], the samples used and the window [s].

    Raises
    ------
    ProcessingError
        Record shorter than a period, rank-deficient design or zero amplitude.

    Notes
    -----
    The standard error is ``sqrt(S1/(A1^2 T) + S2/(A2^2 T))`` [rad], the Cramér-Rao bound
    of [1]_ for white noise of one-sided density S_i near ``f_mod_hz``, taken from each
    channel's fit residual (:func:`local_noise_psd`), so that unmodelled lines far from
    f_mod (vibration) do not inflate it. The fit is the IEEE Std 1057 three-parameter sine
    fit [2]_ extended with nuisance terms.

    References
    ----------
    .. [1] D.C. Rife and R.R. Boorstyn, "Single-tone parameter estimation from discrete-time
       observations", IEEE Trans. Inf. Theory 20(5) (1974) 591-598.
    .. [2] IEEE Std 1057-2017, "IEEE Standard for Digitizing Waveform Recorders".
    """
    torque = np.asarray(torque, dtype=np.float64)
    wheel = np.asarray(wheel, dtype=np.float64)
    start, stop = whole_period_window(torque.size, fs_hz, f_mod_hz, center_s)
    n = stop - start
    resolution = fs_hz / n
    keep = tuple(f for f in nuisance_hz if abs(f - f_mod_hz) > resolution)
    records = [torque, wheel]
    if noise_from is not None:  # the four records in one solve
        records += [np.asarray(noise_from[0]), np.asarray(noise_from[1])]
    status, compiled = 5, False
    if n >= 8 and all(r.dtype == np.float64 and r.ndim == 1 and r.size >= stop
                      for r in records):  # the design, the records' window and the fit in
        # one call (the arrays of the route below, the same numbers)
        fixed = _fixed_columns(n, float(fs_hz), float(f_mod_hz), bool(trend))
        compiled = True
        status, coef, psds = _sine_fit_records(
            fixed, np.array(keep, dtype=np.float64), *records[:2], *records[-2:],
            len(records), start, float(fs_hz), float(f_mod_hz), *_dft_table(n),
            *lapack_addresses())
    if status != 0:  # numpy's route: a design that needs the SVD, or too short a window
        design = _design(n, fs_hz, f_mod_hz, keep, trend)
        y = np.column_stack([r[start:stop] for r in records])
        if not compiled and n >= 8 and y.dtype == np.float64:
            status, coef, psds = _sine_fit(np.ascontiguousarray(design), y, float(fs_hz),
                                           float(f_mod_hz), *_dft_table(n),
                                           *lapack_addresses())
        if status != 0:
            coef, psds = _sine_fit_numpy(design, y, fs_hz, f_mod_hz)
    t_win = n / fs_hz
    (c_t, c_w), (s_t, s_w) = coef[:2, :2].tolist()  # Python floats: the same arithmetic
    var_phi, amps = 0.0, []
    for c, s, psd in ((c_t, s_t, float(psds[0])), (c_w, s_w, float(psds[1]))):
        a2 = c * c + s * s
        if a2 == 0:
            raise ProcessingError("zero amplitude at the modulation frequency")
        # var(phi_i) = S_i/(A_i^2 T) with S_i the one-sided noise density at f_mod
        # (Rife and Boorstyn 1974)
        var_phi += psd / (a2 * t_win)
        amps.append(math.sqrt(a2))  # (sqrt is correctly rounded: numpy's numbers)
    # both phases atan2(-s, c) in one call (numpy's arctan2 element by element)
    ph_t, ph_w = np.arctan2(np.array([-s_t, -s_w]), np.array([c_t, c_w])).tolist()
    return SineFitResult(wrapped_angle(ph_t - ph_w) * DEG_PER_RAD,
                         math.sqrt(var_phi) * DEG_PER_RAD, amps[0], amps[1], ph_t, ph_w, n,
                         (start / fs_hz, stop / fs_hz))


def wrapped_angle(angle_rad: float) -> float:
    """An angle wrapped to (-pi, pi] [rad]: ``np.angle(np.exp(1j*angle_rad))``, the angle
    of ``(cos, sin)`` by numpy's ``arctan2``, with one ufunc call instead of three.

    Parameters
    ----------
    angle_rad : float
        Any angle [rad].

    Returns
    -------
    float
        The same direction in (-pi, pi] [rad] (numpy's number: ``exp(1j*a)`` is
        ``(cos a, sin a)`` exactly, ``exp(0) = 1``).

    Examples
    --------
    >>> round(wrapped_angle(3 * 3.141592653589793 / 2), 12)
    -1.570796326795
    """
    a = float(angle_rad)
    return float(np.arctan2(math.sin(a), math.cos(a)))


def _sine_fit_numpy(design: np.ndarray, y: np.ndarray, fs_hz: float, f_mod_hz: float
                    ) -> tuple[np.ndarray, list[float]]:
    """:func:`sinefit_phase`'s fit step by step in numpy: the signals' coefficients
    ``(m, 2)`` and the residuals' noise densities near ``f_mod_hz`` [unit^2/Hz]
    (:func:`local_noise_psd`), the residual of ``y``'s last two columns (``y`` holds the
    torque and wheel speed, then optionally the records whose residual gives the noise)."""
    fac = LstsqFactor.of(design)  # one factor for both fits below (lstsq's own numbers)
    if fac is None and lstsq(design, y[:, 0])[1] < design.shape[1]:
        raise ProcessingError("sine-fit design matrix is rank deficient (nuisance tones "
                              "coincide)")
    c_all = fac.solve(y) if fac is not None else lstsq(design, y)[0]
    resid = y[:, -2:] - design @ c_all[:, -2:]
    return c_all[:, :2], [local_noise_psd(resid[:, ch], fs_hz, f_mod_hz) for ch in range(2)]


@functools.lru_cache(maxsize=16)
def _dft_table(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``cos`` and ``sin`` of ``2*pi*j/n`` for j = 0..n-1 (the DFT's twiddles, exact index
    arithmetic ``k*t mod n`` picks them), the periodic Hann window and its sum of squares
    (:func:`_hann_periodic`); cached read-only, one per window length."""
    angle = 2.0 * np.pi * np.arange(n) / n
    w, ss = _hann_periodic(n)
    out = (np.cos(angle), np.sin(angle), w)
    for a in out:
        a.setflags(write=False)
    return (*out, ss)


@njit(cache=True, nogil=True)
def _sine_fit_records(fixed: np.ndarray, tones_hz: np.ndarray, r0: np.ndarray, r1: np.ndarray,
                      r2: np.ndarray, r3: np.ndarray, n_records: int, start: int,
                      fs_hz: float, f_hz: float, cos_t: np.ndarray, sin_t: np.ndarray,
                      w: np.ndarray, ss: float, potrf: int, potrs: int
                      ) -> tuple[int, np.ndarray, np.ndarray]:
    """:func:`_sine_fit` of the window ``start:start + n`` of the records ``r0 .. r3`` (the
    first ``n_records`` of them; ``n`` the rows of ``fixed``) on the design of
    :func:`_design` (its columns ``fixed`` from :func:`_fixed_columns`, then the tones
    ``tones_hz`` by :func:`_fill_tones_together`), both built here in C order with the same
    values."""
    n, n_fixed = fixed.shape
    design = np.empty((n, n_fixed + 2 * tones_hz.size))
    design[:, :n_fixed] = fixed
    if tones_hz.size:
        _fill_tones_together(design, n_fixed, fs_hz, tones_hz)
    y = np.empty((n, n_records))
    for j in range(n_records):
        r = r0 if j == 0 else r1 if j == 1 else r2 if j == 2 else r3
        for i in range(n):
            y[i, j] = r[start + i]
    return _sine_fit(design, y, fs_hz, f_hz, cos_t, sin_t, w, ss, potrf, potrs)


@njit(cache=True, nogil=True)
def _sine_fit(design: np.ndarray, y: np.ndarray, fs_hz: float, f_hz: float, cos_t: np.ndarray,
              sin_t: np.ndarray, w: np.ndarray, ss: float, potrf: int, potrs: int
              ) -> tuple[int, np.ndarray, np.ndarray]:
    """:func:`_sine_fit_numpy` in one call: ``(status, coef, psds)``, status 0, or not 0
    where that route must decide (a design :func:`~torquemod.dsp.lstsq.lstsq_compiled`
    leaves to the SVD, fewer than two bins in the noise band). The least squares by
    :func:`~torquemod.dsp.lstsq.lstsq_compiled`; each density as
    :func:`local_noise_psd` forms it with the periodogram's bins in the band summed
    directly over the samples (:func:`_band_density`) instead of by the FFT (the same
    values to rounding)."""
    coef, status = lstsq_compiled(design, y, potrf, potrs)
    if status != 0:
        return status, np.empty((0, 2)), np.empty(2)
    k0 = y.shape[1] - 2
    fit = np.dot(design, np.ascontiguousarray(coef[:, k0:]))
    psds = np.empty(2)
    for ch in range(2):
        psds[ch] = _band_density(y[:, k0 + ch] - fit[:, ch], fs_hz, f_hz, cos_t, sin_t, w,
                                 ss, 0.75)
        if not psds[ch] == psds[ch]:
            return 4, coef, psds
    return 0, np.ascontiguousarray(coef[:, :2]), psds


@njit(cache=True, nogil=True)
def _band_density(x: np.ndarray, fs_hz: float, f_hz: float, cos_t: np.ndarray,
                  sin_t: np.ndarray, w: np.ndarray, ss: float, half_width_hz: float) -> float:
    """:func:`local_noise_psd` of ``x`` [unit^2/Hz] with the Hann-windowed periodogram's
    bins within ``half_width_hz`` of ``f_hz`` (the two nearest left out) evaluated as DFT
    sums over the samples: the same bins, frequencies and scaling as :func:`_density` and
    the mean as numpy forms it; NaN where the band holds fewer than two bins."""
    n = x.size
    mean = _numpy_sum(x, 0, n) / n
    xw = (x - mean) * w
    val = 1.0 / (n * (1.0 / fs_hz))  # np.fft.rfftfreq's spacing
    ks = np.empty(n // 2 + 1, dtype=np.int64)
    count = 0
    for k in range(n // 2 + 1):
        off = abs(k * val - f_hz)
        if off <= half_width_hz and off > 1.5 * (val - 0.0):
            ks[count] = k
            count += 1
    res, ims = np.empty(count), np.empty(count)
    for g in range(0, count, 4):  # four bins' sums at a time (independent: they overlap)
        _dft_bins(xw, cos_t, sin_t, ks, g, min(g + 4, count), res, ims)
    vals = np.empty(count)
    for c in range(count):
        p = (res[c] * res[c] + ims[c] * ims[c]) / (fs_hz * ss)
        if 1 <= ks[c] < n // 2 + (n % 2):
            p *= 2.0
        vals[c] = p
    if count < 2:
        return math.nan
    return _numpy_sum(vals, 0, count) / count


@njit(cache=True, nogil=True)
def _dft_bins(xw: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray, ks: np.ndarray, lo: int,
              hi: int, res: np.ndarray, ims: np.ndarray) -> None:
    """The DFT sums ``sum_t xw[t] exp(-2j pi k t / n)`` of the bins ``ks[lo:hi]`` (1 to 4)
    into ``res``, ``ims``: ``re += x cos``, ``im -= x sin`` over the samples in order with
    the table index ``k t mod n``, as one bin at a time, the bins advancing together."""
    n = xw.size
    last = hi - 1
    k0, k1, k2, k3 = ks[lo], ks[min(lo + 1, last)], ks[min(lo + 2, last)], ks[last]
    r0 = r1 = r2 = r3 = 0.0
    i0 = i1 = i2 = i3 = 0.0
    j0 = j1 = j2 = j3 = 0
    for t in range(n):
        x = xw[t]
        r0 += x * cos_t[j0]
        i0 -= x * sin_t[j0]
        r1 += x * cos_t[j1]
        i1 -= x * sin_t[j1]
        r2 += x * cos_t[j2]
        i2 -= x * sin_t[j2]
        r3 += x * cos_t[j3]
        i3 -= x * sin_t[j3]
        j0 = j0 + k0 - n if j0 + k0 >= n else j0 + k0
        j1 = j1 + k1 - n if j1 + k1 >= n else j1 + k1
        j2 = j2 + k2 - n if j2 + k2 >= n else j2 + k2
        j3 = j3 + k3 - n if j3 + k3 >= n else j3 + k3
    re_, im_ = (r0, r1, r2, r3), (i0, i1, i2, i3)
    for q in range(hi - lo):
        res[lo + q] = re_[q]
        ims[lo + q] = im_[q]


def phase_crb_deg(amplitude_1: float, amplitude_2: float, noise_std_1: float, noise_std_2: float,
                  n_samples: int) -> float:
    """Cramér-Rao bound on the standard deviation of the phase difference between two
    sinusoids of a common known frequency in white noise:
    ``var = (1/N)(1/eta1 + 1/eta2)``, ``eta_i = A_i^2/(2 sigma_i^2)``.

    Parameters
    ----------
    amplitude_1, amplitude_2 : float
        Sinusoid amplitudes A_i [unit of each signal].
    noise_std_1, noise_std_2 : float
        White-noise standard deviations sigma_i [same units as the amplitudes].
    n_samples : int
        Samples N.

    Returns
    -------
    float
        Standard deviation bound [deg].

    References
    ----------
    .. [1] D.C. Rife and R.R. Boorstyn, "Single-tone parameter estimation from discrete-time
       observations", IEEE Trans. Inf. Theory 20(5) (1974) 591-598.

    Examples
    --------
    >>> import math
    >>> s = phase_crb_deg(1.0, 1.0, math.sqrt(0.5), math.sqrt(0.5), 2)
    >>> round(s, 9) == round(math.degrees(1.0), 9)
    True
    """
    eta1 = amplitude_1 ** 2 / (2 * noise_std_1 ** 2)
    eta2 = amplitude_2 ** 2 / (2 * noise_std_2 ** 2)
    return float(np.degrees(np.sqrt((1 / eta1 + 1 / eta2) / n_samples)))


@functools.lru_cache(maxsize=16)
def _hann_periodic(n: int) -> tuple[np.ndarray, float]:
    """The periodic Hann window of n samples (``scipy.signal.get_window('hann', n)``) and the
    sum of its squares."""
    w = signal.get_window("hann", n)
    return w, float(w @ w)


def periodogram_density(x: np.ndarray, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """One-sided Hann-windowed periodogram of a record (mean removed).

    The same numbers as ``scipy.signal.periodogram(x - mean, fs, window='hann',
    detrend=False, scaling='density')`` without its general cross-spectral machinery, which
    dominates on the on-board estimator's one-second windows.

    Parameters
    ----------
    x : ndarray
        The record, any unit.
    fs_hz : float
        Sample rate [Hz].

    Returns
    -------
    f : ndarray
        Frequencies [Hz].
    p : ndarray
        Density [unit^2/Hz].

    Examples
    --------
    >>> import numpy as np
    >>> from scipy import signal
    >>> x = np.random.default_rng(1).normal(size=64)
    >>> f, p = periodogram_density(x, 10.0)
    >>> bool(np.allclose(p, signal.periodogram(x - x.mean(), 10.0, window="hann",
    ...                                        detrend=False)[1]))
    True
    """
    x = np.asarray(x, dtype=np.float64)
    return np.fft.rfftfreq(x.size, 1.0 / fs_hz), _density(x, fs_hz)


def _density(x: np.ndarray, fs_hz: float) -> np.ndarray:
    """The density of :func:`periodogram_density` [unit^2/Hz] of a float64 record."""
    n = x.size
    w, ss = _hann_periodic(n)
    spec = np.fft.rfft((x - float(x.sum()) / n) * w)  # (np.mean's numbers)
    p = (spec.real ** 2 + spec.imag ** 2) / (fs_hz * ss)
    p[1:n // 2 + (n % 2)] *= 2.0  # one-sided: every bin but DC and (n even) Nyquist
    return p


@functools.lru_cache(maxsize=16)
def _frequencies(n: int, fs_hz: float) -> np.ndarray:
    """``np.fft.rfftfreq(n, 1/fs_hz)`` [Hz], cached read-only (one per record length)."""
    f = np.fft.rfftfreq(n, 1.0 / fs_hz)
    f.setflags(write=False)
    return f


def local_noise_psd(residual: np.ndarray, fs_hz: float, f_hz: float, *,
                    half_width_hz: float = 0.75) -> float:
    """One-sided noise power spectral density of a residual near a frequency.

    The mean of its Hann-windowed periodogram over ``f_hz +- half_width_hz``, leaving out
    the two bins nearest ``f_hz`` (where a fitted line's remainder would sit); the mean over
    all bins but DC when that band holds fewer than two bins (windows shorter than ~3 s).

    Parameters
    ----------
    residual : ndarray
        The fit's residual, any unit.
    fs_hz : float
        Sample rate [Hz].
    f_hz : float
        The frequency [Hz].
    half_width_hz : float
        Half-width of the band averaged [Hz]. Default 0.75.

    Returns
    -------
    float
        Density [unit^2/Hz].
    """
    x = np.asarray(residual, dtype=np.float64)
    f, p = _frequencies(x.size, float(fs_hz)), _density(x, fs_hz)  # periodogram_density's
    df = f[1] - f[0]
    off = np.abs(f - f_hz)
    vals = p[(off <= half_width_hz) & (off > 1.5 * df)]
    if vals.size < 2:
        vals = p[1:]
    return float(vals.sum()) / vals.size  # (np.mean's numbers)
