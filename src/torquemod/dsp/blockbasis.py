"""An orthonormal basis of ``[S, O]`` from one of a fixed block S and a few further columns O.

The chain's step 1 removes, from each cycle, its slow part and rotation orders: it needs an
orthonormal basis of ``B = [S, O]`` with S the slow basis (the same for every cycle of a
given length and band, ~20 columns) and O the tracked orders (a few columns, new each
cycle). Block Gram-Schmidt (Golub & Van Loan, *Matrix Computations*, 4th ed., section
5.2.8): with ``Q_S`` an orthonormal basis of S, made once per S, the orders' part
orthogonal to S is ``R = O_n - Q_S Q_S'O_n`` (``O_n`` the orders with unit-norm columns;
classical Gram-Schmidt applied twice, "twice is enough": Giraud, Langou, Rozloznik and van
den Eshof 2005, Numer. Math. 101), and ``Q_O`` comes from R by CholeskyQR2 (Fukaya,
Nakatsukasa, Yanagisawa and Yamamoto 2014, ScalA'14): ``Q = [Q_S, Q_O]`` spans B and is
orthonormal to rounding. Per cycle this costs a few products with the ``p x n`` rows of
``Q_S`` instead of a factorisation and CholeskyQR2 of the whole ``n x (p + k)`` design.

The diagonal of R's Cholesky factor holds the residual norms of the normalised order
columns on S and the orders before them, which are the diagonal elements of the whole
normalised design's Cholesky factor past S's block: the rank decision of
:meth:`torquemod.dsp.lstsq.LstsqFactor.of` can be read from it.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from torquemod.dsp import numpyblas
from torquemod.dsp.lstsq import LstsqFactor, _sums_of_squares
from torquemod.dsp.projection import _removal_at, orthonormal_basis_t

#: the smallest squared pivot (diagonal element of the normalised design's Cholesky factor,
#: 1 at best) at which :func:`removal_basis` extends the slow basis's own; 100x above the
#: 1e-10 at which :meth:`~torquemod.dsp.lstsq.LstsqFactor.of` refuses a design, so that
#: near that limit the decision stays LstsqFactor.of's own
MIN_PIVOT = 1e-8

#: Q_S' and Q_S'S of read-only slow bases S (one per record length and band), by id
_SLOW_BASES: dict[int, tuple[np.ndarray, tuple[np.ndarray, np.ndarray] | None]] = {}

#: Q_S (C order) of the read-only Q_S' that :func:`slow_basis_t` keeps, by id
_SLOW_BASES_Q: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def slow_basis_t(slow: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``Q_S'`` of an orthonormal basis of a basis S (CholeskyQR2 from its least-squares
    factor, :func:`~torquemod.dsp.projection.orthonormal_basis_t`) and S's triangular factor
    ``Q_S'S``.

    Parameters
    ----------
    slow : ndarray
        ``(n, p)`` columns S. A read-only S's result is kept (by identity; the chain's slow
        bases are made once per record length and band).

    Returns
    -------
    tuple of ndarray or None
        ``(Q_S', Q_S'S)``, read-only; None where S's factor fails or its smallest squared
        pivot is below :data:`MIN_PIVOT`.
    """
    key = id(slow)
    hit = _SLOW_BASES.get(key)
    if hit is not None and hit[0] is slow:
        return hit[1]
    fac = LstsqFactor.of(np.ascontiguousarray(slow))
    out = None
    if fac is not None and float(np.min(np.diag(fac.factor)) ** 2) >= MIN_PIVOT:
        qs_t = orthonormal_basis_t(fac)
        if qs_t is not None:
            out = (qs_t, np.triu(qs_t @ slow))
            for a in out:
                a.setflags(write=False)
    if not slow.flags.writeable:
        if len(_SLOW_BASES) >= 32:
            _SLOW_BASES.pop(next(iter(_SLOW_BASES)))
        _SLOW_BASES[key] = (slow, out)
    return out


