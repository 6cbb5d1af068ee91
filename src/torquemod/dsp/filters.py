"""Steps 2-5 of the V-Track chain: resampling, notch, high-pass and band-pass filters.

Design is kept apart from application (as in scipy.signal). Every filter is applied forward
and backward (zero phase) with Gustafsson's initial conditions, ``filtfilt(method="gust")``,
so it shifts no phase and its edge transients are small: with the default padding
``sosfiltfilt`` left ±0.1-0.3 deg of phase-difference error in the middle periods of a 6.5 s
record, Gustafsson's method 0.004 deg (measured with scipy 1.17).
"""

from __future__ import annotations

import cmath
import functools
import math
from fractions import Fraction

import numba
import numpy as np
from scipy import signal

from torquemod.dsp.basis import (  # noqa: F401  (re-exported: filters is the module callers use)
    _dpss,
    _order_columns,
    _slow_basis_cached,
    order_design,
    slow_basis,
    unwrapped_angle,
)
from torquemod.dsp.decimate import (  # noqa: F401  (re-exported: filters is the module callers use)
    _fir_decimate,
    _fir_decimate_row,
    _resampling_fir,
    _stage2_phases,
    _two_stage_rows,
    _upfirdn_centred_row,
    decimate_two_stage,
    stage1_fir,
    two_stage_plan,
)
from torquemod.dsp.lstsq import LstsqFactor, _cho_solve, lstsq  # noqa: F401  (re-exported)


def resample_ratio(fs_in_hz: float, fs_target_hz: float, *, max_denominator: int = 1000
                   ) -> tuple[int, int]:
    """Integers (up, down) with ``fs_in*up/down`` closest to ``fs_target``.

    Cached: the same rates for every cycle of a run, and ``Fraction.limit_denominator``
    costs ~50 us.

    Parameters
    ----------
    fs_in_hz : float
        Input rate [Hz].
    fs_target_hz : float
        Wanted rate [Hz].
    max_denominator : int
        Largest ``down`` [-]. Default 1000.

    Returns
    -------
    tuple of int
        (up, down).

    Examples
    --------
    >>> resample_ratio(16670.0, 53.344)
    (2, 625)
    """
    return _resample_ratio(float(fs_in_hz), float(fs_target_hz), int(max_denominator))


@functools.lru_cache(maxsize=64)
def _resample_ratio(fs_in_hz: float, fs_target_hz: float, max_denominator: int
                    ) -> tuple[int, int]:
    frac = Fraction(fs_target_hz / fs_in_hz).limit_denominator(max_denominator)
    if frac.numerator == 0:
        raise ValueError(f"cannot resample {fs_in_hz} Hz to {fs_target_hz} Hz")
    return frac.numerator, frac.denominator


RESAMPLE_METHODS = ("polyphase", "two_stage")


def resample(x: np.ndarray, up: int, down: int, *, kaiser_beta: float = 5.0,
             method: str = "polyphase", padtype: str = "line") -> np.ndarray:
    """Polyphase resampling by ``up/down`` along the last axis.

    MATLAB ``resample`` equivalent, Kaiser beta 5; the FIR is designed once per ratio and
    cached. Each row's mean is removed before and restored after, and with
    ``padtype="line"`` the ends are padded along a line, so a DC offset or slow trend does
    not ring at the edges [1]_. ``padtype="constant"`` changes only the
    :func:`resampler_edge_samples` outputs at each end, which the chain cuts off, and saves
    the padding's cost. ``method="two_stage"`` gives the same output samples at the same
    times through a cheaper route (:func:`decimate_two_stage`: an integer decimation by a
    long Kaiser FIR first, then ``resample_poly``'s arithmetic for the rest of the ratio); it
    falls back to ``"polyphase"`` when ``down`` has no suitable integer factor.

    Parameters
    ----------
    x : ndarray
        Signal(s), any unit, resampled along the last axis.
    up : int
        Upsampling factor [-].
    down : int
        Downsampling factor [-].
    kaiser_beta : float
        Kaiser window beta of the FIR [-]. Default 5 (MATLAB's ``resample``).
    method : {"polyphase", "two_stage"}
        The route; both give the same output samples. Default "polyphase".
    padtype : {"line", "constant"}
        Pad the ends along a line, or with zeros after the mean removal. Default "line".

    Returns
    -------
    ndarray
        The resampled signal(s), same unit.

    Raises
    ------
    ValueError
        An unknown ``method`` or ``padtype``.

    References
    ----------
    .. [1] F. Gustafsson, "Determining the initial states in forward-backward filtering",
       IEEE Trans. Signal Process. 44(4) (1996) 988-992.
    """
    if method not in RESAMPLE_METHODS:
        raise ValueError(f"unknown resampling method {method!r}; use one of {RESAMPLE_METHODS}")
    if padtype not in ("line", "constant"):
        raise ValueError(f"padtype must be 'line' or 'constant', got {padtype!r}")
    x = np.asarray(x, dtype=np.float64)
    m = x.mean(axis=-1, keepdims=True)
    if method == "two_stage" and padtype == "constant" and two_stage_plan(up, down):
        rows = x.reshape(-1, x.shape[-1])
        y = _two_stage_rows(list(rows), m.reshape(-1), up, down, kaiser_beta)
        return y.reshape(*x.shape[:-1], y.shape[-1])
    return _resample_centred(x - m, m, up, down, kaiser_beta, method, padtype)


