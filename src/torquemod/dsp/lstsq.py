"""Least squares for the chain's small designs: a Cholesky factorisation of the
column-normalised normal equations with iterative refinement (steps 1 and 6-8 of the V-Track
chain fit many designs of a few hundred rows and tens of columns).

Golub & Van Loan, *Matrix Computations* (4th ed.), section 5.3.2 (normal equations) and
section 3.5.3 (iterative refinement): the normal equations square the condition number, and
two refinement steps on the residual bring the solution to the SVD's accuracy for these
well-conditioned designs; near rank deficiency :func:`lstsq` falls back to the SVD.

The factorisation and the refined solve each run as one compiled call (numba) that makes the
BLAS products numpy made and calls LAPACK's ``potrf`` and ``potrs`` in scipy's own library
at their addresses (``scipy.linalg.cython_lapack``): the same routines with the same
arguments as ``scipy.linalg.cho_factor`` and ``cho_solve``, so the same numbers, without
the Python-level cost of a dozen numpy and scipy calls per solve. Designs and records in
another memory layout (a strided column, a Fortran-ordered design) keep numpy's route,
whose BLAS calls differ with the layout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import get_cython_function_address, intrinsic
from scipy import linalg

from torquemod.dsp import numpyblas


def lstsq(design: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, int]:
    """Least-squares coefficients of ``y ~ design @ coef`` and the design's numerical rank.

    Solved by a Cholesky factorisation of the column-normalised normal equations: for the
    small, well-conditioned designs of the chain (a few hundred rows, tens of columns) it is
    10x faster than ``numpy.linalg.lstsq``, whose threaded SVD costs milliseconds at this
    size, and agrees with it to 1e-14. Falls back to the SVD when the design is (nearly) rank
    deficient (condition number of the normalised normal matrix above 1e10). Two steps of
    iterative refinement bring it to the SVD's accuracy [1]_.

    Parameters
    ----------
    design : ndarray
        (n, m) design matrix.
    y : ndarray
        (n,) or (n, k) observations.

    Returns
    -------
    coef : ndarray
        (m,) or (m, k) coefficients.
    rank : int
        Numerical rank of ``design``.

    References
    ----------
    .. [1] G.H. Golub and C.F. Van Loan, "Matrix Computations", 4th ed., Johns Hopkins
       University Press 2013 (normal equations; iterative refinement).

    Examples
    --------
    >>> import numpy as np
    >>> d = np.column_stack([np.ones(4), np.arange(4.0)])
    >>> coef, rank = lstsq(d, 1.0 + 2.0 * np.arange(4.0))
    >>> np.round(coef, 12).tolist(), rank
    ([1.0, 2.0], 2)
    """
    d = np.asarray(design, dtype=np.float64)
    fac = LstsqFactor.of(d)
    if fac is not None:
        return fac.solve(y), d.shape[1]
    coef, _, rank, _ = np.linalg.lstsq(d, y, rcond=None)
    return coef, int(rank)


@dataclass(frozen=True)
class LstsqFactor:
    """The Cholesky factor of one design's column-normalised normal equations.

    For solving with the same design many times: ``solve(y)`` gives exactly the numbers
    ``lstsq(design, y)[0]`` does.

    Attributes
    ----------
    dn : ndarray
        The column-normalised design.
    scale : ndarray
        The columns' norms.
    factor : ndarray
        The Cholesky factor of ``dn.T @ dn``.
    gram : ndarray or None
        ``dn.T @ dn`` when kept for the refinement.
    """

    dn: np.ndarray  # design with unit-norm columns
    scale: np.ndarray  # the columns' norms
    factor: np.ndarray  # upper Cholesky factor of dn.T @ dn (LAPACK's layout: Fortran
    # order, the upper triangle; the lower one is not part of it)
    gram: np.ndarray | None = None  # dn.T @ dn itself, when asked for (keep_gram)

    @classmethod
    def of(cls, design: np.ndarray, *, keep_gram: bool = False) -> LstsqFactor | None:
        """The factor, or None when :func:`lstsq` would fall back to the SVD (no columns, a
        zero column, or a normalised normal matrix with condition number above 1e10). With
        ``keep_gram`` the normal matrix is kept too. Every array is read-only."""
        d = np.asarray(design, dtype=np.float64)
        if d.ndim != 2 or not d.shape[1]:
            return None
        blas = numpyblas.addresses()
        if blas is not None and d.flags.c_contiguous and d.shape[0] > 1 and d.shape[1] > 1:
            # one compiled call: the same steps as below, numpy's syrk called from it
            dn, scale, gram, factor, status = _factor_of(d, blas[0], _DPOTRF)
            if status != 0:
                return None
            for a in (dn, scale, gram, factor):
                a.setflags(write=False)
            return cls(dn, scale, factor, gram if keep_gram else None)
        if d.flags.c_contiguous and d.shape[1] > 1:  # the column norms and the normalised
            dn, scale = _normalised(d)  # design in one compiled call (the same numbers as
            # below; einsum sums a single column in another order)
        else:  # numpy's route: a layout's BLAS calls are its own
            scale = np.sqrt(np.einsum("ij,ij->j", d, d))
            dn = d / scale if scale.min() > 0 else d
        if not scale.min() > 0:  # (NaN fails too)
            return None
        # the normal matrix by numpy (BLAS syrk) and its factor by LAPACK's potrf, the
        # routines and arguments of scipy.linalg.cho_factor
        gram = dn.T @ dn
        factor, status = _cholesky(np.array(gram, order="F"), _DPOTRF)  # (a copy: potrf
        # works in place, and a 1 x 1 matrix is already in Fortran order)
        if status != 0:
            return None
        for a in (dn, scale, gram, factor):
            a.setflags(write=False)
        return cls(dn, scale, factor, gram if keep_gram else None)

    def trailing(self, k: int) -> LstsqFactor | None:
        """The factor of the design without its first ``k`` columns, from the kept normal
        matrix (``keep_gram``): its trailing block is that design's normalised normal
        matrix (the column norms do not depend on the other columns), so only the Cholesky
        factorisation is new. None without the normal matrix or where :meth:`of` would
        give None."""
        if self.gram is None or not 0 <= k < self.gram.shape[0]:
            return None
        factor, status = _cholesky(np.array(self.gram[k:, k:], order="F"), _DPOTRF)
        if status != 0:
            return None
        dn = self.dn[:, k:]
        if self.dn.flags.c_contiguous:  # (BLAS packs the columns: the same products)
            dn = np.ascontiguousarray(dn)
        scale = self.scale[k:].copy()
        for a in (dn, scale, factor):
            a.setflags(write=False)
        return LstsqFactor(dn, scale, factor)

    def solve(self, y: np.ndarray) -> np.ndarray:
        """Least-squares coefficients for ``y`` (one or more columns)."""
        y = np.asarray(y, dtype=np.float64)
        if self.dn.flags.c_contiguous and (y.ndim == 2 or y.flags.c_contiguous):
            # one compiled call (a fresh C copy of y: one signature per dimension)
            # (LAPACK reads the factor in Fortran order: a factor made elsewhere is copied)
            return _solve(self.dn, np.asfortranarray(self.factor), self.scale,
                          np.array(y, order="C"), _DPOTRS)
        # numpy's route (BLAS's matrix-vector products of a strided vector, and of another
        # layout, are their own; this keeps their numbers)
        dn = self.dn
        coef = _cho_solve(self.factor, dn.T @ y)
        for _ in range(2):  # iterative refinement, as _solve
            coef += _cho_solve(self.factor, dn.T @ (y - dn @ coef))
        return (coef.T / self.scale).T


_POTRS = linalg.get_lapack_funcs(("potrs",), (np.zeros((1, 1)),))[0]


def _cho_solve(factor: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``scipy.linalg.cho_solve((factor, False), b)`` for a float64 upper factor."""
    x, info = _POTRS(factor, b, lower=False, overwrite_b=False)
    if info != 0:
        raise ValueError(f"illegal value in argument {-info} of LAPACK potrs")
    return x


