"""numpy's own BLAS products inside compiled code, with numpy's numbers.

The chain's phase is defined to its last bits by the rounding of the matrix products in its
least-squares fits: a wheel speed of ~30 rad/s carrying a ~2e-3 rad/s modulation turns one
ulp of its slow part into ~1e-10 deg of phase. A product computed any other way (numba's
``np.dot`` calls scipy's BLAS, a hand loop sums in another order) moves those bits. The
kernels here call the CBLAS routines of the OpenBLAS that numpy itself is linked against, at
their run-time addresses, with the arguments numpy's ``matmul`` passes for the same operands
(numpy/_core/src/umath/matmul.c.src): the same library, routine and arguments, so the same
numbers.

For C-ordered float64 operands whose every dimension is at least 2, ``matmul`` calls

* ``a.T @ a`` (one buffer on both sides): ``dsyrk(RowMajor, Upper, Trans, m, n, 1, a, m,
  0, c, m)`` and copies the upper triangle to the lower one;
* ``a @ b``: ``dgemm(RowMajor, NoTrans, NoTrans, m, p, n, 1, a, n, b, p, 0, c, p)``;
* ``a.T @ b`` (another buffer): ``dgemm(RowMajor, Trans, NoTrans, m, p, n, 1, a, m, b, p, 0,
  c, p)``;
* ``a @ x`` (a contiguous vector): ``dgemv(ColMajor, Trans, n, m, 1, a, n, x, 1, 0, y, 1)``;
* ``a.T @ v``: ``dgemv(RowMajor, Trans, n, m, 1, a, m, v, 1, 0, y, 1)``.

Dimensions of 1 or 0 take other routes in numpy (a dot product, its own loops): the
functions here refuse them (the callers keep numpy's route there). The routines are looked
up once per process in the libraries numpy's extension module loads (:func:`addresses`) and
checked against numpy's ``matmul`` on a small design; if a symbol is absent or a check
differs, :func:`addresses` gives None and the callers use numpy itself. The addresses are
run-time arguments of the kernels, so numba's cache stays valid across processes.
"""

from __future__ import annotations

import ctypes
import functools

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

# CBLAS's enumerations (cblas.h)
_ROW_MAJOR, _COL_MAJOR = 101, 102
_NO_TRANS, _TRANS = 111, 112
_UPPER = 121

#: symbol names tried, in order: numpy >= 2.0 wheels (scipy-openblas, 64-bit integers), then
#: numpy 1.26 wheels (openblas64_); both ILP64 (64-bit integers)
_PREFIXES = ("scipy_cblas_", "cblas_")
_SUFFIX = "64_"


@intrinsic
def _cblas_call(typingctx, address, args):
    """Call the C routine at ``address`` with the tuple ``args`` passed by value: int32
    (CBLAS's enumerations), int64 (its integers and, as integers, its pointers) and float64
    (its scalars). The routine's address is a run-time value, so the kernels that use it can
    be cached."""
    sig = types.void(types.intp, args)

    def codegen(context, builder, signature, llargs):
        arg_types = [context.get_value_type(t) for t in signature.args[1]]
        fn = ir.FunctionType(ir.VoidType(), arg_types)
        routine = builder.inttoptr(llargs[0], fn.as_pointer())
        builder.call(routine, [builder.extract_value(llargs[1], i)
                               for i in range(len(arg_types))])
        return context.get_dummy_value()

    return sig, codegen