def resample_rows(rows, up: int, down: int, *, kaiser_beta: float = 5.0,
                  method: str = "polyphase", padtype: str = "line", return_means: bool = False
                  ):
    """:func:`resample` of ``np.vstack(rows)`` without stacking them first.

    Each row's mean is removed while it is copied into the stacked array, which saves one
    pass over the data. The means are the same numbers ``resample`` removes (numpy sums each
    row the same way), so the output is bit-identical.

    Parameters
    ----------
    rows : sequence of ndarray
        Records of equal length, any unit.
    up : int
        Upsampling factor [-].
    down : int
        Downsampling factor [-].
    kaiser_beta : float
        Kaiser window beta of the FIR [-]. Default 5 (MATLAB's ``resample``).
    method : {"polyphase", "two_stage"}
        The route; both give the same output samples. Default "polyphase".
    padtype : {"line", "constant"}
        Pad the ends along a line, or with zeros after the mean removal. Default "line".
    return_means : bool
        Also return the rows' means. Default False.

    Returns
    -------
    y : ndarray
        (n_rows, n_out) resampled rows.
    means : ndarray
        ``np.mean(row)`` of each row (float64), only with ``return_means``.

    Raises
    ------
    ValueError
        An unknown ``method`` or ``padtype``.
    """
    if method not in RESAMPLE_METHODS:
        raise ValueError(f"unknown resampling method {method!r}; use one of {RESAMPLE_METHODS}")
    if padtype not in ("line", "constant"):
        raise ValueError(f"padtype must be 'line' or 'constant', got {padtype!r}")
    rows = [np.asarray(r, dtype=np.float64) for r in rows]
    if method == "two_stage" and padtype == "constant" and two_stage_plan(up, down):
        # the means removed inside the numba kernel, row by row: no stacked copy at all
        m = np.array([r.mean() for r in rows])
        y = _two_stage_rows(rows, m, up, down, kaiser_beta)
        return (y, m) if return_means else y
    xc = np.empty((len(rows), rows[0].size))
    m = np.empty((len(rows), 1))
    for i, r in enumerate(rows):
        m[i, 0] = r.mean()
        np.subtract(r, m[i, 0], out=xc[i])
    y = _resample_centred(xc, m, up, down, kaiser_beta, method, padtype)
    return (y, m[:, 0]) if return_means else y


def _resample_centred(xc: np.ndarray, m: np.ndarray, up: int, down: int, kaiser_beta: float,
                      method: str, padtype: str) -> np.ndarray:
    """Resample mean-free rows ``xc`` and add their means ``m`` back (see :func:`resample`)."""
    if method == "two_stage":
        plan = two_stage_plan(up, down)
        if plan is not None:
            return decimate_two_stage(xc, up, down, kaiser_beta=kaiser_beta,
                                      line=padtype == "line") + m
    y = signal.resample_poly(xc, up, down, axis=-1,
                             window=_resampling_fir(up, down, float(kaiser_beta)),
                             padtype=padtype)
    return y + m