_LAPACK = "scipy.linalg.cython_lapack"
#: addresses of LAPACK's dpotrf and dpotrs in scipy's own library (_POTRS is the latter)
_DPOTRF = get_cython_function_address(_LAPACK, "dpotrf")
_DPOTRS = get_cython_function_address(_LAPACK, "dpotrs")


@intrinsic
def _fortran_call(typingctx, address, args):
    """Call the Fortran routine at ``address`` with the tuple ``args`` of addresses (all
    integers: ``array.ctypes.data``); the routine's address is a run-time value, so the
    kernels that use it can be cached."""
    sig = types.void(types.intp, args)

    def codegen(context, builder, signature, llargs):
        ptr = ir.IntType(8).as_pointer()
        n_args = len(signature.args[1])
        routine = builder.inttoptr(llargs[0], ir.FunctionType(ir.VoidType(),
                                                              [ptr] * n_args).as_pointer())
        builder.call(routine, [builder.inttoptr(builder.extract_value(llargs[1], i), ptr)
                               for i in range(n_args)])
        return context.get_dummy_value()

    return sig, codegen


@numba.njit(cache=True, nogil=True)
def _cholesky(a: np.ndarray, potrf: int) -> tuple[np.ndarray, int]:
    """LAPACK ``potrf`` of the upper triangle of the Fortran-ordered ``a`` in place (the
    lower triangle kept, as ``potrf(..., clean=False)``): ``(a, status)`` with status 0, 2 (not
    positive definite) or 3 (condition number above 1e10: the smallest diagonal element
    squared below 1e-10 of the largest)."""
    m = a.shape[0]
    ints = np.array([85, m, m, 0], dtype=np.int32)  # "U" (its first byte), n, lda, info
    p = ints.ctypes.data
    _fortran_call(potrf, (p, p + 4, a.ctypes.data, p + 8, p + 12))
    if ints[3] != 0:
        return a, 2
    lo = hi = a[0, 0]
    for j in range(1, m):
        lo = min(lo, a[j, j])
        hi = max(hi, a[j, j])
    if not lo * lo > 1e-10 * (hi * hi):  # (potrf's diagonal is positive)
        return a, 3
    return a, 0


