"""A tone (with its harmonics) fitted beside a fixed basis at many trial frequencies: the
variable-projection search of the modulation frequency (Golub and Pereyra 1973) needs, at
each trial frequency f, the power a record's residual on the basis B keeps along the tone's
columns M(f) once those are made orthogonal to B (Frisch-Waugh-Lovell).

With Q an orthonormal basis of B's span and ``C = Q'M``, the residual ``r_M = M - Q C`` gives
``r_M'r_M = M'M - C'C`` and ``r_M'r_y = M'r_y - C'Q'r_y``: one matrix product per batch of
trial frequencies instead of a least-squares solve per frequency, and small systems of
2 x (harmonics + 1) unknowns, all in one compiled call (:func:`explained_power`).

Q comes from the design's Cholesky factor by CholeskyQR2 (Fukaya, Nakatsukasa, Yanagisawa and
Yamamoto 2014, "CholeskyQR2: a simple and communication-avoiding algorithm for computing a
tall-skinny QR factorization", ScalA'14): ``Q1 = D R^-1`` from the normal equations' factor
R, then ``Q = Q1 R2^-1`` with R2 the Cholesky factor of ``Q1'Q1``; orthonormal to rounding
for condition numbers below ~1e8 (the chain's designs are refused by
:class:`~torquemod.dsp.lstsq.LstsqFactor` long before that).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy import linalg

from torquemod.dsp import numpyblas
from torquemod.dsp.lstsq import _DPOTRF, LstsqFactor, _cholesky, _fortran_call

_TRTRS, _POTRF = linalg.get_lapack_funcs(("trtrs", "potrf"), (np.zeros((1, 1)),))


def orthonormal_basis_t(factor: LstsqFactor, *, compiled: bool = False) -> np.ndarray | None:
    """An orthonormal basis of a design's span by CholeskyQR2, transposed.

    Parameters
    ----------
    factor : LstsqFactor
        The design's least-squares factor (its column-normalised design ``dn`` and the upper
        Cholesky factor R of ``dn'dn``).
    compiled : bool
        False (default): LAPACK's triangular solves (``trtrs``). True: one compiled call,
        the triangular solves by row operations over the samples and the second factor by
        LAPACK's ``potrf``; 2-3x faster on the chain's designs, the same span and as
        orthonormal (the basis itself differs from the default's by rounding amplified by
        the design's condition number: ~1e-10 relative at 1e6).

    Returns
    -------
    ndarray or None
        ``Q'`` (``p x n``, C order) with ``Q = dn R^-1 R2^-1`` orthonormal to rounding
        (Fukaya et al. 2014); None when a triangular solve or the second factorisation
        fails (a design too ill-conditioned for it).
    """
    if compiled:
        qt, ok = _cholesky_qr2_t(factor.dn, factor.factor, _DPOTRF)
        return qt if ok else None
    qt1, info = _TRTRS(factor.factor, factor.dn.T, lower=False, trans=1)  # R^-T D'
    if info != 0:
        return None
    r2, info = _POTRF(qt1 @ qt1.T, lower=False, clean=True)
    if info != 0:
        return None
    qt, info = _TRTRS(r2, qt1, lower=False, trans=1)
    if info != 0:
        return None
    return np.ascontiguousarray(qt)


@numba.njit(cache=True, nogil=True)
def _cholesky_qr2_t(dn: np.ndarray, r: np.ndarray, potrf: int) -> tuple[np.ndarray, bool]:
    """``Q' = R2^-T R^-T dn'`` (CholeskyQR2 from the factor R of ``dn'dn``, upper triangle
    read) and whether every step succeeded."""
    p, n = dn.shape[1], dn.shape[0]
    qt1 = np.empty((p, n))
    ok = _forward_rows(r, dn.T, qt1)  # R^-T dn'
    if not ok:
        return qt1, False
    r2, status = _cholesky(np.asfortranarray(np.dot(qt1, qt1.T)), potrf)
    if status == 2:  # (a condition number above 1e10 is fine here: R2 is close to I)
        return qt1, False
    qt = np.empty((p, n))
    ok = _forward_rows(r2, qt1, qt)
    return qt, ok


@numba.njit(cache=True, nogil=True)
def _forward_rows(r: np.ndarray, b: np.ndarray, out: np.ndarray) -> bool:
    """``out = R^-T b`` for an upper triangular R (upper triangle read), row by row:
    ``out_i = (b_i - sum_{j<i} R[j, i] out_j)/R[i, i]``, each an operation over the rows'
    samples; False on a zero diagonal element."""
    p, n = b.shape
    for i in range(p):
        d = r[i, i]
        if d == 0.0:
            return False
        oi = out[i]
        for t in range(n):
            oi[t] = b[i, t]
        for j in range(i):
            c = r[j, i]
            oj = out[j]
            for t in range(n):
                oi[t] -= c * oj[t]
        for t in range(n):
            oi[t] /= d
    return True


def powers_in_span(qt_b: np.ndarray, m: np.ndarray, v: np.ndarray) -> np.ndarray | None:
    """The power of each column of ``v`` in the span of a basis and further columns:
    ``|Q'v_j|^2`` for Q an orthonormal basis of ``[B, M]``, given ``Q_B'`` of B.

    ``|Q'v|^2 = |Q_B'v|^2 + b'(R'R)^-1 b`` with ``R = M - Q_B Q_B'M`` (one classical
    Gram-Schmidt pass: R's share along Q_B, ~1e-16 of M, moves the power by as little
    where M keeps a good part of its norm, which is what is asked) and ``b = R'v``: the
    projection on ``[B, M]`` split into B's and that of M's part orthogonal to B
    (Frisch-Waugh-Lovell), from the basis of B and a few small products instead of an
    orthonormal basis of the whole design.

    Parameters
    ----------
    qt_b : ndarray
        ``Q_B'`` (``p x n``, rows orthonormal).
    m : ndarray
        ``(n, k)`` further columns, any unit.
    v : ndarray
        ``(n, j)`` vectors, any unit.

    Returns
    -------
    ndarray or None
        ``(j,)`` powers [``v``'s unit squared]; None when M's part orthogonal to B is
        (nearly) rank deficient (a column of R keeps less than 1e-5 of its column of M's
        norm, or a pivot of ``R'R``'s Cholesky factorisation falls below 1e-10 of its
        diagonal element).
    """
    powers, ok = _powers_in_span(np.ascontiguousarray(qt_b, dtype=np.float64),
                                 np.ascontiguousarray(m.T, dtype=np.float64),
                                 np.ascontiguousarray(v, dtype=np.float64))
    return powers if ok else None


@numba.njit(cache=True, nogil=True)
def _powers_in_span(qt_b: np.ndarray, mt: np.ndarray, v: np.ndarray
                    ) -> tuple[np.ndarray, bool]:
    """:func:`powers_in_span` with M given transposed (``k x n``), in one call: the products
    by BLAS (``np.dot``), ``R'R``'s Cholesky factor and its two triangular solves by hand
    (k is a few columns); ``(powers, ok)``."""
    k, j = mt.shape[0], v.shape[1]
    rt = mt - np.dot(np.dot(mt, qt_b.T), qt_b)
    gram = np.dot(rt, rt.T)
    for i in range(k):  # a column left with less than 1e-5 of its norm: (nearly) in B
        norm2 = 0.0
        for t in range(mt.shape[1]):
            norm2 += mt[i, t] * mt[i, t]
        if not gram[i, i] > 1e-10 * norm2:
            return np.empty(0), False
    low = np.zeros((k, k))  # gram = L L'
    for i in range(k):
        for c in range(i + 1):
            acc = gram[i, c]
            for q in range(c):
                acc -= low[i, q] * low[c, q]
            if i == c:
                if not acc > 1e-10 * gram[i, i]:  # (and NaN)
                    return np.empty(0), False
                low[i, i] = math.sqrt(acc)
            else:
                low[i, c] = acc / low[c, c]
    pb = np.dot(qt_b, v)
    b = np.dot(rt, v)
    powers = np.zeros(j)
    y = np.empty(k)
    for col in range(j):
        for i in range(k):  # L y = b, then |y|^2 = b'(L L')^-1 b
            acc = b[i, col]
            for q in range(i):
                acc -= low[i, q] * y[q]
            y[i] = acc / low[i, i]
        acc = 0.0
        for i in range(pb.shape[0]):
            acc += pb[i, col] * pb[i, col]
        for i in range(k):
            acc += y[i] * y[i]
        powers[col] = acc
    return powers, True


def removal_at(m: np.ndarray, qt: np.ndarray, r_y: np.ndarray, qy: np.ndarray
               ) -> np.ndarray | None:
    """Records less their projection on a basis and a tone: ``r_y + Q C c_M`` with
    ``C = Q'M`` and ``c_M`` the solution of ``(M'M - C'C) c_M = M'r_y - C'Q'r_y``
    (Frisch-Waugh-Lovell), with numpy's numbers (its BLAS calls for the products and the
    ``dgesv`` of ``numpy.linalg.solve``) in one compiled call.

    Parameters
    ----------
    m : ndarray
        ``(n, k2)`` C-ordered tone columns, ``k2 >= 2``.
    qt : ndarray
        ``Q'`` (``p x n``, C order, ``p >= 2``) of an orthonormal basis Q
        (:func:`orthonormal_basis_t`).
    r_y : ndarray
        ``(n, k)`` C-ordered records less their projection on Q, ``k >= 2``.
    qy : ndarray
        ``Q' r_y`` (``p x k``, C order).

    Returns
    -------
    ndarray or None
        ``(n, k)`` records; None where numpy's routines cannot be called
        (:mod:`torquemod.dsp.numpyblas`), the layouts are not those the kernel reproduces,
        or the system is singular (``numpy.linalg.solve`` raises there): the caller takes
        numpy's route.
    """
    blas, gesv = numpyblas.addresses(), numpyblas.gesv_address()
    arrays = (m, qt, r_y, qy)
    if (blas is None or gesv is None or any(a.ndim != 2 or a.shape[0] < 2 or a.shape[1] < 2
                                            or a.dtype != np.float64
                                            or not a.flags.c_contiguous for a in arrays)):
        return None
    out, ok = _removal_at(m, qt, r_y, qy, blas[0], blas[1], gesv)
    return out if ok else None


@numba.njit(cache=True, nogil=True)
def _removal_at(m, qt, r_y, qy, syrk, gemm, gesv):
    """:func:`removal_at` in one call: numpy's ``syrk`` for ``M'M`` and ``C'C``, its
    ``gemm`` for the other products, its ``dgesv`` on Fortran-ordered copies as
    ``numpy.linalg.solve``; ``(out, ok)``."""
    c = numpyblas.matmul(qt, m, gemm)
    a = np.asfortranarray(numpyblas.gram_t(m, syrk) - numpyblas.gram_t(c, syrk))
    b = np.asfortranarray(numpyblas.matmul_tn(m, r_y, gemm) - numpyblas.matmul_tn(c, qy, gemm))
    k2, k = b.shape
    ints = np.array([k2, k, k2, k2, 0], dtype=np.int64)  # n, nrhs, lda, ldb, info
    ipiv = np.zeros(k2, dtype=np.int64)
    q = ints.ctypes.data
    _fortran_call(gesv, (q, q + 8, a.ctypes.data, q + 16, ipiv.ctypes.data, b.ctypes.data,
                         q + 24, q + 32))
    if ints[4] != 0:
        return r_y, False
    c_m = np.ascontiguousarray(b)
    return r_y + numpyblas.matmul_any(qt.T, numpyblas.matmul(c, c_m, gemm), gemm), True


def removal_at_tone(fs_hz: float, modulation_hz: float, orders, qt: np.ndarray,
                    r_y: np.ndarray, qy: np.ndarray) -> np.ndarray | None:
    """:func:`removal_at` with the tone's columns made in the same compiled call:
    ``cos(2*pi*k*f*t)`` and ``sin(2*pi*k*f*t)`` for each order k, t from the record's
    middle, each from libm at its own argument ``(k*w)*t`` (``w = 2*pi*f``) as
    :func:`torquemod.processing.speedmodel.modulation_columns` forms it with numpy (the
    same numbers where numpy's ``cos`` and ``sin`` are libm's, as on x86-64 Linux).

    Parameters
    ----------
    fs_hz : float
        Sample rate [Hz].
    modulation_hz : float
        The tone's frequency f [Hz].
    orders : sequence of int
        The tone's orders (1 and its harmonics).
    qt, r_y, qy : ndarray
        As :func:`removal_at` (``r_y`` has the records' n samples).

    Returns
    -------
    ndarray or None
        As :func:`removal_at`.
    """
    blas, gesv = numpyblas.addresses(), numpyblas.gesv_address()
    arrays = (qt, r_y, qy)
    if (blas is None or gesv is None or any(a.ndim != 2 or a.shape[0] < 2 or a.shape[1] < 2
                                            or a.dtype != np.float64
                                            or not a.flags.c_contiguous for a in arrays)):
        return None
    out, ok = _removal_at_tone(float(fs_hz), 2 * np.pi * float(modulation_hz),
                               np.asarray(orders, dtype=np.int64), qt, r_y, qy,
                               blas[0], blas[1], gesv)
    return out if ok else None


@numba.njit(cache=True, nogil=True)
def _removal_at_tone(fs_hz, w, orders, qt, r_y, qy, syrk, gemm, gesv):
    """:func:`removal_at_tone` in one call: the columns (``n x 2*len(orders)``, C order),
    then :func:`_removal_at`; ``(out, ok)``."""
    n = r_y.shape[0]
    half = (n - 1) / 2.0
    m = np.empty((n, 2 * orders.size))
    for j in range(orders.size):
        kw = orders[j] * w
        for i in range(n):
            a = kw * ((i - half) / fs_hz)
            m[i, 2 * j] = math.cos(a)
            m[i, 2 * j + 1] = math.sin(a)
    return _removal_at(m, qt, r_y, qy, syrk, gemm, gesv)


def tone_columns(n: int, fs_hz: float, frequencies_hz, orders=(1,)) -> np.ndarray:
    """Cosine and sine columns of tones and their harmonics, time from the record's middle.

    Parameters
    ----------
    n : int
        Samples.
    fs_hz : float
        Sample rate [Hz]; sample i is at ``t = (i - (n-1)/2)/fs_hz`` [s].
    frequencies_hz : sequence of float
        Fundamental frequencies f [Hz].
    orders : sequence of int
        Orders k (1 for the fundamental, 2, 3, ... for its harmonics).

    Returns
    -------
    ndarray
        ``n x 2*len(frequencies_hz)*len(orders)``: for each f, for each k, ``cos(2*pi*k*f*t)``
        then ``sin(2*pi*k*f*t)``; the columns of
        :func:`torquemod.processing.speedmodel.modulation_columns` side by side to ~1e-14
        (exact every 32 samples, rotated by one sample's angle between, the harmonics as
        powers of the fundamental's phasor).
    """
    out = np.empty((2 * len(frequencies_hz) * len(orders), n))
    _fill_tones_t(out, float(fs_hz), 2 * np.pi * np.asarray(frequencies_hz, dtype=np.float64),
                  np.asarray(orders, dtype=np.int64))
    return out.T


@numba.njit(cache=True, nogil=True)
def _fill_tones_t(out: np.ndarray, fs_hz: float, omegas: np.ndarray, orders: np.ndarray
                  ) -> None:
    """Rows of ``out`` (``2*len(omegas)*len(orders) x n``): for each angular frequency w
    [rad/s] and order k, ``cos(k*w*t)`` then ``sin(k*w*t)`` over ``t = (i - (n-1)/2)/fs``.

    The fundamental's phasor is exact (libm) at every 32nd sample and rotated by one
    sample's angle between; the blocks of 32 samples are rotated side by side (independent
    recurrences, so the loop over the blocks runs on SIMD lanes), each sample by the same
    operations as one block at a time. The harmonics are powers of the fundamental's phasor,
    ``(c, s) <- (c c1 - s s1, s c1 + c s1)`` from ``(1, 0)``, for all samples at once.
    """
    n = out.shape[1]
    nk = orders.size
    k_max = 1
    for k in orders:
        k_max = max(k_max, k)
    half = (n - 1) / 2.0
    nb = (n + 31) // 32
    cb = np.empty((32, nb))  # cb[j, b]: sample 32*b + j
    sb = np.empty((32, nb))
    c1, s1 = np.empty(n), np.empty(n)
    ck, sk = np.empty(n), np.empty(n)
    for f in range(omegas.size):
        w = omegas[f]
        cd, sd = math.cos(w / fs_hz), math.sin(w / fs_hz)
        for b in range(nb):  # exact, then rotated by one sample
            a = w * ((32 * b - half) / fs_hz)
            cb[0, b] = math.cos(a)
            sb[0, b] = math.sin(a)
        for j in range(1, 32):
            cp, sp, cn, sn = cb[j - 1], sb[j - 1], cb[j], sb[j]
            for b in range(nb):
                cn[b] = cp[b] * cd - sp[b] * sd
                sn[b] = sp[b] * cd + cp[b] * sd
        for b in range(nb):
            for j in range(min(32, n - 32 * b)):
                c1[32 * b + j] = cb[j, b]
                s1[32 * b + j] = sb[j, b]
        ck[:] = 1.0
        sk[:] = 0.0
        for k in range(1, k_max + 1):
            for i in range(n):
                c, s = ck[i], sk[i]
                ck[i] = c * c1[i] - s * s1[i]
                sk[i] = s * c1[i] + c * s1[i]
            for j in range(nk):
                if orders[j] == k:
                    row = 2 * (f * nk + j)
                    out[row] = ck
                    out[row + 1] = sk


def explained_power(qt: np.ndarray, r_y: np.ndarray, qy: np.ndarray, fs_hz: float,
                    frequencies_hz, columns, orders=(1,)) -> np.ndarray:
    """Power of a record's residual that a tone explains beyond a basis, at many trial
    frequencies in one compiled call.

    For each i, ``r_y' r_M (r_M'r_M)^-1 r_M' r_y`` with ``r_y`` record ``columns[i]`` less its
    least-squares fit on the basis and ``r_M`` the tone's columns at ``frequencies_hz[i]``
    (:func:`tone_columns`) less their projection on it (Frisch-Waugh-Lovell):
    ``r_M'r_M = M'M - C'C`` and ``r_M'r_y = M'r_y - C'Q'r_y`` with ``C = Q'M``.

    Parameters
    ----------
    qt : ndarray
        ``Q'`` (``p x n``) of an orthonormal basis Q of the basis's span
        (:func:`orthonormal_basis_t`).
    r_y : ndarray
        Records less their fit on the basis (``n x records``).
    qy : ndarray
        ``Q' r_y`` (``p x records``; zero to rounding).
    fs_hz : float
        Sample rate [Hz]; time runs from the record's middle.
    frequencies_hz, columns : sequence
        Trial frequency [Hz] and record index of each evaluation.
    orders : sequence of int
        The tone's orders (1 and its harmonics).

    Returns
    -------
    ndarray
        The explained power of each evaluation [record unit^2]; NaN where the tone's
        columns are (numerically) in the basis's span.
    """
    return _explained(qt, np.ascontiguousarray(r_y), np.ascontiguousarray(qy), float(fs_hz),
                      2 * np.pi * np.asarray(frequencies_hz, dtype=np.float64),
                      np.asarray(columns, dtype=np.int64), np.asarray(orders, dtype=np.int64))


def refine_peaks(qt: np.ndarray, r_y: np.ndarray, qy: np.ndarray, fs_hz: float,
                 duration_s: float, columns, peaks_hz, orders=(1,), *,
                 tol_hz: float = 1e-6) -> list[float]:
    """The frequencies near ``peaks_hz`` at which a tone explains most of each record beyond
    a basis (variable projection, Golub and Pereyra 1973): parabolic steps through three
    values of :func:`explained_power`, ``0.05/T``, ``0.005/T`` and ``0.0005/T`` apart (T the
    record's duration), each from the previous vertex, until a step is below ``tol_hz``; a
    record whose explained power is not concave there keeps its peak. All the records
    advance in step, in one compiled call.

    Parameters
    ----------
    qt, r_y, qy : ndarray
        As :func:`explained_power`.
    fs_hz : float
        Sample rate [Hz].
    duration_s : float
        The records' duration T [s] (samples over the rate).
    columns, peaks_hz : sequence
        Record index and starting frequency [Hz] of each search.
    orders : sequence of int
        The tone's orders (1 and its harmonics).
    tol_hz : float
        Step below which a search stops [Hz]. Default 1e-6.

    Returns
    -------
    list of float
        The refined frequencies [Hz].
    """
    out = _refine(qt, np.ascontiguousarray(r_y), np.ascontiguousarray(qy), float(fs_hz),
                  float(duration_s), np.asarray(columns, dtype=np.int64),
                  np.asarray(peaks_hz, dtype=np.float64), np.asarray(orders, dtype=np.int64),
                  float(tol_hz))
    return [float(v) for v in out]


@numba.njit(cache=True, nogil=True)
def _refine(qt, r_y, qy, fs_hz, duration, columns, peaks, orders, tol_hz):
    """:func:`refine_peaks` in one call: each step's explained powers of every active
    search from one :func:`_explained` evaluation, the steps' arithmetic as Python's on
    floats."""
    f = peaks.copy()
    active = np.ones(peaks.size, dtype=np.bool_)
    two_pi = 2 * np.pi
    for h in (0.05 / duration, 0.005 / duration, 0.0005 / duration):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        omegas = np.empty(3 * idx.size)
        cols = np.empty(3 * idx.size, dtype=np.int64)
        for j in range(idx.size):
            i = idx[j]
            omegas[3 * j] = two_pi * (f[i] + -1.0 * h)
            omegas[3 * j + 1] = two_pi * (f[i] + 0.0 * h)
            omegas[3 * j + 2] = two_pi * (f[i] + 1.0 * h)
            cols[3 * j] = cols[3 * j + 1] = cols[3 * j + 2] = columns[i]
        e = _explained(qt, r_y, qy, fs_hz, omegas, cols, orders)
        for j in range(idx.size):
            i = idx[j]
            e_lo, e_0, e_hi = e[3 * j], e[3 * j + 1], e[3 * j + 2]
            curvature = e_lo - 2.0 * e_0 + e_hi
            active[i] = False
            if not curvature < 0:  # not near a maximum: the spectral peak's value
                f[i] = peaks[i]
                continue
            step = 0.5 * h * (e_lo - e_hi) / curvature
            lo, hi = -2.0 * h, 2.0 * h
            step = lo if lo > step else step  # Python's max(step, lo), min(., hi)
            step = hi if hi < step else step
            f[i] += step
            if not abs(step) < tol_hz:
                active[i] = True
    return f


@numba.njit(cache=True, nogil=True)
def _explained(qt: np.ndarray, r_y: np.ndarray, qy: np.ndarray, fs_hz: float,
               omegas: np.ndarray, columns: np.ndarray, orders: np.ndarray) -> np.ndarray:
    """:func:`explained_power` in one compiled call (the basis products by BLAS)."""
    n = r_y.shape[0]
    p = qt.shape[0]
    k2 = 2 * orders.size
    rows = np.empty((omegas.size * k2 + r_y.shape[1], n))  # M' and then r_y'
    mt = rows[:omegas.size * k2]
    _fill_tones_t(mt, fs_hz, omegas, orders)
    rows[omegas.size * k2:] = r_y.T
    ct = mt @ qt.T  # (M'Q): C' row by row
    out = np.empty(omegas.size)
    g = np.empty((k2, k2))
    b = np.empty(k2)
    # the products r_M'r_y (k2) and the lower triangle of M'M (k2*(k2+1)/2) of one
    # frequency: jobs (row of mt, other vector, target), 8 dot products per pass over the
    # samples (each summed in sample order as one at a time: the same numbers, without
    # waiting on one sum's additions)
    n_jobs = k2 + k2 * (k2 + 1) // 2
    job_a = np.empty(n_jobs, dtype=np.int64)
    job_d = np.empty(n_jobs, dtype=np.int64)
    sums = np.empty(n_jobs)
    n_tone_rows = omegas.size * k2
    for f in range(omegas.size):
        o = f * k2
        col = columns[f]
        q = 0
        for a in range(k2):
            job_a[q] = o + a
            job_d[q] = n_tone_rows + col  # the record's residual, a row after the tones
            q += 1
            for d in range(a + 1):
                job_a[q] = o + a
                job_d[q] = o + d
                q += 1
        for start in range(0, n_jobs, 8):
            _dots8(rows, job_a, job_d, start, min(start + 8, n_jobs), sums)
        q = 0
        for a in range(k2):
            s = sums[q]
            q += 1
            for j in range(p):
                s -= ct[o + a, j] * qy[j, col]
            b[a] = s
            for d in range(a + 1):
                s = sums[q]
                q += 1
                for j in range(p):
                    s -= ct[o + a, j] * ct[o + d, j]
                g[a, d] = s
        # b' g^-1 b by the Cholesky factor of g (lower, in place): |L^-1 b|^2
        ok = True
        for a in range(k2):
            for d in range(a + 1):
                s = g[a, d]
                for j in range(d):
                    s -= g[a, j] * g[d, j]
                if a == d:
                    if not s > 0:
                        ok = False
                        break
                    g[a, a] = math.sqrt(s)
                else:
                    g[a, d] = s / g[d, d]
            if not ok:
                break
        if not ok:
            out[f] = np.nan
            continue
        e = 0.0
        for a in range(k2):
            s = b[a]
            for j in range(a):
                s -= g[a, j] * b[j]
            b[a] = s / g[a, a]
            e += b[a] * b[a]
        out[f] = e
    return out


@numba.njit(cache=True, nogil=True)
def _dots8(rows: np.ndarray, job_a: np.ndarray, job_d: np.ndarray, start: int, stop: int,
           sums: np.ndarray) -> None:
    """``sums[q] = rows[job_a[q]] . rows[job_d[q]]`` for q in ``start:stop`` (at most 8):
    eight running sums at once, each over the samples in order (the numbers of one sum at a
    time)."""
    last = stop - 1
    x0, y0 = rows[job_a[start]], rows[job_d[start]]
    x1, y1 = rows[job_a[min(start + 1, last)]], rows[job_d[min(start + 1, last)]]
    x2, y2 = rows[job_a[min(start + 2, last)]], rows[job_d[min(start + 2, last)]]
    x3, y3 = rows[job_a[min(start + 3, last)]], rows[job_d[min(start + 3, last)]]
    x4, y4 = rows[job_a[min(start + 4, last)]], rows[job_d[min(start + 4, last)]]
    x5, y5 = rows[job_a[min(start + 5, last)]], rows[job_d[min(start + 5, last)]]
    x6, y6 = rows[job_a[min(start + 6, last)]], rows[job_d[min(start + 6, last)]]
    x7, y7 = rows[job_a[min(start + 7, last)]], rows[job_d[min(start + 7, last)]]
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = 0.0
    for i in range(rows.shape[1]):
        s0 += x0[i] * y0[i]
        s1 += x1[i] * y1[i]
        s2 += x2[i] * y2[i]
        s3 += x3[i] * y3[i]
        s4 += x4[i] * y4[i]
        s5 += x5[i] * y5[i]
        s6 += x6[i] * y6[i]
        s7 += x7[i] * y7[i]
    acc = (s0, s1, s2, s3, s4, s5, s6, s7)
    for q in range(stop - start):
        sums[start + q] = acc[q]
