"""Least squares beside a fixed basis through an orthonormal basis of it: with Q an
orthonormal basis of a basis B's span, a record's residual on B is ``y - Q Q'y``, and further
columns M are fitted beside B from the products ``C = Q'M`` (Frisch-Waugh-Lovell):
``r_M'r_M = M'M - C'C`` and ``r_M'r_y = M'r_y - C'Q'r_y``, small systems instead of a new
factorisation of the whole design (:func:`removal_at`, :func:`powers_in_span`; the search of
a tone's frequency is :mod:`torquemod.dsp.tonesearch`'s).

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
from torquemod.dsp.lstsq import (
    _DPOTRF,
    LstsqFactor,
    _cholesky,
    _fortran_call,
    _row_sums_of_squares,
)

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
    powers, ok, _ = _powers_in_span(np.ascontiguousarray(qt_b, dtype=np.float64),
                                 np.ascontiguousarray(m.T, dtype=np.float64),
                                 np.ascontiguousarray(v, dtype=np.float64))
    return powers if ok else None


@numba.njit(cache=True, nogil=True)
def _powers_in_span(qt_b: np.ndarray, mt: np.ndarray, v: np.ndarray
                    ) -> tuple[np.ndarray, bool, np.ndarray]:
    """:func:`powers_in_span` with M given transposed (``k x n``), in one call: the products
    by BLAS (``np.dot``), ``R'R``'s Cholesky factor and its two triangular solves by hand
    (k is a few columns); ``(powers, ok, G)`` with ``G = R'R``, the normal matrix of M's
    residuals on B, also where the powers are not made."""
    k, j = mt.shape[0], v.shape[1]
    rt = mt - np.dot(np.dot(mt, qt_b.T), qt_b)
    gram = np.dot(rt, rt.T)
    norms2 = _row_sums_of_squares(mt)
    for i in range(k):  # a column left with less than 1e-5 of its norm: (nearly) in B
        norm2 = norms2[i]
        if not gram[i, i] > 1e-10 * norm2:
            return np.empty(0), False, gram
    low = np.zeros((k, k))  # gram = L L'
    for i in range(k):
        for c in range(i + 1):
            acc = gram[i, c]
            for q in range(c):
                acc -= low[i, q] * low[c, q]
            if i == c:
                if not acc > 1e-10 * gram[i, i]:  # (and NaN)
                    return np.empty(0), False, gram
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
    return powers, True, gram


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
    same numbers where numpy's ``cos`` and ``sin`` are libm's, as on x86-64 Linux). The
    samples' times are symmetric about the middle to the bit and libm's cosine is even and
    its sine odd to the bit (it reduces the argument's magnitude), so the second half of
    the samples takes the first half's values: half the calls.

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
    """:func:`removal_at_tone` in one call: the columns (``n x 2*len(orders)``, C order;
    libm for the first half of the samples, the second half their mirror image), then
    :func:`_removal_at`; ``(out, ok)``."""
    n = r_y.shape[0]
    half = (n - 1) / 2.0
    m = np.empty((n, 2 * orders.size))
    for j in range(orders.size):
        kw = orders[j] * w
        for i in range(n // 2):
            # sample n-1-i is at -t exactly, its argument -a: cos(-a) = cos(a) and
            # sin(-a) = -sin(a) as libm rounds them (it reduces |a|)
            a = kw * ((i - half) / fs_hz)
            c, s = math.cos(a), math.sin(a)
            m[i, 2 * j], m[i, 2 * j + 1] = c, s
            m[n - 1 - i, 2 * j], m[n - 1 - i, 2 * j + 1] = c, -s
        if n % 2:  # the middle sample, t = 0
            a = kw * ((n // 2 - half) / fs_hz)
            m[n // 2, 2 * j], m[n // 2, 2 * j + 1] = math.cos(a), math.sin(a)
    return _removal_at(m, qt, r_y, qy, syrk, gemm, gesv)
