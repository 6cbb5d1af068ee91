"""Bases of the speed model (a chain that is right on a moving speed): the slow
variation (Legendre polynomials and Slepian sequences) and the rotation orders that follow
an encoder's integrated angle, and the choice of the slow band for a cycle. Re-exported by
:mod:`torquemod.dsp.filters`."""

from __future__ import annotations

import functools
import math

import numba
import numpy as np
from scipy.special import fdtri

from torquemod.dsp.lstsq import LstsqFactor, lstsq
from torquemod.dsp.projection import orthonormal_basis_t


@functools.lru_cache(maxsize=64)
def _slow_basis_cached(n: int, nw: float, k: int, degree: int) -> np.ndarray:
    from numpy.polynomial import legendre
    x = np.linspace(-1.0, 1.0, n)
    cols = [legendre.legvander(x, degree)]
    if k > 0:
        cols.append(np.atleast_2d(_dpss(n, nw, k)).T)
    basis = np.column_stack(cols)
    basis.setflags(write=False)
    return basis


def _dpss(n: int, nw: float, k: int) -> np.ndarray:
    """``scipy.signal.windows.dpss(n, nw, k)`` (rows, unit norm, scipy's sign conventions):
    the ``k`` largest eigenvectors of the same tridiagonal matrix (Percival and Walden 1993,
    ch. 8), with its eigenvalues located by bisection (LAPACK ``stebz``) to 1e-9 of their
    size instead of to full precision, then inverse iteration (``stein``) as scipy does. The
    eigenvalues are ~1e-3 of their size apart, so the vectors come out the same to rounding
    (measured <= 2e-14 against scipy for n = 323..1000) in 60 % of the time (the cost of a
    cycle of a new length). Falls back to scipy outside the usual case."""
    from scipy.linalg import lapack
    from scipy.signal.windows import dpss
    if not (0 < k <= n and 0 < nw < n / 2):
        return dpss(n, nw, k)
    w_half = nw / n
    idx = np.arange(n)
    d = ((n - 1 - 2 * idx) / 2.0) ** 2 * np.cos(2 * np.pi * w_half)
    e = idx[1:] * (n - idx[1:]) / 2.0
    scale = float(np.max(np.abs(d)) + 2.0 * np.max(e, initial=0.0))  # Gershgorin bound
    m, w, iblock, isplit, info = lapack.dstebz(d, e, 3, 0.0, 1.0, n - k + 1, n, 1e-9 * scale,
                                               "B")
    if info != 0 or m != k:
        return dpss(n, nw, k)
    z, info = lapack.dstein(d, e, w[:m], iblock, isplit)
    if info != 0:
        return dpss(n, nw, k)
    windows = z[:, ::-1].T.copy()  # largest eigenvalue first
    for i in range(0, k, 2):  # symmetric tapers: positive mean (scipy's convention)
        if windows[i].sum() < 0:
            windows[i] *= -1
    thresh = max(1e-7, 1.0 / n)
    for i in range(1, k, 2):  # antisymmetric tapers: a positive first lobe
        row = windows[i]
        if row[row * row > thresh][0] < 0:
            windows[i] *= -1
    return windows