def removal_basis(y: np.ndarray, slow: np.ndarray, orders: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``Q'``, ``y - Q Q'y`` and ``Q'(y - Q Q'y)`` for Q an orthonormal basis of
    ``[slow, orders]`` extended from the slow basis's own (:func:`slow_basis_t`,
    :func:`extended_basis_t`).

    Parameters
    ----------
    y : ndarray
        ``(n, c)`` records.
    slow, orders : ndarray
        ``(n, p)`` and ``(n, k)`` columns.

    Returns
    -------
    tuple of ndarray or None
        None where a pivot falls below :data:`MIN_PIVOT` (the whole design's factor should
        then decide), or without orders, or with fewer than two slow columns.
    """
    out = removal_basis_at(y, slow, orders, None)
    return None if out is None else out[:3]


def removal_basis_at(y: np.ndarray, slow: np.ndarray, orders: np.ndarray,
                     tone: np.ndarray | None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None] | None:
    """:func:`removal_basis` and, in the same compiled call, the records less their
    projection on the basis and a tone's columns
    (:func:`torquemod.dsp.projection.removal_at`, the same numbers).

    Parameters
    ----------
    y : ndarray
        ``(n, c)`` records.
    slow, orders : ndarray
        ``(n, p)`` and ``(n, k)`` columns.
    tone : ndarray or None
        ``(n, k2)`` tone columns (C order), or None for the basis alone.

    Returns
    -------
    tuple or None
        ``(Q', y - Q Q'y, Q'(y - Q Q'y), removed)``, ``removed`` None without a tone or
        where :func:`~torquemod.dsp.projection.removal_at` would return None; None as
        :func:`removal_basis`.
    """
    if orders.shape[1] == 0 or slow.shape[1] < 2 or y.ndim != 2:
        return None
    slow_t = slow_basis_t(slow)
    if slow_t is None:
        return None
    qs_t = slow_t[0]
    hit = _SLOW_BASES_Q.get(id(qs_t))
    if hit is None or hit[0] is not qs_t:  # Q_S itself, kept with a kept Q_S'
        hit = (qs_t, np.ascontiguousarray(qs_t.T))
        if not slow.flags.writeable:
            if len(_SLOW_BASES_Q) >= 32:
                _SLOW_BASES_Q.pop(next(iter(_SLOW_BASES_Q)))
            _SLOW_BASES_Q[id(qs_t)] = hit
    cols = np.ascontiguousarray(orders, dtype=np.float64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    blas, gesv = numpyblas.addresses(), numpyblas.gesv_address()
    if (tone is not None and blas is not None and gesv is not None and y.shape[1] >= 2
            and tone.ndim == 2 and tone.shape[1] >= 2 and tone.dtype == np.float64
            and tone.flags.c_contiguous):  # (the layouts removal_at's kernel takes)
        qt, r_y, qy, pivot, ok, removed, removed_ok = _extended_basis_and_removal(
            qs_t, hit[1], cols, y, tone, blas[0], blas[1], gesv)
        if not removed_ok:
            removed = None
    else:
        qt, r_y, qy, pivot, ok = _extended_basis_t(qs_t, hit[1], cols, y)
        removed = None
    if not ok or not pivot >= MIN_PIVOT:
        return None
    return qt, r_y, qy, removed


def extended_basis_t(qs_t: np.ndarray, cols: np.ndarray, y: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float] | None:
    """``Q'`` of an orthonormal basis of ``[S, cols]`` from ``Q_S'`` of S, and the records
    ``y`` less their projection on it.

    Parameters
    ----------
    qs_t : ndarray
        ``Q_S'`` (``p x n``, rows orthonormal).
    cols : ndarray
        ``(n, k)`` further columns (``k >= 1``), any unit.
    y : ndarray
        ``(n, c)`` records, any unit.

    Returns
    -------
    qt : ndarray
        ``(p + k, n)``: ``Q_S'`` and then ``Q_O'``, C order.
    r_y : ndarray
        ``y - Q Q'y`` (``n x c``).
    qy : ndarray
        ``Q' r_y`` (``(p + k) x c``, ~0).
    pivot : float
        The smallest squared diagonal element of the Cholesky factor of ``R'R``, R the
        normalised columns' part orthogonal to S and to the columns before them (1 at best).
    None
        Where a column is zero or not finite or ``R'R`` is not positive definite.
    """
    qs_t = np.ascontiguousarray(qs_t, dtype=np.float64)
    out = _extended_basis_t(qs_t, np.ascontiguousarray(qs_t.T),
                            np.ascontiguousarray(cols, dtype=np.float64),
                            np.ascontiguousarray(y, dtype=np.float64))
    qt, r_y, qy, pivot, ok = out
    if not ok:
        return None
    return qt, r_y, qy, float(pivot)


@numba.njit(cache=True, nogil=True)
def _cholesky_upper(g: np.ndarray) -> tuple[np.ndarray, bool]:
    """The upper Cholesky factor U (``g = U'U``) of a small symmetric matrix (its upper
    triangle read); False where a pivot is not positive."""
    k = g.shape[0]
    u = np.zeros((k, k))
    for j in range(k):
        s = g[j, j]
        for m in range(j):
            s -= u[m, j] * u[m, j]
        if not s > 0.0:
            return u, False
        d = math.sqrt(s)
        u[j, j] = d
        for i in range(j + 1, k):
            t = g[j, i]
            for m in range(j):
                t -= u[m, j] * u[m, i]
            u[j, i] = t / d
    return u, True


@numba.njit(cache=True, nogil=True)
def _times_inverse_t(u: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``U^-T a`` for an upper triangular ``k x k`` U and ``a`` of ``k`` rows: forward
    substitution, one row of samples at a time."""
    k, n = a.shape
    out = np.empty((k, n))
    for i in range(k):
        oi = out[i]
        oi[:] = a[i]
        for m in range(i):
            c = u[m, i]
            om = out[m]
            for t in range(n):
                oi[t] -= c * om[t]
        d = u[i, i]
        for t in range(n):
            oi[t] /= d
    return out