def design_notch(f0_hz: float, q: float, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Second-order IIR notch at ``f0_hz`` with quality factor ``q`` (bandwidth f0/q).

    ``scipy.signal.iirnotch(f0_hz, q, fs=fs_hz)`` by its own arithmetic on Python floats [1]_,
    the same bits without its per-call array handling.

    Parameters
    ----------
    f0_hz : float
        Notch frequency [Hz].
    q : float
        Quality factor f0/bandwidth [-].
    fs_hz : float
        Sample rate [Hz].

    Returns
    -------
    b, a : ndarray
        Numerator and denominator coefficients.

    Notes
    -----
    ``beta = tan(bw/2)`` with bw = 2*pi*(f0/q)/fs, ``gain = 1/(1 + beta)``,
    ``b = gain*[1, -2*cos(w0), 1]``, ``a = [1, -2*gain*cos(w0), 2*gain - 1]``.

    References
    ----------
    .. [1] S.J. Orfanidis, "Introduction to Signal Processing", Prentice Hall 1996,
       Eqs. (11.3.4)-(11.3.7).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy import signal
    >>> b, a = design_notch(50.0, 30.0, 1000.0)
    >>> bool(np.allclose(b, signal.iirnotch(50.0, 30.0, fs=1000.0)[0], rtol=0, atol=1e-15))
    True
    """
    fs = float(fs_hz)
    w0 = 2 * float(f0_hz) / fs
    if w0 > 1.0 or w0 < 0.0 or not fs > 0:
        return signal.iirnotch(f0_hz, q, fs=fs_hz)  # scipy's own error message
    bw = w0 / float(q) * math.pi
    w0 = w0 * math.pi
    gain = 1.0 / (1.0 + math.tan(bw / 2.0))
    b = np.array([gain * 1.0, gain * (-2.0 * math.cos(w0)), gain * 1.0])
    a = np.array([1.0, -2.0 * gain * math.cos(w0), 2.0 * gain - 1.0])
    return b, a


@functools.lru_cache(maxsize=32)
def design_highpass(cutoff_hz: float, order: int, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Butterworth high-pass (applied twice by :func:`zero_phase`).

    Its parameters are configuration, not measurements, so the design is cached (read-only
    arrays).

    Parameters
    ----------
    cutoff_hz : float
        Cut-off frequency [Hz].
    order : int
        Filter order [-].
    fs_hz : float
        Sample rate [Hz].

    Returns
    -------
    b, a : ndarray
        Coefficients (read-only).
    """
    b, a = signal.butter(order, cutoff_hz, "highpass", fs=fs_hz)
    b.setflags(write=False)
    a.setflags(write=False)
    return b, a


def design_bandpass(center_hz: float, width_hz: float, order: int, fs_hz: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Butterworth band-pass from ``center - width/2`` to ``center + width/2``.

    Parameters
    ----------
    center_hz : float
        Centre frequency [Hz].
    width_hz : float
        Band width [Hz].
    order : int
        The prototype's order [-]; the band-pass has twice that (scipy's convention).
    fs_hz : float
        Sample rate [Hz].

    Returns
    -------
    b, a : ndarray
        Coefficients.

    Raises
    ------
    ValueError
        The band does not fit in 0..fs/2.
    """
    lo, hi = center_hz - width_hz / 2, center_hz + width_hz / 2
    if lo <= 0 or hi >= fs_hz / 2:
        raise ValueError(f"band-pass {lo:.3f}-{hi:.3f} Hz does not fit in 0..{fs_hz / 2} Hz")
    return _butter_bandpass(order, lo / fs_hz, hi / fs_hz)


def _butter_bandpass(order: int, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.signal.butter(order, [lo, hi], "bandpass", fs=1)`` (band edges in cycles per
    sample) by the same route (Butterworth prototype poles, low-pass to band-pass, bilinear
    transform with pre-warped edges, polynomial expansion) in plain complex arithmetic,
    without scipy's per-call array handling, which cost 10x the arithmetic here (the chain
    designs one per cycle). Agrees with scipy to rounding (tests/dsp/test_decimate_kernels.py)."""
    w1, w2 = 4.0 * math.tan(math.pi * lo), 4.0 * math.tan(math.pi * hi)  # pre-warped, fs=2
    bw, wo2 = w2 - w1, w1 * w2
    poles = []
    for m in range(-order + 1, order, 2):
        p = -cmath.exp(1j * math.pi * m / (2 * order)) * bw / 2  # prototype pole, scaled
        root = cmath.sqrt(p * p - wo2)
        poles += [p + root, p - root]
    gain = bw ** order
    den = 1.0 + 0j
    a = [1.0 + 0j]
    for p in poles:
        den *= 4.0 - p
        z = (4.0 + p) / (4.0 - p)  # bilinear transform (fs = 2)
        a = [u - z * v for u, v in zip([*a, 0j], [0j, *a], strict=True)]
    k = gain * (4.0 ** order / den).real  # the analog zeros (order at s=0) map to z=1
    # zeros: order at z=1, order at z=-1: the numerator is k*(z^2 - 1)^order
    b = np.zeros(2 * order + 1)
    for j in range(order + 1):
        b[2 * j] = k * math.comb(order, j) * (-1) ** j
    return b, np.array([c.real for c in a])


def zero_phase(ba: tuple[np.ndarray, np.ndarray], x: np.ndarray, *, method: str = "gust"
               ) -> np.ndarray:
    """Apply a filter forward and backward (zero phase).

    Parameters
    ----------
    ba : tuple of ndarray
        (b, a) coefficients.
    x : ndarray
        The record, any unit.
    method : {"gust", "none"}
        ``"gust"``: Gustafsson's initial conditions [1]_; ``"none"``: filter the record as it
        is, for records already padded (:func:`model_padded`). Default "gust".

    Returns
    -------
    ndarray
        The filtered record, same unit.

    References
    ----------
    .. [1] F. Gustafsson, "Determining the initial states in forward-backward filtering",
       IEEE Trans. Signal Process. 44(4) (1996) 988-992.
    """
    b, a = ba
    if method == "none":
        return signal.filtfilt(b, a, x, padlen=0)
    return signal.filtfilt(b, a, x, method="gust")


def zero_phase_cascade(filters_ba: list[tuple[np.ndarray, np.ndarray]], x: np.ndarray
                       ) -> np.ndarray:
    """Each filter in turn, forward and backward, along the last axis.

    The same arithmetic as ``zero_phase(ba, x, method="none")`` applied in sequence to each
    row (``filtfilt(b, a, x, padlen=0)``: initial state ``lfilter_zi`` times the first
    sample, each way), so the results are bit-identical, but every row goes through one
    ``lfilter`` call per direction and the steady-state vector is computed once per filter.

    Parameters
    ----------
    filters_ba : list of tuple of ndarray
        The (b, a) of each filter, in order.
    x : ndarray
        One record or several rows, any unit.

    Returns
    -------
    ndarray
        The filtered record(s), same unit.
    """
    y = np.array(x, dtype=np.float64)  # a copy, filtered in place
    rows = y.reshape(-1, y.shape[-1])
    for b, a in filters_ba:
        b = np.atleast_1d(np.asarray(b, dtype=np.float64))
        a = np.atleast_1d(np.asarray(a, dtype=np.float64))
        # a cached (read-only) design, the high-pass, has its steady state cached too
        zi = _lfilter_zi(b.tobytes(), a.tobytes()) if not (b.flags.writeable
                                                           or a.flags.writeable) \
            else _steady_state(b, a)
        if a[0] != 1.0 or a.size != b.size or b.size < 2:  # lfilter's general case
            y = _cascade_scipy(b, a, zi, y)
            rows = y.reshape(-1, y.shape[-1])
            continue
        _filtfilt_rows(b, a, zi, rows)
    return y


def _cascade_scipy(b: np.ndarray, a: np.ndarray, zi: np.ndarray, y: np.ndarray) -> np.ndarray:
    """One filter of :func:`zero_phase_cascade` through ``scipy.signal.lfilter``."""
    zi = zi.reshape([1] * (y.ndim - 1) + [-1])
    y, _ = signal.lfilter(b, a, y, axis=-1, zi=zi * y[..., :1])
    y, _ = signal.lfilter(b, a, y[..., ::-1], axis=-1, zi=zi * y[..., -1:])
    return np.ascontiguousarray(y[..., ::-1])


@numba.njit(cache=True, nogil=True)
def _filtfilt_rows(b: np.ndarray, a: np.ndarray, zi: np.ndarray, x: np.ndarray) -> None:
    """Each row of ``x`` through ``b/a`` forward, then backward, in place, each way from the
    steady state ``zi`` times the first sample it meets: ``filtfilt(b, a, row, padlen=0)``.
    The direct form II transposed with scipy's order of operations (``y = z0 + b0*x``,
    ``z_i = z_(i+1) + x*b_(i+1) - y*a_(i+1)``; ``a[0] = 1``, ``b`` and ``a`` of one length)
    and no fast-math, so the same bits as ``lfilter``
    (tests/processing/test_chain_speed_equivalence.py
    and tests/dsp/test_decimate_kernels.py). The rows advance together: their recursions are
    independent, so the processor overlaps them."""
    n_rows, n = x.shape
    m = b.size - 1
    z = np.empty((n_rows, m))
    for direction in range(2):
        first = 0 if direction == 0 else n - 1
        for r in range(n_rows):
            for i in range(m):
                z[r, i] = zi[i] * x[r, first]
        for k in range(n):
            j = k if direction == 0 else n - 1 - k
            for r in range(n_rows):
                xn = x[r, j]
                yn = z[r, 0] + b[0] * xn
                for i in range(m - 1):
                    z[r, i] = z[r, i + 1] + xn * b[i + 1] - yn * a[i + 1]
                z[r, m - 1] = xn * b[m] - yn * a[m]
                x[r, j] = yn


def _steady_state(b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``scipy.signal.lfilter_zi(b, a)`` for 1-D float64 coefficients with ``a[0] != 0``:
    the same operations (normalise by ``a[0]``, pad to equal length, solve
    ``(I - companion(a).T) zi = b[1:] - a[1:]*b[0]``), so the same bits (tested), without
    its array-API dispatch."""
    if a[0] != 1.0:
        b, a = b / a[0], a / a[0]
    n = max(a.size, b.size)
    if a.size < n:
        a = np.concatenate((a, np.zeros(n - a.size)))
    elif b.size < n:
        b = np.concatenate((b, np.zeros(n - b.size)))
    if n < 2:
        return np.zeros(0)
    return _steady_state_solve(np.ascontiguousarray(b, dtype=np.float64),
                               np.ascontiguousarray(a, dtype=np.float64))


@numba.njit(cache=True, nogil=True)
def _steady_state_solve(b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``lfilter_zi``'s system ``(I - C^T) zi = b[1:] - a[1:]*b[0]`` (C the companion matrix
    of ``a``: first row ``-a[1:]/a[0]``, ones below the diagonal) built entry by entry with
    the same arithmetic and solved by LAPACK ``gesv`` as ``numpy.linalg.solve`` does: the
    same bits (tests/dsp/test_decimate_kernels.py and tests/processing/test_chain_kernels.py)."""
    n = a.size
    m = np.zeros((n - 1, n - 1))
    for i in range(n - 1):
        for j in range(n - 1):
            c = 0.0
            if j == 0:
                c = -a[i + 1] / a[0]  # C^T[i, 0] = C[0, i]
            elif j == i + 1:
                c = 1.0  # C^T[i, i + 1] = C[i + 1, i]
            m[i, j] = (1.0 if i == j else 0.0) - c
    return np.linalg.solve(m, b[1:] - a[1:] * b[0])


@functools.lru_cache(maxsize=16)
def _lfilter_zi(b_bytes: bytes, a_bytes: bytes) -> np.ndarray:
    """``lfilter_zi`` of float64 coefficients given as bytes (for filters whose design is
    cached: configuration, not measurements); read-only."""
    zi = signal.lfilter_zi(np.frombuffer(b_bytes), np.frombuffer(a_bytes))
    zi.setflags(write=False)
    return zi


def notch_frequencies(rotation_hz: float, harmonics: tuple[int, ...], fs_hz: float
                      ) -> list[float]:
    """The harmonics of a rotation frequency that lie strictly below Nyquist.

    Parameters
    ----------
    rotation_hz : float
        Rotation frequency [Hz].
    harmonics : tuple of int
        Harmonic numbers.
    fs_hz : float
        Sample rate [Hz].

    Returns
    -------
    list of float
        The frequencies [Hz].

    Examples
    --------
    >>> notch_frequencies(10.0, (1, 2, 3), 50.0)
    [10.0, 20.0]
    """
    return [h * rotation_hz for h in harmonics if 0 < h * rotation_hz < fs_hz / 2]


def settling_samples(ba: tuple[np.ndarray, np.ndarray], *, tol: float = 1e-6,
                     max_samples: int = 1_000_000) -> int:
    """Samples after which a filter's impulse response stays below a share of its peak.

    Derived from the design; used as the padding length. A cached (read-only) design, the
    high-pass, has its answer cached too.

    Parameters
    ----------
    ba : tuple of ndarray
        (b, a) coefficients.
    tol : float
        Share of the peak [-]. Default 1e-6.
    max_samples : int
        Longest response searched [-]. Default 1 000 000.

    Returns
    -------
    int
        Samples.
    """
    b, a = ba
    if all(isinstance(v, np.ndarray) and v.dtype == np.float64 and not v.flags.writeable
           for v in (b, a)):
        return _settling_cached(b.tobytes(), a.tobytes(), tol, max_samples)
    return _settling_search(b, a, tol, max_samples)


@functools.lru_cache(maxsize=16)
def _settling_cached(b_bytes: bytes, a_bytes: bytes, tol: float, max_samples: int) -> int:
    return _settling_search(np.frombuffer(b_bytes), np.frombuffer(a_bytes), tol, max_samples)


def _settling_search(b, a, tol: float, max_samples: int) -> int:
    """:func:`settling_samples` of the filter ``b/a``: the doubling search (compiled for the
    chain's designs, ``a[0] = 1`` and ``b``, ``a`` of one length; scipy's ``lfilter``
    otherwise)."""
    b = np.atleast_1d(np.asarray(b, dtype=np.float64))
    a = np.atleast_1d(np.asarray(a, dtype=np.float64))
    if a[0] == 1.0 and a.size == b.size >= 2:
        return int(_settling_kernel(b, a, float(tol), int(max_samples)))
    n = 256
    h = np.empty(0)
    while n <= max_samples:
        if h.size < n:  # a causal filter's first n outputs do not depend on the length, so
            # one response 8x longer serves the next three lengths tried
            length = 8 * n if 8 * n <= max_samples else n
            h = signal.lfilter(b, a, np.r_[1.0, np.zeros(length - 1)])
        mag = np.abs(h[:n])
        above = np.flatnonzero(mag > tol * mag.max())
        if above[-1] < n - n // 4:
            return int(above[-1]) + 1
        n *= 2
    return max_samples


@numba.njit(cache=True, nogil=True)
def _settling_kernel(b: np.ndarray, a: np.ndarray, tol: float, max_samples: int) -> int:
    """The doubling search of :func:`_settling_search` on the impulse response computed in
    the direct form II transposed with ``lfilter``'s order of operations (as
    :func:`_filtfilt_rows`: the same bits), extended only as far as the search reads it."""
    m = b.size - 1
    z = np.zeros(m)
    h = np.empty(min(max_samples, 4096))  # grown when the search goes further
    done = 0
    n = 256
    while n <= max_samples:
        if n > h.size:
            grown = np.empty(min(max_samples, 4 * n))
            grown[:done] = h[:done]
            h = grown
        for k in range(done, n):  # the response's first n samples
            xn = 1.0 if k == 0 else 0.0
            yn = z[0] + b[0] * xn
            for i in range(m - 1):
                z[i] = z[i + 1] + xn * b[i + 1] - yn * a[i + 1]
            z[m - 1] = xn * b[m] - yn * a[m]
            h[k] = yn
        done = n
        peak = 0.0
        for k in range(n):
            peak = max(peak, abs(h[k]))
        last = -1
        for k in range(n):
            if abs(h[k]) > tol * peak:
                last = k
        if last < n - n // 4:
            return last + 1
        n *= 2
    return max_samples


def resampler_edge_samples(up: int, down: int) -> int:
    """Output samples at each end touched by the zero padding of :func:`resample`'s FIR.

    ``resample_poly`` uses ``10*max(up, down)`` taps either side of the centre at the
    upsampled rate; one output sample is ``down`` upsampled samples, so the FIR reaches
    ``ceil(10*max(up, down)/down)`` output samples into the padding (plus one of margin).

    Parameters
    ----------
    up : int
        Upsampling factor [-].
    down : int
        Downsampling factor [-].

    Returns
    -------
    int
        Samples at each end.

    Examples
    --------
    >>> resampler_edge_samples(2, 625)
    11
    """
    half_taps = 10 * max(up, down)
    return int(np.ceil(half_taps / down)) + 1


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
    """The design of :func:`fit_line_and_tones` for ``n`` samples and the tones it keeps."""
    res = fs_hz / n
    kept: list[float] = []
    for f in tones_hz:
        if 0 < f < fs_hz / 2 and all(abs(f - g) > res for g in kept):
            kept.append(f)
    design = np.empty((n, 2 + 2 * len(kept)))
    design[:, 0] = 1.0
    design[:, 1] = (np.arange(n) - (n - 1) / 2) / fs_hz  # t - mean t
    _fill_cos_sin(design, 2, 2 * np.pi * np.array(kept, dtype=np.float64) / fs_hz, 0)
    return design, kept


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