@numba.njit(cache=True, nogil=True)
def gram_t(a: np.ndarray, syrk: int) -> np.ndarray:
    """``a.T @ a`` of a float64 ``(n, m)`` matrix (n, m >= 2) with contiguous rows (a C-ordered
    matrix or a block of its columns) by numpy's ``dsyrk`` call (the row stride as the
    leading dimension), the full symmetric ``(m, m)`` result.

    Parameters
    ----------
    a : ndarray
        ``(n, m)`` float64 matrix [any unit].
    syrk : int
        numpy's routine (:func:`addresses`).

    Returns
    -------
    ndarray
        ``(m, m)`` C-ordered product [unit^2].
    """
    n, m = a.shape
    c = np.empty((m, m))
    _cblas_call(syrk, (np.int32(_ROW_MAJOR), np.int32(_UPPER), np.int32(_TRANS), np.int64(m),
                       np.int64(n), 1.0, np.int64(a.ctypes.data), np.int64(a.strides[0] // 8),
                       0.0,
                       np.int64(c.ctypes.data), np.int64(m)))
    for i in range(m):
        for j in range(i + 1, m):
            c[j, i] = c[i, j]
    return c


@numba.njit(cache=True, nogil=True)
def matmul(a: np.ndarray, b: np.ndarray, gemm: int) -> np.ndarray:
    """``a @ b`` of C-ordered float64 matrices ``(m, n)`` and ``(n, p)`` (all >= 2) by
    numpy's ``dgemm`` call.

    Parameters
    ----------
    a, b : ndarray
        ``(m, n)`` and ``(n, p)`` C-ordered float64 matrices.
    gemm : int
        numpy's routine (:func:`addresses`).

    Returns
    -------
    ndarray
        ``(m, p)`` C-ordered product.
    """
    m, n = a.shape
    p = b.shape[1]
    c = np.empty((m, p))
    _cblas_call(gemm, (np.int32(_ROW_MAJOR), np.int32(_NO_TRANS), np.int32(_NO_TRANS),
                       np.int64(m), np.int64(p), np.int64(n), 1.0, np.int64(a.ctypes.data),
                       np.int64(n), np.int64(b.ctypes.data), np.int64(p), 0.0,
                       np.int64(c.ctypes.data), np.int64(p)))
    return c


@numba.njit(cache=True, nogil=True)
def matmul_tn(a: np.ndarray, b: np.ndarray, gemm: int) -> np.ndarray:
    """``a.T @ b`` of C-ordered float64 matrices ``(n, m)`` and ``(n, p)`` (all >= 2, not
    one buffer: that is :func:`gram_t`) by numpy's ``dgemm`` call.

    Parameters
    ----------
    a, b : ndarray
        ``(n, m)`` and ``(n, p)`` C-ordered float64 matrices.
    gemm : int
        numpy's routine (:func:`addresses`).

    Returns
    -------
    ndarray
        ``(m, p)`` C-ordered product.
    """
    n, m = a.shape
    p = b.shape[1]
    c = np.empty((m, p))
    _cblas_call(gemm, (np.int32(_ROW_MAJOR), np.int32(_TRANS), np.int32(_NO_TRANS),
                       np.int64(m), np.int64(p), np.int64(n), 1.0, np.int64(a.ctypes.data),
                       np.int64(m), np.int64(b.ctypes.data), np.int64(p), 0.0,
                       np.int64(c.ctypes.data), np.int64(p)))
    return c


@numba.njit(cache=True, nogil=True)
def matvec(a: np.ndarray, x: np.ndarray, gemv: int) -> np.ndarray:
    """``a @ x`` of a float64 ``(m, n)`` matrix (m >= 2) whose rows are contiguous (a C-ordered
    matrix or a block of its columns) or else whose columns are, and an ``(n,)`` vector of
    any positive stride (a column of a C- or Fortran-ordered matrix), as numpy's
    ``matmul`` makes it: its ``dgemv`` call for n >= 2 (rows contiguous: ``dgemv(ColMajor,
    Trans, n, m, 1, a, lda, x, incx, 0, y, 1)``; columns: ``dgemv(RowMajor, Trans, n, m, 1,
    a, lda, x, incx, 0, y, 1)``), its own loop for n = 1 (``0 + a*x``), zeros for n = 0.

    Parameters
    ----------
    a : ndarray
        ``(m, n)`` float64 matrix.
    x : ndarray
        ``(n,)`` float64 vector.
    gemv : int
        numpy's routine (:func:`addresses`).

    Returns
    -------
    ndarray
        ``(m,)`` product.
    """
    m, n = a.shape
    y = np.zeros(m)
    if n > 1 and not _c_blasable(a):  # columns contiguous: numpy's row-major call
        _cblas_call(gemv, (np.int32(_ROW_MAJOR), np.int32(_TRANS), np.int64(n), np.int64(m),
                           1.0, np.int64(a.ctypes.data), np.int64(a.strides[1] // 8),
                           np.int64(x.ctypes.data), np.int64(x.strides[0] // 8), 0.0,
                           np.int64(y.ctypes.data), np.int64(1)))
    elif n == 1:
        for i in range(m):
            y[i] = 0.0 + a[i, 0] * x[0]
    elif n > 1:
        _cblas_call(gemv, (np.int32(_COL_MAJOR), np.int32(_TRANS), np.int64(n), np.int64(m),
                           1.0, np.int64(a.ctypes.data), np.int64(a.strides[0] // 8),
                           np.int64(x.ctypes.data), np.int64(x.strides[0] // 8), 0.0,
                           np.int64(y.ctypes.data), np.int64(1)))
    return y


@numba.njit(cache=True, nogil=True)
def matvec_t(a: np.ndarray, v: np.ndarray, gemv: int) -> np.ndarray:
    """``a.T @ v`` of a C-ordered ``(n, m)`` float64 matrix (n, m >= 2) and a contiguous
    ``(n,)`` vector by numpy's ``dgemv`` call.

    Parameters
    ----------
    a : ndarray
        ``(n, m)`` C-ordered float64 matrix.
    v : ndarray
        ``(n,)`` contiguous float64 vector.
    gemv : int
        numpy's routine (:func:`addresses`).

    Returns
    -------
    ndarray
        ``(m,)`` product.
    """
    n, m = a.shape
    y = np.empty(m)
    _cblas_call(gemv, (np.int32(_ROW_MAJOR), np.int32(_TRANS), np.int64(n), np.int64(m), 1.0,
                       np.int64(a.ctypes.data), np.int64(m), np.int64(v.ctypes.data),
                       np.int64(1), 0.0, np.int64(y.ctypes.data), np.int64(1)))
    return y


@numba.njit(cache=True, nogil=True)
def _c_blasable(a: np.ndarray) -> bool:
    """numpy's test that a 2-D float64 array's rows are contiguous for BLAS."""
    return a.strides[1] == 8 and a.strides[0] % 8 == 0 and a.strides[0] // 8 >= a.shape[1]


@numba.njit(cache=True, nogil=True)
def _f_blasable(a: np.ndarray) -> bool:
    """numpy's test that a 2-D float64 array's columns are contiguous for BLAS."""
    return a.strides[0] == 8 and a.strides[1] % 8 == 0 and a.strides[1] // 8 >= a.shape[0]


@numba.njit(cache=True, nogil=True)
def matmul_any(a: np.ndarray, b: np.ndarray, gemm: int) -> np.ndarray:
    """``a @ b`` of float64 matrices ``(m, n)`` and ``(n, p)`` (all >= 2), each with
    contiguous rows or contiguous columns, not one buffer, as numpy's ``matmul`` makes it:
    ``dgemm(RowMajor, ta, tb, m, p, n, 1, a, lda, b, ldb, 0, c, p)`` with NoTrans and the
    row stride for rows that are contiguous, Trans and the column stride otherwise. Raises
    ValueError for other layouts (numpy copies them first).

    Parameters
    ----------
    a, b : ndarray
        ``(m, n)`` and ``(n, p)`` float64 matrices.
    gemm : int
        numpy's routine (:func:`addresses`).

    Returns
    -------
    ndarray
        ``(m, p)`` C-ordered product.
    """
    m, n = a.shape
    p = b.shape[1]
    if _c_blasable(a):
        ta, lda = _NO_TRANS, a.strides[0] // 8
    elif _f_blasable(a):
        ta, lda = _TRANS, a.strides[1] // 8
    else:
        raise ValueError("matmul_any: a layout numpy copies")
    if _c_blasable(b):
        tb, ldb = _NO_TRANS, b.strides[0] // 8
    elif _f_blasable(b):
        tb, ldb = _TRANS, b.strides[1] // 8
    else:
        raise ValueError("matmul_any: a layout numpy copies")
    c = np.empty((m, p))
    _cblas_call(gemm, (np.int32(_ROW_MAJOR), np.int32(ta), np.int32(tb), np.int64(m),
                       np.int64(p), np.int64(n), 1.0, np.int64(a.ctypes.data), np.int64(lda),
                       np.int64(b.ctypes.data), np.int64(ldb), 0.0, np.int64(c.ctypes.data),
                       np.int64(p)))
    return c


@numba.njit(cache=True, nogil=True)
def pairwise_leaf(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise sum of a block ``a[lo:lo + n]`` of at most 128 elements: in order
    below 8, else in eight interleaved partial sums combined as a tree, then the rest."""
    if n < 8:
        res = -0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    end = n - n % 8
    while i < end:
        j = lo + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@numba.njit(cache=True, nogil=True)
def vector_sum(a: np.ndarray) -> float:
    """``a.sum()`` of a contiguous 1-D float64 array with numpy's numbers: its pairwise
    summation (blocks above 128 elements split in halves rounded down to a multiple of 8,
    the halves' sums added) added to the reduction's initial 0. Iterative (an explicit
    stack: numba's cached recursion is not used).

    Parameters
    ----------
    a : ndarray
        Contiguous 1-D float64 array [any unit].

    Returns
    -------
    float
        The sum [unit].
    """
    los = np.empty(64, dtype=np.int64)
    ns = np.empty(64, dtype=np.int64)
    stage = np.empty(64, dtype=np.int64)
    vals = np.empty(64)
    top, nv = 1, 0
    los[0], ns[0], stage[0] = 0, a.size, 0
    while top > 0:
        t = top - 1
        lo, n = los[t], ns[t]
        if n <= 128:
            vals[nv] = pairwise_leaf(a, lo, n)
            nv += 1
            top -= 1
            continue
        n2 = n // 2
        n2 -= n2 % 8
        if stage[t] == 0:  # the first half
            stage[t] = 1
            los[top], ns[top], stage[top] = lo, n2, 0
            top += 1
        elif stage[t] == 1:  # the second half
            stage[t] = 2
            los[top], ns[top], stage[top] = lo + n2, n - n2, 0
            top += 1
        else:  # both halves' sums are the last two values
            vals[nv - 2] = vals[nv - 2] + vals[nv - 1]
            nv -= 1
            top -= 1
    return 0.0 + vals[0]


def _lookup() -> tuple[int, int, int] | None:
    """The addresses of ``dsyrk``, ``dgemm`` and ``dgemv`` in the BLAS numpy is linked
    against, or None."""
    try:
        from numpy._core import _multiarray_umath as umath
    except ImportError:  # numpy < 2.0
        from numpy.core import _multiarray_umath as umath
    try:
        lib = ctypes.CDLL(umath.__file__)  # (the loaded module: dlsym searches its
    except OSError:  # dependencies, numpy's own BLAS among them)
        return None
    for prefix in _PREFIXES:
        found = []
        for name in ("dsyrk", "dgemm", "dgemv"):
            try:
                found.append(ctypes.cast(getattr(lib, f"{prefix}{name}{_SUFFIX}"),
                                         ctypes.c_void_p).value)
            except AttributeError:
                break
        if len(found) == 3 and all(found):
            return tuple(found)
    return None


def _agrees(found: tuple[int, int, int]) -> bool:
    """Whether the routines at ``found``, called through ctypes with the arguments the
    kernels pass, give numpy's ``matmul`` bit for bit on a small design."""
    syrk, gemm, gemv = found
    i32, i64, f64, ptr = ctypes.c_int32, ctypes.c_int64, ctypes.c_double, ctypes.c_void_p
    rng = np.random.default_rng(5)
    a = rng.standard_normal((57, 7)) * np.logspace(0, 3, 7)
    b = rng.standard_normal((57, 3))
    x = rng.standard_normal(7)
    n, m = a.shape
    p = b.shape[1]
    c = np.zeros((m, m))
    ctypes.CFUNCTYPE(None, i32, i32, i32, i64, i64, f64, ptr, i64, f64, ptr, i64)(syrk)(
        _ROW_MAJOR, _UPPER, _TRANS, m, n, 1.0, a.ctypes.data, m, 0.0, c.ctypes.data, m)
    c = np.triu(c) + np.triu(c, 1).T
    d = np.zeros((m, p))
    ctypes.CFUNCTYPE(None, i32, i32, i32, i64, i64, i64, f64, ptr, i64, ptr, i64, f64, ptr,
                     i64)(gemm)(_ROW_MAJOR, _TRANS, _NO_TRANS, m, p, n, 1.0, a.ctypes.data, m,
                                b.ctypes.data, p, 0.0, d.ctypes.data, p)
    y = np.zeros(n)
    ctypes.CFUNCTYPE(None, i32, i32, i64, i64, f64, ptr, i64, ptr, i64, f64, ptr, i64)(gemv)(
        _COL_MAJOR, _TRANS, m, n, 1.0, a.ctypes.data, m, x.ctypes.data, 1, 0.0, y.ctypes.data,
        1)
    return (np.array_equal(c, a.T @ a) and np.array_equal(d, a.T @ b)
            and np.array_equal(y, a @ x))


@functools.cache
def addresses() -> tuple[int, int, int] | None:
    """The run-time addresses of numpy's own ``dsyrk``, ``dgemm`` and ``dgemv`` (CBLAS,
    64-bit integers), the last arguments of the kernels here.

    Returns
    -------
    tuple of int or None
        ``(syrk, gemm, gemv)``; None when numpy's BLAS does not export them under the names
        of numpy's wheels (numpy 1.26-2.x: ``scipy_cblas_*64_`` or ``cblas_*64_``) or when
        they do not reproduce numpy's ``matmul`` bit for bit on a check design: the callers
        then keep numpy's own route, with the same numbers.
    """
    found = _lookup()
    if found is None or not _agrees(found):
        return None
    return found


@functools.cache
def gesv_address() -> int | None:
    """The run-time address of LAPACK's ``dgesv`` (64-bit integers) in the library numpy's
    ``numpy.linalg.solve`` calls, or None (absent, or not numpy's numbers on a check
    system): the kernels that solve small systems as ``numpy.linalg.solve`` take it."""
    try:
        from numpy.linalg import _umath_linalg
        lib = ctypes.CDLL(_umath_linalg.__file__)
    except (ImportError, OSError):
        return None
    address = None
    for prefix in ("scipy_", ""):
        try:
            address = ctypes.cast(getattr(lib, f"{prefix}dgesv_{_SUFFIX}"), ctypes.c_void_p).value
            break
        except AttributeError:
            continue
    if not address:
        return None
    rng = np.random.default_rng(6)
    a = rng.standard_normal((6, 6)) + 3 * np.eye(6)
    b = rng.standard_normal((6, 2))
    af, bf = np.asfortranarray(a), np.asfortranarray(b)
    ints = np.array([6, 2, 6, 6, 0], dtype=np.int64)
    ipiv = np.zeros(6, dtype=np.int64)
    p = ints.ctypes.data
    ctypes.CFUNCTYPE(None, *[ctypes.c_void_p] * 8)(address)(
        p, p + 8, af.ctypes.data, p + 16, ipiv.ctypes.data, bf.ctypes.data, p + 24, p + 32)
    if ints[4] != 0 or not np.array_equal(bf, np.linalg.solve(a, b)):
        return None
    return address