@numba.njit(cache=True, nogil=True)
def _extension(qs_t, cols):
    """``Q_O'`` (``k x n``) of the columns' part orthogonal to ``Q_S``, the smallest squared
    pivot and whether every step succeeded (see :func:`extended_basis_t`)."""
    return _extension_q(qs_t, np.ascontiguousarray(qs_t.T), cols)


@numba.njit(cache=True, nogil=True)
def _extension_q(qs_t, qs, cols):
    """:func:`_extension` given also ``Q_S`` (``n x p``, C order)."""
    n = qs_t.shape[1]
    k = cols.shape[1]
    rt = np.empty((k, n))  # the normalised columns, as rows
    sums = _sums_of_squares(cols)  # (each column's, over the samples in order)
    for j in range(k):
        s = sums[j]
        if not (s > 0.0 and s < np.inf):
            return rt, 0.0, False
        inv = 1.0 / math.sqrt(s)
        for t in range(n):
            rt[j, t] = cols[t, j] * inv
    for _ in range(2):  # classical Gram-Schmidt against Q_S, twice
        c = np.dot(rt, qs)  # (k, p) = R'Q_S
        rt = rt - np.dot(c, qs_t)
    u, ok = _cholesky_upper(np.dot(rt, rt.T))
    if not ok:
        return rt, 0.0, False
    pivot = 1.0
    for j in range(k):
        pivot = min(pivot, u[j, j] * u[j, j])
    q1 = _times_inverse_t(u, rt)  # (R U^-1)'
    u2, ok = _cholesky_upper(np.dot(q1, q1.T))
    if not ok:
        return rt, 0.0, False
    return _times_inverse_t(u2, q1), pivot, True


@numba.njit(cache=True, nogil=True)
def extension_t(qs_t, cols, min_pivot):
    """For compiled callers: ``(Q_O', ok)``, ``Q_O'`` (``k x n``) an orthonormal basis of
    the part of ``cols`` (``n x k``, C order) orthogonal to the rows of ``qs_t`` (the steps
    of :func:`extended_basis_t`); ok False where a column is zero or a squared pivot is
    below ``min_pivot``."""
    qo, pivot, ok = _extension(qs_t, cols)
    return qo, ok and pivot >= min_pivot


@numba.njit(cache=True, nogil=True)
def upper_solve(u: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``U^-1 b`` for the upper triangle of ``u`` (``m x m``) and ``b`` of m rows
    (back substitution), for compiled callers."""
    m, c = b.shape
    x = np.empty((m, c))
    for i in range(m - 1, -1, -1):
        for j in range(c):
            s = b[i, j]
            for l in range(i + 1, m):
                s -= u[i, l] * x[l, j]
            x[i, j] = s / u[i, i]
    return x


@numba.njit(cache=True, nogil=True)
def _extended_basis_t(qs_t, qs, cols, y):
    """:func:`extended_basis_t` given also ``Q_S`` (``n x p``, C order); ``(qt, r_y, qy,
    pivot, ok)``."""
    p, n = qs_t.shape
    k = cols.shape[1]
    qo, pivot, ok = _extension_q(qs_t, qs, cols)
    if not ok:
        e = np.empty((0, 0))
        return e, e, e, 0.0, False
    qt = np.empty((p + k, n))
    qt[:p] = qs_t
    qt[p:] = qo
    r_y = y - np.dot(qt.T, np.dot(qt, y))
    qy = np.dot(qt, r_y)
    return qt, r_y, qy, pivot, True


@numba.njit(cache=True, nogil=True)
def _extended_basis_and_removal(qs_t, qs, cols, y, tone, syrk, gemm, gesv):
    """:func:`_extended_basis_t` and then :func:`torquemod.dsp.projection._removal_at` on
    its result with the tone's columns; ``(qt, r_y, qy, pivot, ok, removed, removed_ok)``."""
    qt, r_y, qy, pivot, ok = _extended_basis_t(qs_t, qs, cols, y)
    if not ok or not pivot >= MIN_PIVOT:
        return qt, r_y, qy, pivot, ok, r_y, False
    removed, removed_ok = _removal_at(tone, qt, r_y, qy, syrk, gemm, gesv)
    return qt, r_y, qy, pivot, ok, removed, removed_ok