def column_sums_of_squares(a: np.ndarray) -> np.ndarray:
    """The sum of squares of each column of a matrix, ``einsum("ij,ij->j", a, a)``.

    Parameters
    ----------
    a : ndarray
        ``(n, m)`` matrix, any unit.

    Returns
    -------
    ndarray
        ``(m,)`` sums [unit^2]: einsum's own numbers (each column summed row by row) from
        one compiled call for a C-ordered float64 matrix of two or more columns; einsum
        itself otherwise.

    Examples
    --------
    >>> import numpy as np
    >>> column_sums_of_squares(np.array([[1.0, 2.0], [3.0, 4.0]])).tolist()
    [10.0, 20.0]
    """
    a = np.asarray(a)
    if a.dtype == np.float64 and a.ndim == 2 and a.shape[1] > 1 and a.flags.c_contiguous:
        return _sums_of_squares(a)
    return np.einsum("ij,ij->j", a, a)


@numba.njit(cache=True, nogil=True)
def _sums_of_squares(d: np.ndarray) -> np.ndarray:
    """Each column's sum of squares, summed row by row (``einsum("ij,ij->j")``'s order for
    two or more columns). Up to 12 columns, four at a time with their sums in registers
    (:func:`_sums_of_squares_4`; each sum's additions in the same order, so the same
    numbers), instead of a row's sums loaded and stored at every row."""
    n, m = d.shape
    acc = np.zeros(m)
    if m <= 12:
        for j0 in range(0, m, 4):
            _sums_of_squares_4(d, j0, min(m - j0, 4), acc)
        return acc
    for i in range(n):
        for j in range(m):
            acc[j] += d[i, j] * d[i, j]
    return acc


@numba.njit(cache=True, nogil=True)
def _sums_of_squares_4(d: np.ndarray, j0: int, width: int, acc: np.ndarray) -> None:
    """The sums of squares of columns ``j0 .. j0 + width - 1`` (``width`` 1 to 4) of ``d``
    over its rows in order into ``acc``: four running sums, the unused ones left out of
    ``acc``."""
    s0 = s1 = s2 = s3 = 0.0
    last = j0 + width - 1
    c1, c2, c3 = min(j0 + 1, last), min(j0 + 2, last), min(j0 + 3, last)
    for i in range(d.shape[0]):
        v0, v1, v2, v3 = d[i, j0], d[i, c1], d[i, c2], d[i, c3]
        s0 += v0 * v0
        s1 += v1 * v1
        s2 += v2 * v2
        s3 += v3 * v3
    sums = (s0, s1, s2, s3)
    for q in range(width):
        acc[j0 + q] = sums[q]