def slow_basis(n_samples: int, fs_hz: float, max_hz: float, *, extra: int = 2,
               degree: int = 5) -> np.ndarray:
    """Basis of slowly varying signals: Legendre polynomials and Slepian sequences.

    Legendre polynomials up to ``degree`` and the first ``round(2*T*max_hz) + extra``
    discrete prolate spheroidal (Slepian) sequences of half-bandwidth ``max_hz`` over the
    record's duration T. The Slepian sequences are the signals of length T most concentrated
    in ``|f| < max_hz`` [1]_, so any variation below ``max_hz`` is nearly in their span while
    they stay nearly orthogonal to a modulation above it; they are small at the record's
    ends, where the polynomials give the basis its freedom.

    Parameters
    ----------
    n_samples : int
        Samples [-].
    fs_hz : float
        Sample rate [Hz].
    max_hz : float
        Half-bandwidth [Hz]; 0 gives the polynomials alone.
    extra : int
        Slepian sequences beyond ``round(2*T*max_hz)`` [-]. Default 2.
    degree : int
        Highest polynomial degree [-]. Default 5.

    Returns
    -------
    ndarray
        (n_samples, m) basis.

    Notes
    -----
    Measured over a 6.05 s record at 53.3 Hz with ``max_hz = 1.2``, ``extra = 2``,
    ``degree = 5``: a unit sinusoid anywhere in 0.2-1.0 Hz leaks < 1e-5 into a jointly
    fitted 2 Hz modulation (2e-4 at 1.2 Hz), and the joint fit costs the modulation 23 % of
    variance (:meth:`torquemod.processing.speedmodel.SpeedModel.variance_factor`).

    References
    ----------
    .. [1] D. Slepian, "Prolate spheroidal wave functions, Fourier analysis, and
       uncertainty - V: the discrete case", Bell Syst. Tech. J. 57(5) (1978) 1371-1430.
    """
    duration = n_samples / fs_hz
    nw = duration * max_hz
    k = 0 if nw < 0.5 else max(0, min(n_samples // 2, round(2 * nw) + extra))
    degree = max(0, min(degree, n_samples // 4))
    return _slow_basis_cached(int(n_samples), float(nw), int(k), int(degree))


def unwrapped_angle(speed_rad_s: np.ndarray, fs_hz: float) -> np.ndarray:
    """Angle turned since the first sample: the trapezoidal integral of an angular speed.

    Used to follow rotation orders whose frequency moves.

    Parameters
    ----------
    speed_rad_s : ndarray
        Angular speed [rad/s].
    fs_hz : float
        Sample rate [Hz].

    Returns
    -------
    ndarray
        Angle [rad], 0 at the first sample.

    Examples
    --------
    >>> import numpy as np
    >>> unwrapped_angle(np.full(3, 2.0), 10.0).tolist()
    [0.0, 0.2, 0.4]
    """
    w = np.asarray(speed_rad_s, dtype=np.float64)
    out = np.empty_like(w)
    out[0] = 0.0
    np.cumsum(0.5 * (w[1:] + w[:-1]) / fs_hz, out=out[1:])
    return out


def order_design(angle_rad: np.ndarray, orders) -> np.ndarray:
    """Columns ``cos(k*theta), sin(k*theta)`` for each rotation order k.

    An encoder's eccentricity error follows the angle, so when the speed moves its tones move
    with it (order tracking); fixed-frequency tones would leave sidebands. The orders above 1
    are powers of ``exp(1j*theta)``.

    Parameters
    ----------
    angle_rad : ndarray
        The angle theta [rad] (:func:`unwrapped_angle`).
    orders : sequence of int
        The orders k.

    Returns
    -------
    ndarray
        (n, 2*len(orders)) design columns [-].
    """
    theta = np.asarray(angle_rad, dtype=np.float64)
    orders = np.array([int(k) for k in orders], dtype=np.int64)
    if orders.size == 0:
        return np.empty((theta.size, 0))
    return _order_columns(theta, orders)


@numba.njit(cache=True, nogil=True)
def _order_columns(theta: np.ndarray, orders: np.ndarray) -> np.ndarray:
    """``cos(k*theta)``, ``sin(k*theta)`` for each k of ``orders`` (positive integers): one
    ``cos`` and ``sin`` of theta per sample, then ``exp(1j*k*theta)`` by repeated complex
    multiplication (k - 1 products, ~k units in the last place from the direct evaluation;
    tests/processing/test_chain_kernels.py); a non-positive order is evaluated directly."""
    n = theta.size
    out = np.empty((n, 2 * orders.size))
    k_max = 0
    for k in orders:
        k_max = max(k_max, k)
    for i in range(n):
        c1, s1 = math.cos(theta[i]), math.sin(theta[i])
        c, s = c1, s1
        for k in range(1, k_max + 1):
            if k > 1:
                c, s = c * c1 - s * s1, s * c1 + c * s1
            for j in range(orders.size):
                if orders[j] == k:
                    out[i, 2 * j] = c
                    out[i, 2 * j + 1] = s
        for j in range(orders.size):
            if orders[j] <= 0:
                out[i, 2 * j] = math.cos(orders[j] * theta[i])
                out[i, 2 * j + 1] = math.sin(orders[j] * theta[i])
    return out


#: :func:`order_design`'s compiled kernel (``theta`` [rad] as a float64 array, ``orders`` as
#: an int64 array of positive orders), for other compiled kernels to call.
order_columns = _order_columns


#: Thresholds of :func:`needs_wide_band`: the platform speed's variation above the quiet
#: band must be significant (F test; false-alarm probability on white noise) ...
WIDE_BAND_FALSE_ALARM = 1e-3
#: ... and move the wheel's modulation by more than this phase [rad] (0.006 deg) if left out
#: of the slow model (the wheel follows the platform's relative speed variation).
WIDE_BAND_RISK_RAD = 1e-4


def needs_wide_band(wheel: np.ndarray, platform: np.ndarray | None, fs_hz: float,
                    modulation_hz: float, quiet_hz: float, wide_hz: float, *, extra: int,
                    degree: int) -> bool:
    """Whether the speed model needs its full slow band for one cycle.

    Under a speed wobble at f_w the wheel's answer to the modulation at f moves with the
    operating point and carries sidebands at f +- f_w and, near saturation, f +- 2 f_w. A
    slow band reaching them takes part of the answer away and changes the phase (0.3-0.5 deg
    at 80-90 % of the peak under a 0.3 % wobble at 0.2-0.6 Hz with a 1.2 Hz band at 2 Hz;
    independent rig, benchmarks/chain_accuracy.py). The quiet band keeps them, but a speed
    variation above it (a speed loop wobbling at 0.8-1.2 Hz) then leaks into the modulation.
    The platform speed carries the speed loop's variation and hardly any answer to the
    modulation, so it decides.

    Parameters
    ----------
    wheel : ndarray
        Wheel speed of the cycle [rad/s].
    platform : ndarray or None
        Platform speed [rad/s]; None: the wide band is always needed.
    fs_hz : float
        Sample rate [Hz].
    modulation_hz : float
        Modulation frequency [Hz].
    quiet_hz : float
        The quiet band's half-width [Hz] (``slow.quiet_max_hz``).
    wide_hz : float
        The full band's half-width [Hz] (``slow.max_hz``).
    extra : int
        Slepian sequences beyond the band's count in the wide basis [-].
    degree : int
        Polynomial degree of the basis [-].

    Returns
    -------
    bool
        True when the wide band is needed.

    Notes
    -----
    The platform speed is fitted with the modulation beside the Slepian sequences of the
    quiet band (without extra sequences) and beside the full slow basis of the wide band
    (:func:`slow_basis`). The wide band is needed when it explains significantly more (the F
    test of nested least-squares models [1]_ at :data:`WIDE_BAND_FALSE_ALARM`) and when the
    platform's modulation coefficients of the two fits differ, relative to its mean speed, by
    more than :data:`WIDE_BAND_RISK_RAD` times the wheel's relative modulation amplitude.

    References
    ----------
    .. [1] S. Weisberg, "Applied Linear Regression", 4th ed., Wiley 2014 (the F test of
       nested models).
    """
    if platform is None:
        return True
    stats = _wide_band_statistics(wheel, platform, fs_hz, modulation_hz, quiet_hz, wide_hz,
                                  extra=extra, degree=degree)
    if stats is None:
        return True
    f_stat, f_critical, risk = stats
    return bool(f_stat > f_critical and risk > WIDE_BAND_RISK_RAD)


def _wide_band_statistics(wheel: np.ndarray, platform: np.ndarray, fs_hz: float,
                          modulation_hz: float, quiet_hz: float, wide_hz: float, *,
                          extra: int, degree: int, maps: bool = True
                          ) -> tuple[float, float, float] | None:
    """:func:`needs_wide_band`'s F statistic [-], its critical value [-] and the risk [rad];
    None where the test cannot be made (no degrees of freedom, a zero mean speed or no
    wheel modulation: the wide band). ``maps=False``: each fit by its own refined solve
    instead of the cached coefficient maps (the same fits, other rounding: ~1e-12
    relative, tests/dsp/test_wide_band.py)."""
    n = wheel.size
    key = (int(n), float(fs_hz), float(modulation_hz), int(degree))
    cached = _wide_band_maps(*key, float(quiet_hz), float(wide_hz), int(extra)) \
        if maps and degree >= 0 else None  # (degree >= 0: the designs hold the constant)
    if cached is not None:
        # both fits from the designs' orthonormal bases and the modulation's rows of their
        # pseudo-inverses (made once per record length), of the records less their means
        # (both designs hold the constant: the same fits), and the statistics, in one call
        maps_t, wheel_mod, p_q, f_critical = cached
        if wheel.dtype != np.float64 or platform.dtype != np.float64:
            wheel, platform = wheel.astype(np.float64), platform.astype(np.float64)
        valid, f_stat, risk = _wide_band_test(maps_t, wheel_mod, p_q, wheel, platform)
        return (f_stat, f_critical, risk) if valid else None
    y = np.column_stack([wheel, platform])
    fits = []
    for band, ext in ((quiet_hz, 0), (wide_hz, extra)):
        design, fac = _wide_band_design(*key[:3], float(band), int(ext), int(degree))
        coef, rank = (fac.solve(y), design.shape[1]) if fac is not None \
            else lstsq(design, y)
        resid = platform - design @ coef[:, 1]
        fits.append((float(resid @ resid), rank, coef[:2]))
    (rss_q, rank_q, coef_q), (rss_w, rank_w, coef_w) = fits
    plat_q, plat_w, coef_w0 = coef_q[:, 1], coef_w[:, 1], coef_w[:, 0]
    dfn, dfd = rank_w - rank_q, n - rank_w
    w_mean = float(wheel.sum()) / wheel.size  # np.mean's numbers, cheaper
    p_mean = float(platform.sum()) / platform.size
    wheel_rel = float(np.hypot(coef_w0[0], coef_w0[1])) / abs(w_mean) if w_mean else 0.0
    if dfn <= 0 or dfd <= 0 or not (p_mean and wheel_rel > 0):
        return None
    f_stat = (rss_q - rss_w) / dfn / max(rss_w / dfd, 1e-300)
    d_plat = plat_q - plat_w
    risk = float(np.hypot(d_plat[0], d_plat[1])) / abs(p_mean) / wheel_rel
    return f_stat, _f_critical(dfn, dfd), risk


@numba.njit(cache=True, nogil=True)
def _wide_band_test(maps_t: np.ndarray, wheel_mod: np.ndarray, p_q: int, wheel: np.ndarray,
                    platform: np.ndarray) -> tuple[bool, float, float]:
    """:func:`_wide_band_statistics` from :func:`_wide_band_maps`' arrays in one call:
    whether the test can be made, the F statistic [-] and the risk [rad].

    ``maps_t`` holds ``[Q_q Q_w W_q' W_w']`` (C order, a row a sample), ``wheel_mod`` is
    ``W_w`` (C order) and ``p_q`` the quiet basis' width. The platform's and the wheel's
    residual sums of squares and modulation coefficients are those of the records less
    their means (each product summed over the samples, and over the columns, in ascending
    order, as plain loops take them: the projections advance together sample by sample,
    and the fits read the same rows while they are in cache), the mean speeds of the
    ratios numpy's pairwise sums (:func:`_numpy_sum`)."""
    n, cols = maps_t.shape
    p_w = cols - p_q - 4
    p_sum = 0.0
    w_sum = 0.0
    for t in range(n):
        p_sum += platform[t]
        w_sum += wheel[t]
    p_c = p_sum / n
    w_c = w_sum / n
    pl = np.empty(n)
    for t in range(n):
        pl[t] = platform[t] - p_c
    proj = np.zeros(cols)  # [Q_q Q_w W_q' W_w']' pl
    for t in range(n):
        v = pl[t]
        for i in range(cols):
            proj[i] += maps_t[t, i] * v
    fits = _two_fits(maps_t, proj, p_q, p_w)
    rss_q = 0.0
    rss_w = 0.0
    c0 = 0.0
    c1 = 0.0
    for t in range(n):
        fit_q = fits[0, t]  # Q_q (Q_q' pl) and Q_w (Q_w' pl) at sample t
        fit_w = fits[1, t]
        rss_q += (pl[t] - fit_q) ** 2
        rss_w += (pl[t] - fit_w) ** 2
        c0 += wheel_mod[0, t] * (wheel[t] - w_c)
        c1 += wheel_mod[1, t] * (wheel[t] - w_c)
    dfn, dfd = p_w - p_q, n - p_w
    w_mean = _numpy_sum(wheel, 0, n) / n
    p_mean = _numpy_sum(platform, 0, n) / n
    wheel_rel = math.hypot(c0, c1) / abs(w_mean) if w_mean != 0 else 0.0
    if dfn <= 0 or dfd <= 0 or p_mean == 0 or not wheel_rel > 0:
        return False, np.nan, np.nan
    f_stat = (rss_q - rss_w) / dfn / max(rss_w / dfd, 1e-300)
    k = p_q + p_w
    risk = math.hypot(proj[k] - proj[k + 2], proj[k + 1] - proj[k + 3]) / abs(p_mean) \
        / wheel_rel
    return True, f_stat, risk


@numba.njit(cache=True, nogil=True)
def _two_fits(maps_t: np.ndarray, proj: np.ndarray, p_q: int, p_w: int) -> np.ndarray:
    """``(2, n)``: at each sample t, ``sum_i maps_t[t, i] proj[i]`` over the columns
    ``0..p_q-1``, then over ``p_q..p_q+p_w-1``, each summed in ascending order. Four samples
    at a time (eight independent sums, each with the additions of one sample at a time: the
    same numbers), so that the processor overlaps their additions instead of waiting on
    each in turn."""
    n = maps_t.shape[0]
    fits = np.empty((2, n))
    t = 0
    while t + 4 <= n:
        r0, r1, r2, r3 = maps_t[t], maps_t[t + 1], maps_t[t + 2], maps_t[t + 3]
        q0 = q1 = q2 = q3 = 0.0
        for i in range(p_q):
            v = proj[i]
            q0 += r0[i] * v
            q1 += r1[i] * v
            q2 += r2[i] * v
            q3 += r3[i] * v
        w0 = w1 = w2 = w3 = 0.0
        for i in range(p_q, p_q + p_w):
            v = proj[i]
            w0 += r0[i] * v
            w1 += r1[i] * v
            w2 += r2[i] * v
            w3 += r3[i] * v
        fits[0, t], fits[0, t + 1], fits[0, t + 2], fits[0, t + 3] = q0, q1, q2, q3
        fits[1, t], fits[1, t + 1], fits[1, t + 2], fits[1, t + 3] = w0, w1, w2, w3
        t += 4
    for u in range(t, n):
        q = 0.0
        for i in range(p_q):
            q += maps_t[u, i] * proj[i]
        w = 0.0
        for i in range(p_q, p_q + p_w):
            w += maps_t[u, i] * proj[i]
        fits[0, u], fits[1, u] = q, w
    return fits


@numba.njit(cache=True, nogil=True)
def _numpy_sum(a: np.ndarray, start: int, n: int) -> float:
    """``a[start:start + n].sum()`` as numpy adds a contiguous float64 array: in order below
    8 values, with eight running sums up to 128, and above that the sum of the sums of two
    parts split at half the length rounded down to a multiple of 8 (pairwise summation,
    N. J. Higham, "The accuracy of floating point summation", SIAM J. Sci. Comput. 14(4),
    1993). Without recursion (a cached kernel must not call itself): the parts on a
    stack."""
    starts = np.empty(64, dtype=np.int64)  # the parts still to add or to combine
    sizes = np.empty(64, dtype=np.int64)
    split = np.zeros(64, dtype=np.bool_)  # the part's two halves are summed: combine them
    sums = np.empty(64)
    top, m = 0, 0
    starts[0], sizes[0] = start, n
    while top >= 0:
        s0, size = starts[top], sizes[top]
        if size > 128 and not split[top]:
            half = size // 2
            half -= half % 8
            split[top] = True
            starts[top + 1], sizes[top + 1], split[top + 1] = s0 + half, size - half, False
            starts[top + 2], sizes[top + 2], split[top + 2] = s0, half, False
            top += 2  # the first half on top: summed first
            continue
        top -= 1
        if size > 128:
            sums[m - 2] = sums[m - 2] + sums[m - 1]  # first half + second half
            m -= 1
            continue
        sums[m] = _block_sum(a, s0, size)
        m += 1
    return sums[0]


@numba.njit(cache=True, nogil=True)
def _block_sum(a: np.ndarray, start: int, n: int) -> float:
    """numpy's sum of ``a[start:start + n]`` for ``n <= 128`` (:func:`_numpy_sum`)."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[start + i]
        return res
    r = a[start:start + 8].copy()
    i = 8
    while i < n - n % 8:
        for j in range(8):
            r[j] += a[start + i + j]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[start + i]
        i += 1
    return res


@functools.lru_cache(maxsize=64)
def _f_critical(dfn: int, dfd: int) -> float:
    """The F distribution's upper :data:`WIDE_BAND_FALSE_ALARM` point for ``dfn`` and
    ``dfd`` degrees of freedom [-] (``scipy.special.fdtri``), cached."""
    return float(fdtri(dfn, dfd, 1.0 - WIDE_BAND_FALSE_ALARM))


@functools.lru_cache(maxsize=16)
def _wide_band_maps(n: int, fs_hz: float, modulation_hz: float, degree: int, quiet_hz: float,
                    wide_hz: float, extra: int
                    ) -> tuple[np.ndarray, np.ndarray, int, float] | None:
    """For the two designs of :func:`needs_wide_band` (quiet band without extra sequences,
    wide band with ``extra``): ``[Q_q Q_w W_q' W_w']`` (``(n, p_q + p_w + 4)``), ``W_w``
    (both C order), ``p_q`` and the F test's critical value (NaN without degrees of
    freedom). Q is an orthonormal basis of a design D (CholeskyQR2 from its factor,
    :func:`~torquemod.dsp.projection.orthonormal_basis_t`) and W the modulation's two rows
    of D's pseudo-inverse ``(Q'D)^-1 Q'``: ``W x`` is the modulation's least-squares
    coefficients of a record x, ``x - Q Q'x`` its residual. None when either design has no
    factor or basis (the refined solves' route). Cached, read-only: the designs depend on
    the record's length and the configuration only."""
    qs, ws = [], []
    for band, ext in ((quiet_hz, 0), (wide_hz, extra)):
        design, fac = _wide_band_design(n, fs_hz, modulation_hz, band, ext, degree)
        qt = orthonormal_basis_t(fac, compiled=True) if fac is not None else None
        if qt is None:
            return None
        qs.append(qt)
        # the first two rows of (Q'D)^-1 Q': (Q'D)' z_i = e_i, W = [z_0 z_1]' Q'
        z = np.linalg.solve((qt @ design).T, np.eye(design.shape[1], 2))
        ws.append(z.T @ qt)
    maps_t = np.ascontiguousarray(np.vstack([*qs, *ws]).T)
    wheel_mod = np.ascontiguousarray(ws[1])
    for a in (maps_t, wheel_mod):
        a.setflags(write=False)
    p_q, p_w = qs[0].shape[0], qs[1].shape[0]
    dfn, dfd = p_w - p_q, n - p_w
    return maps_t, wheel_mod, p_q, \
        _f_critical(dfn, dfd) if dfn > 0 and dfd > 0 else float("nan")


@functools.lru_cache(maxsize=32)
def _wide_band_design(n: int, fs_hz: float, modulation_hz: float, band_hz: float, extra: int,
                      degree: int) -> tuple[np.ndarray, LstsqFactor | None]:
    """One design of :func:`needs_wide_band`, ``[cos, sin, slow_basis(band_hz)]`` with time
    from the record's middle, and its least-squares factor (None: :func:`lstsq` falls back
    to the SVD); cached, read-only."""
    t = (np.arange(n) - (n - 1) / 2) / fs_hz
    mod = np.column_stack([np.cos(2 * np.pi * modulation_hz * t),
                           np.sin(2 * np.pi * modulation_hz * t)])
    design = np.hstack([mod, slow_basis(n, fs_hz, band_hz, extra=extra, degree=degree)])
    design.setflags(write=False)
    fac = LstsqFactor.of(design)
    if fac is not None:
        fac.factor.setflags(write=False)
    return design, fac
