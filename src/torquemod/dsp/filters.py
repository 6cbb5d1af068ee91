"""Steps 3-5 of the V-Track chain: notch, high-pass and band-pass filters (resampling, step 2,
is in :mod:`torquemod.dsp.resampling`; the line-plus-tones padding model in
:mod:`torquemod.dsp.tonemodel`).

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
    lo, hi = bandpass_edges(center_hz, width_hz, fs_hz)
    return _butter_bandpass(order, lo, hi)


def bandpass_edges(center_hz: float, width_hz: float, fs_hz: float) -> tuple[float, float]:
    """The band edges of :func:`design_bandpass` [cycles per sample].

    Parameters
    ----------
    center_hz : float
        Centre frequency [Hz].
    width_hz : float
        Band width [Hz].
    fs_hz : float
        Sample rate [Hz].

    Returns
    -------
    lo, hi : float
        ``(center -+ width/2)/fs`` [-].

    Raises
    ------
    ValueError
        The band does not fit in 0..fs/2.
    """
    lo, hi = center_hz - width_hz / 2, center_hz + width_hz / 2
    if lo <= 0 or hi >= fs_hz / 2:
        raise ValueError(f"band-pass {lo:.3f}-{hi:.3f} Hz does not fit in 0..{fs_hz / 2} Hz")
    return lo / fs_hz, hi / fs_hz


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
    if m == 2 or m == 4:  # second and fourth order: the state in registers (the same
        for r in range(0, n_rows, 2):  # operations in the same order), two rows at a time
            _filtfilt_pair(b, a, zi, x, r, min(r + 1, n_rows - 1))
        return
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


@numba.njit(cache=True, nogil=True)
def _filtfilt_pair(b: np.ndarray, a: np.ndarray, zi: np.ndarray, x: np.ndarray, r: int,
                   s: int) -> None:
    """:func:`_filtfilt_rows` of rows ``r`` and ``s`` of ``x`` (one row when ``r == s``) for
    a filter of order 2 or 4 (``b.size`` 3 or 5), the state as scalars (registers, not
    memory) and both recursions in one loop: each sample's operations and their order are
    those of :func:`_filtfilt_rows`, so the same bits."""
    n = x.shape[1]
    two = s != r
    fourth = b.size == 5
    b0, b1, b2 = b[0], b[1], b[2]
    a1, a2 = a[1], a[2]
    b3 = b[3] if fourth else 0.0
    b4 = b[4] if fourth else 0.0
    a3 = a[3] if fourth else 0.0
    a4 = a[4] if fourth else 0.0
    xr, xs = x[r], x[s]
    for direction in range(2):
        first = 0 if direction == 0 else n - 1
        step = 1 if direction == 0 else -1
        u0, u1 = zi[0] * xr[first], zi[1] * xr[first]
        v0, v1 = zi[0] * xs[first], zi[1] * xs[first]
        u2 = zi[2] * xr[first] if fourth else 0.0
        u3 = zi[3] * xr[first] if fourth else 0.0
        v2 = zi[2] * xs[first] if fourth else 0.0
        v3 = zi[3] * xs[first] if fourth else 0.0
        j = first
        if fourth:
            for _ in range(n):
                xn = xr[j]
                yn = u0 + b0 * xn
                u0 = u1 + xn * b1 - yn * a1
                u1 = u2 + xn * b2 - yn * a2
                u2 = u3 + xn * b3 - yn * a3
                u3 = xn * b4 - yn * a4
                xr[j] = yn
                if two:
                    xm = xs[j]
                    ym = v0 + b0 * xm
                    v0 = v1 + xm * b1 - ym * a1
                    v1 = v2 + xm * b2 - ym * a2
                    v2 = v3 + xm * b3 - ym * a3
                    v3 = xm * b4 - ym * a4
                    xs[j] = ym
                j += step
        else:
            for _ in range(n):
                xn = xr[j]
                yn = u0 + b0 * xn
                u0 = u1 + xn * b1 - yn * a1
                u1 = xn * b2 - yn * a2
                xr[j] = yn
                if two:
                    xm = xs[j]
                    ym = v0 + b0 * xm
                    v0 = v1 + xm * b1 - ym * a1
                    v1 = xm * b2 - ym * a2
                    xs[j] = ym
                j += step


@numba.njit(cache=True, nogil=True)
def _response_samples(b: np.ndarray, a: np.ndarray, z: np.ndarray, h: np.ndarray, start: int,
                      stop: int) -> None:
    """Samples ``start:stop`` of the impulse response of ``b/a`` into ``h``, from and to the
    state ``z`` (:func:`_filtfilt_rows`'s operations; orders 2 and 4 with the state as
    scalars: the same bits)."""
    m = b.size - 1
    if m == 2 or m == 4:
        fourth = m == 4
        z0, z1 = z[0], z[1]
        z2 = z[2] if fourth else 0.0
        z3 = z[3] if fourth else 0.0
        b0, b1, b2, a1, a2 = b[0], b[1], b[2], a[1], a[2]
        b3 = b[3] if fourth else 0.0
        b4 = b[4] if fourth else 0.0
        a3 = a[3] if fourth else 0.0
        a4 = a[4] if fourth else 0.0
        for k in range(start, stop):
            xn = 1.0 if k == 0 else 0.0
            yn = z0 + b0 * xn
            if fourth:
                z0 = z1 + xn * b1 - yn * a1
                z1 = z2 + xn * b2 - yn * a2
                z2 = z3 + xn * b3 - yn * a3
                z3 = xn * b4 - yn * a4
            else:
                z0 = z1 + xn * b1 - yn * a1
                z1 = xn * b2 - yn * a2
            h[k] = yn
        z[0], z[1] = z0, z1
        if fourth:
            z[2], z[3] = z2, z3
        return
    for k in range(start, stop):
        xn = 1.0 if k == 0 else 0.0
        yn = z[0] + b[0] * xn
        for i in range(m - 1):
            z[i] = z[i + 1] + xn * b[i + 1] - yn * a[i + 1]
        z[m - 1] = xn * b[m] - yn * a[m]
        h[k] = yn


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
    peak = 0.0
    n = 256
    while n <= max_samples:
        if n > h.size:
            grown = np.empty(min(max_samples, 4 * n))
            grown[:done] = h[:done]
            h = grown
        _response_samples(b, a, z, h, done, n)  # the response's first n samples
        for k in range(done, n):  # the peak of the first n: the earlier ones' and the new
            peak = max(peak, abs(h[k]))
        done = n
        last = n - 1  # the last sample above the share of the peak, from the end
        while last >= 0 and not abs(h[last]) > tol * peak:
            last -= 1
        if last < n - n // 4:
            return last + 1
        n *= 2
    return max_samples