@numba.njit(cache=True, nogil=True)
def _row_sums_of_squares(a: np.ndarray) -> np.ndarray:
    """Each row's sum of squares over its elements in order (``s += a[i, t]**2`` as
    ``a[i, t] * a[i, t]``, t ascending): :func:`_sums_of_squares` of the transpose, whose
    columns are these rows (four at a time, the numbers of one row at a time)."""
    return _sums_of_squares(a.T)


@numba.njit(cache=True, nogil=True)
def _normalised(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The columns' norms (:func:`_sums_of_squares`) and the design divided by them (empty
    when a norm is zero or not finite)."""
    m = d.shape[1]
    scale = np.sqrt(_sums_of_squares(d))
    for j in range(m):
        if not scale[j] > 0.0:  # (NaN too)
            return np.empty((0, m)), scale
    return _divided_by_columns(np.ascontiguousarray(d), scale), scale


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _divided_by_columns(d: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """``d / scale`` for a C-ordered ``d`` (``n x m``): each element by one division, as
    numpy divides. The rows in runs against the scale repeated over a run (one flat loop
    of a few hundred elements, which vectorises: numpy's error model leaves out the
    zero-divisor check of each element, the caller having checked the scale)."""
    n, m = d.shape
    out = np.empty((n, m))
    if n == 0 or m == 0:
        return out
    flat_out = out.reshape(n * m)
    flat_d = d.reshape(n * m)
    rows = max(1, 256 // m)
    rep = np.empty(rows * m)
    for r in range(rows):
        for j in range(m):
            rep[r * m + j] = scale[j]
    width = rows * m
    i = 0
    while i + rows <= n:
        base = i * m
        for q in range(width):
            flat_out[base + q] = flat_d[base + q] / rep[q]
        i += rows
    base = i * m
    for q in range((n - i) * m):
        flat_out[base + q] = flat_d[base + q] / rep[q]
    return out


@numba.njit(cache=True, nogil=True)
def _cho_solve_inplace(factor: np.ndarray, b: np.ndarray, potrs: int) -> None:
    """LAPACK ``potrs`` with the upper factor: ``b <- (R'R)^-1 b`` in place (``b`` one
    column, or Fortran-ordered columns)."""
    m = factor.shape[0]
    # "U" (its first byte), n, nrhs, lda, ldb, info
    ints = np.array([85, m, b.size // max(m, 1), m, m, 0], dtype=np.int32)
    p = ints.ctypes.data
    _fortran_call(potrs, (p, p + 4, p + 8, factor.ctypes.data, p + 12, b.ctypes.data, p + 16,
                          p + 20))
    if ints[5] != 0:
        raise ValueError("illegal value in an argument of LAPACK potrs")


@numba.njit(cache=True, nogil=True)
def _solve(dn: np.ndarray, factor: np.ndarray, scale: np.ndarray, y: np.ndarray, potrs: int
           ) -> np.ndarray:
    """:meth:`LstsqFactor.solve` in one call, with the operations, BLAS products and LAPACK
    routine of the former numpy and scipy route (the same numbers): the normal equations'
    solution, two steps of iterative refinement on the residual, the columns' scale
    undone."""
    dnt = dn.T
    coef = np.asfortranarray(np.dot(dnt, y))
    _cho_solve_inplace(factor, coef, potrs)
    for _ in range(2):  # iterative refinement: the normal equations square the
        # condition number, and a large DC (a wheel speed of 30 rad/s beside a
        # modulation of 1e-3 rad/s) needs the residual to full precision
        step = np.asfortranarray(np.dot(dnt, y - np.dot(dn, coef)))
        _cho_solve_inplace(factor, step, potrs)
        coef += step
    return (coef.T / scale).T


@numba.njit(cache=True, nogil=True)
def _factor_of(d: np.ndarray, syrk: int, potrf: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """:meth:`LstsqFactor.of` of a C-ordered design of two or more rows and columns in one
    call: the normalised design and the columns' norms (:func:`_normalised`), the normal
    matrix by numpy's own ``syrk`` call (:func:`torquemod.dsp.numpyblas.gram_t`: numpy's
    numbers) and its factor by LAPACK ``potrf``; the status of :func:`lstsq_compiled`."""
    dn, scale = _normalised(d)
    if dn.shape[0] == 0:
        e = np.empty((0, 0))
        return dn, scale, e, e, 1
    gram = numpyblas.gram_t(dn, syrk)
    factor, status = _cholesky(np.asfortranarray(gram), potrf)
    return dn, scale, gram, factor, status


def lapack_addresses() -> tuple[int, int]:
    """The addresses of LAPACK's ``dpotrf`` and ``dpotrs`` in scipy's library.

    Returns
    -------
    potrf, potrs : int
        The routines' addresses, the last two arguments of :func:`lstsq_compiled` (run-time
        values, so a kernel that takes them can be cached).
    """
    return _DPOTRF, _DPOTRS


@numba.njit(cache=True, nogil=True)
def lstsq_compiled(design: np.ndarray, y: np.ndarray, potrf: int, potrs: int
                   ) -> tuple[np.ndarray, int]:
    """:func:`lstsq`'s Cholesky route inside compiled code, for kernels that fit small
    designs in a loop.

    The column-normalised normal equations ``dn'dn`` factored by LAPACK ``potrf`` and solved
    with two steps of iterative refinement by ``potrs`` (Golub & Van Loan, sections 5.3.2
    and 3.5.3), the routines of :func:`lstsq`. The normal matrix is a general matrix product
    here (numpy's is a symmetric rank-k update), so the coefficients agree with
    :func:`lstsq`'s to rounding, not bit for bit.

    Parameters
    ----------
    design : ndarray
        ``(n, m)`` C-ordered design, ``m >= 2``.
    y : ndarray
        ``(n,)`` or ``(n, k)`` observations, C-ordered.
    potrf, potrs : int
        LAPACK's routines (:func:`lapack_addresses`).

    Returns
    -------
    coef : ndarray
        ``(m,)`` or ``(m, k)`` coefficients, C-ordered (none unless the status is 0).
    status : int
        0; 1 a zero or non-finite column; 2 a normal matrix not positive definite; 3 its
        condition number above 1e10. Where it is not 0, :func:`lstsq` would fall back to the
        SVD: the caller does.
    """
    dn, scale = _normalised(design)
    if dn.shape[0] == 0:
        return np.empty((0, *y.shape[1:])), 1
    gram = np.asfortranarray(np.dot(dn.T, dn))
    factor, status = _cholesky(gram, potrf)
    if status != 0:
        return np.empty((0, *y.shape[1:])), status
    return np.ascontiguousarray(_solve(dn, factor, scale, y, potrs)), 0


@numba.njit(cache=True, nogil=True)
def fit_with_parts(design: np.ndarray, y: np.ndarray, bounds: np.ndarray, wanted: np.ndarray,
                   syrk: int, gemm: int, gemv: int, potrf: int, potrs: int):
    """:func:`lstsq` of every column of ``y`` on a design and the fit's parts over blocks of
    the design's columns, in one compiled call with numpy's and LAPACK's numbers.

    The factor as :meth:`LstsqFactor.of` (the normal matrix by numpy's own ``syrk`` call),
    the coefficients as :meth:`LstsqFactor.solve` (Golub & Van Loan, sections 5.3.2 and
    3.5.3), and each part ``design[:, b0:b1] @ coef[b0:b1, j]`` as numpy's ``matmul`` makes
    it (:func:`torquemod.dsp.numpyblas.matvec`); and the variance ratio of the first two
    coefficients, ``trace((R'R)^-1)/trace((M'M)^-1)`` with M the first two columns and R
    their residual on the others (Schur complement of the normal matrix).

    Parameters
    ----------
    design : ndarray
        ``(n, m)`` C-ordered design, ``n, m >= 2``.
    y : ndarray
        ``(n, k)`` C-ordered observations.
    bounds : ndarray
        ``(parts, 2)`` integer column ranges ``[b0, b1)`` of the parts.
    wanted : ndarray
        ``(parts, k)`` booleans: the parts to compute (the others are left undefined).
    syrk, gemm, gemv : int
        numpy's BLAS routines (:func:`torquemod.dsp.numpyblas.addresses`).
    potrf, potrs : int
        LAPACK's routines (:func:`lapack_addresses`).

    Returns
    -------
    dn, scale, gram, factor : ndarray
        The parts of :class:`LstsqFactor` (``factor`` in Fortran order).
    coef : ndarray
        ``(m, k)`` coefficients (Fortran order, as :meth:`LstsqFactor.solve` gives them).
    parts : ndarray
        ``(parts, k, n)``: part p of column j in ``parts[p, j]`` where wanted.
    ratio : float
        The variance ratio (:func:`_leading_variance_ratio`), NaN for fewer than four
        columns or where the others' factor fails.
    status : int
        As :func:`lstsq_compiled`; where it is not 0 nothing else is meaningful and the
        caller fits by :func:`lstsq`.
    """
    return fit_with_parts_and_ratio(design, y, bounds, wanted, syrk, gemm, gemv, potrf, potrs,
                                    True)


@numba.njit(cache=True, nogil=True)
def fit_with_parts_and_ratio(design, y, bounds, wanted, syrk, gemm, gemv, potrf, potrs,
                             with_ratio):
    """:func:`fit_with_parts`, its variance ratio made only ``with_ratio`` (NaN otherwise:
    for callers that have it another way)."""
    dn, scale, gram, factor, status = _factor_of(design, syrk, potrf)
    n, k = y.shape
    if status != 0:
        e = np.empty((0, 0))
        return (dn, scale, gram, factor, np.asfortranarray(e), np.empty((0, 0, 0)), np.nan,
                status)
    coef = _solve(dn, factor, scale, y, potrs)
    parts = np.empty((bounds.shape[0], k, n))
    for p in range(bounds.shape[0]):
        b0, b1 = bounds[p, 0], bounds[p, 1]
        for j in range(k):
            if wanted[p, j]:
                parts[p, j] = numpyblas.matvec(design[:, b0:b1], coef[b0:b1, j], gemv)
    ratio = np.nan
    if with_ratio and design.shape[1] > 3:
        ratio = _leading_variance_ratio(design, gram, dn, scale, potrf, potrs, syrk, gemm)
    return dn, scale, gram, factor, coef, parts, ratio, status


@numba.njit(cache=True, nogil=True)
def _leading_variance_ratio(d, gram, dn, scale, potrf, potrs, syrk, gemm):
    """``trace((R'R)^-1)/trace((M'M)^-1)`` for the first two columns M of a C-ordered design
    (four or more columns) and R their least-squares residual on the others, step by step
    as ``SpeedModel.variance_factor``'s numpy route (the trailing factor of
    :meth:`LstsqFactor.trailing`, the refined solve, numpy's BLAS calls); NaN where that
    factor fails."""
    factor, status = _cholesky(np.asfortranarray(gram[2:, 2:].copy()), potrf)
    if status != 0:
        return np.nan
    m = d[:, :2]
    c_o = _solve(np.ascontiguousarray(dn[:, 2:]), factor, scale[2:].copy(),
                 np.ascontiguousarray(m), potrs)
    m_res = m - numpyblas.matmul_any(d[:, 2:], c_o, gemm)
    a = numpyblas.gram_t(m_res, syrk)
    b = numpyblas.gram_t(m, syrk)
    t_a = (a[0, 0] + a[1, 1]) / (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0])
    t_b = (b[0, 0] + b[1, 1]) / (b[0, 0] * b[1, 1] - b[0, 1] * b[1, 0])
    return t_a / t_b


#: :meth:`LstsqFactor.of`'s compiled route (:func:`_factor_of`: a C-ordered design of two or
#: more rows and columns; ``syrk`` from :func:`torquemod.dsp.numpyblas.addresses`, ``potrf``
#: from :func:`lapack_addresses`), for other kernels to call
factor_compiled = _factor_of
#: :meth:`LstsqFactor.solve`'s compiled route (:func:`_solve`: the factor in Fortran order, a
#: C-ordered ``y``), for other kernels to call
solve_compiled = _solve
#: :func:`column_sums_of_squares`'s compiled route (two or more columns), for other kernels
sums_of_squares_compiled = _sums_of_squares
#: :func:`fit_with_parts`' variance ratio (:func:`_leading_variance_ratio`), for other kernels
leading_variance_ratio = _leading_variance_ratio
