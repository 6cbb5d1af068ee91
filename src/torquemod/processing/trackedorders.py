"""The rotation orders of the speed model (:mod:`torquemod.processing.speedmodel`): an
encoder's eccentricity tracked along the integrated angle of each speed, kept only where the
slow basis does not already span it, and the slow basis with both speeds' orders for one
cycle (:func:`_slow_and_orders`).
"""

from __future__ import annotations

import functools

import numba
import numpy as np

from torquemod.dsp import basis, blockbasis, filters, lstsq, numpyblas
from torquemod.dsp.lstsq import column_sums_of_squares
from torquemod.io.config import ProcessingConfig


def tracked_orders(speed_rad_s: np.ndarray, fs_hz: float, slow: np.ndarray,
                   harmonics: tuple[int, ...], *, above_hz: float, avoid_hz: float,
                   modulation_hz: float | None = None) -> tuple[np.ndarray, float]:
    """Columns of an encoder's eccentricity at rotation orders that follow the angle.

    An eccentric encoder reads ``w*(1 + e(theta))``: its error follows the angle and scales
    with the speed. The columns are ``(w_s/mean w_s)*cos(k*theta)``, ``... sin(k*theta)``
    with ``w_s`` the slow part of the speed (least squares on ``slow`` jointly with the
    modulation at ``modulation_hz``, which then cannot leak into it) and ``theta`` its
    integral, so they follow a wobble or a ramp (order tracking) and do not carry the
    modulation's own phase wobble into the angle.

    Parameters
    ----------
    speed_rad_s : ndarray
        The encoder's angular speed [rad/s].
    fs_hz : float
        Sample rate [Hz].
    slow : ndarray
        The slow basis.
    harmonics : tuple of int
        The rotation orders k.
    above_hz : float
        Orders must lie above this (the slow band's top) [Hz].
    avoid_hz : float
        The modulation frequency to keep clear of [Hz].
    modulation_hz : float or None
        Modulation fitted jointly with the slow part [Hz]; None: none.

    Returns
    -------
    columns : ndarray
        The kept orders' columns [-] (above the slow band, below 0.45 x the sample rate, clear
        of ``avoid_hz`` and not already spanned by the slow basis).
    rotation_hz : float
        The mean rotation frequency [Hz].
    """
    base = _order_base(speed_rad_s.size, fs_hz, slow, modulation_hz)
    return _tracked_orders(speed_rad_s, fs_hz, slow, harmonics, base, None,
                           above_hz=above_hz, avoid_hz=avoid_hz)


def _order_base(n: int, fs_hz: float, slow: np.ndarray, modulation_hz: float | None
                ) -> np.ndarray:
    """The columns :func:`tracked_orders` fits before any order: the slow basis, and the
    modulation at ``modulation_hz`` when given; C order, the layout ``lstsq`` receives in
    :func:`_tracked_orders` (BLAS sums a Fortran-ordered design's normal matrix in another
    order, which changes the last bits)."""
    if modulation_hz is None:
        return np.ascontiguousarray(slow)
    t = np.arange(n) / fs_hz
    w = 2 * np.pi * modulation_hz
    return np.ascontiguousarray(np.column_stack([slow, np.cos(w * t), np.sin(w * t)]))


def _tracked_orders(speed_rad_s: np.ndarray, fs_hz: float, slow: np.ndarray,
                    harmonics: tuple[int, ...], base: np.ndarray,
                    base_factor: filters.LstsqFactor | None, *, above_hz: float,
                    avoid_hz: float) -> tuple[np.ndarray, float]:
    """:func:`tracked_orders` with its first design ``base`` given, and that design's
    least-squares factor when already computed (wheel and platform share both)."""
    block = _tracked_orders_block(speed_rad_s, fs_hz, slow, harmonics, base,
                                  above_hz=above_hz, avoid_hz=avoid_hz)
    if block is not None:
        return block
    blas = numpyblas.addresses()
    if (blas is not None and base_factor is not None and speed_rad_s.ndim == 1
            and speed_rad_s.dtype == np.float64 and speed_rad_s.flags.c_contiguous
            and slow.shape[1] > 1 and base.flags.c_contiguous and base.shape[1] > 1
            and speed_rad_s.size > 1):
        # one compiled call with the numbers of the route below (numpy's BLAS calls)
        cols, f_rot, status = _tracked_orders_compiled(
            speed_rad_s, float(fs_hz), slow,
            np.array([int(h) for h in harmonics], dtype=np.int64), base, base_factor.dn,
            np.asfortranarray(base_factor.factor), base_factor.scale, float(above_hz),
            float(avoid_hz), *blas, *lstsq.lapack_addresses())
        if status == 0:
            return cols, float(f_rot)
    resolution = fs_hz / speed_rad_s.size
    cols = np.empty((speed_rad_s.size, 0))
    f_rot = float("nan")
    for it in range(2):  # the slow part is refitted with the first pass's orders
        if it == 0 and base_factor is not None:
            coef = base_factor.solve(speed_rad_s)
        else:
            coef, _ = filters.lstsq(np.column_stack([base, cols]), speed_rad_s)
        w_s = slow @ coef[:slow.shape[1]]
        mean = float(w_s.sum()) / w_s.size  # np.mean's numbers
        f_rot = abs(mean) / (2 * np.pi)
        kept = [h for h in harmonics if above_hz < h * f_rot < 0.45 * fs_hz
                and abs(h * f_rot - avoid_hz) > 2 * resolution]
        if not kept or mean == 0:
            return np.empty((speed_rad_s.size, 0)), f_rot
        cols = filters.order_design(filters.unwrapped_angle(w_s, fs_hz), kept) \
            * (w_s / mean)[:, None]
        cols = _separable_orders(cols, base, base_factor)
        if not cols.shape[1]:
            return cols, f_rot
    return cols, f_rot


@numba.njit(cache=True, nogil=True)
def _speed_scaled_orders(w_s, mean, f_rot, harmonics, fs_hz, above_hz, avoid_hz, resolution):
    """The order columns ``(w_s/mean)*cos(k*theta)``, ``(w_s/mean)*sin(k*theta)`` of the
    orders k of ``harmonics`` whose frequency ``k*f_rot`` [Hz] lies above ``above_hz``, below
    0.45 ``fs_hz`` and more than two ``resolution`` [Hz] from ``avoid_hz``, with ``theta`` the
    trapezoidal integral of ``w_s`` [rad/s] (as :func:`torquemod.dsp.basis.unwrapped_angle`,
    in numpy's order); no column when none is kept or ``mean`` is 0."""
    n = w_s.size
    n_kept = 0
    kept = np.empty(harmonics.size, dtype=np.int64)
    for h in harmonics:
        if above_hz < h * f_rot < 0.45 * fs_hz and abs(h * f_rot - avoid_hz) > \
                2 * resolution:
            kept[n_kept] = h
            n_kept += 1
    if n_kept == 0 or mean == 0:
        return np.empty((n, 0))
    angle = np.empty(n)
    angle[0] = 0.0
    acc = 0.0
    for i in range(n - 1):
        step = 0.5 * (w_s[i + 1] + w_s[i]) / fs_hz
        acc = step if i == 0 else acc + step
        angle[i + 1] = acc
    raw = basis.order_columns(angle, kept[:n_kept])
    cols = np.empty_like(raw)
    for i in range(n):
        g = w_s[i] / mean
        for j in range(raw.shape[1]):
            cols[i, j] = raw[i, j] * g
    return cols


@numba.njit(cache=True, nogil=True)
def _separable_kept(cols, res):
    """:func:`_separable_orders`' decision in compiled code: the order columns ``cols`` (cos,
    sin per order) whose residuals ``res`` on the first design each keep at least
    :data:`ORDER_MIN_RESIDUAL` of their norm (sums of squares row by row, as
    :func:`~torquemod.dsp.lstsq.column_sums_of_squares`); ``cols`` itself when all do."""
    ss_res = lstsq.sums_of_squares_compiled(res)
    ss_col = lstsq.sums_of_squares_compiled(cols)
    keep = np.zeros(cols.shape[1], dtype=np.bool_)
    for k in range(cols.shape[1] // 2):
        a = np.sqrt(ss_res[2 * k] / ss_col[2 * k])
        b = np.sqrt(ss_res[2 * k + 1] / ss_col[2 * k + 1])
        keep[2 * k] = keep[2 * k + 1] = a >= ORDER_MIN_RESIDUAL and b >= ORDER_MIN_RESIDUAL
    if keep.all():
        return cols
    return np.ascontiguousarray(cols[:, keep])


@numba.njit(cache=True, nogil=True)
def _tracked_orders_compiled(speed, fs_hz, slow, harmonics, base, dn_b, factor_b, scale_b,
                             above_hz, avoid_hz, syrk, gemm, gemv, potrf, potrs):
    """:func:`_tracked_orders` in one call, step by step as it (the BLAS products numpy's
    own calls, :mod:`torquemod.dsp.numpyblas`; sums and the angle's trapezoidal sum in
    numpy's order): ``(cols, f_rot, status)``, status 1 where :func:`_tracked_orders` would
    fit by the SVD (the caller then runs it)."""
    n = speed.size
    n_slow = slow.shape[1]
    resolution = fs_hz / n
    y = speed.copy()
    cols = np.empty((n, 0))
    f_rot = np.nan
    for it in range(2):
        if it == 0:
            coef = lstsq.solve_compiled(dn_b, factor_b, scale_b, y, potrs)
        else:
            design = np.empty((n, base.shape[1] + cols.shape[1]))
            design[:, :base.shape[1]] = base
            design[:, base.shape[1]:] = cols
            dn, scale, _, factor, status = lstsq.factor_compiled(design, syrk, potrf)
            if status != 0:
                return cols, f_rot, 1
            coef = lstsq.solve_compiled(dn, factor, scale, y, potrs)
        w_s = numpyblas.matvec(slow, coef[:n_slow], gemv)
        mean = numpyblas.vector_sum(w_s) / n
        f_rot = abs(mean) / (2 * np.pi)
        cols = _speed_scaled_orders(w_s, mean, f_rot, harmonics, fs_hz, above_hz, avoid_hz,
                                    resolution)
        if cols.shape[1] == 0:
            return cols, f_rot, 0
        # _separable_orders
        fit = lstsq.solve_compiled(dn_b, factor_b, scale_b, cols, potrs)
        cols = _separable_kept(cols, cols - numpyblas.matmul_any(base, fit, gemm))
        if not cols.shape[1]:
            return cols, f_rot, 0
    return cols, f_rot, 0


#: an order's columns whose residual on the slow basis and the modulation keeps less than
#: this fraction of their norm are left to the slow basis (:func:`_separable_orders`)
ORDER_MIN_RESIDUAL = 0.1


def _separable_orders(cols: np.ndarray, base: np.ndarray,
                      base_factor: filters.LstsqFactor | None) -> np.ndarray:
    """The pairs of order columns ``cols`` (cos, sin per order) that the first design
    ``base`` (slow basis and modulation) does not already span: an order is kept when the
    least-squares residual of each of its columns on ``base`` keeps at least
    :data:`ORDER_MIN_RESIDUAL` of the column's norm.

    The slow basis's Slepian sequences (Slepian 1978) and polynomials reach about two frequency
    resolutions above the slow band's nominal top (a tone one resolution above it keeps
    ~1e-3 of its norm, a tone 0.01 resolution above it ~1e-6). An order that close to the
    band is a slow variation over this record: fitted beside the slow basis as well, the
    joint design is rank deficient to rounding (variance inflation ``1/r**2`` for a
    residual fraction r), the split between the slow part and the order is arbitrary, and
    so is every channel's step-8 mean, the slow part's mean (a V-Track platform turning at
    0.188 Hz on a one-revolution cycle with the slow band's top at 0.186 Hz gave a mean
    normal force of -1110 N on a 4200 N record). Left out, the slow basis models it.
    """
    if not cols.shape[1]:
        return cols
    fit = base_factor.solve(cols) if base_factor is not None else filters.lstsq(base, cols)[0]
    res = cols - base @ fit
    frac = np.sqrt(column_sums_of_squares(res) / column_sums_of_squares(cols))
    # an order is kept when both its columns keep ORDER_MIN_RESIDUAL (NaN: not kept)
    keep = [bool(a >= ORDER_MIN_RESIDUAL and b >= ORDER_MIN_RESIDUAL)
            for a, b in zip(frac[0::2].tolist(), frac[1::2].tolist(), strict=True)]
    if all(keep):
        return cols
    return np.ascontiguousarray(cols[:, np.repeat(np.array(keep, dtype=bool), 2)])

def _slow_and_orders(wheel: np.ndarray, platform: np.ndarray | None, fs_hz: float,
                     f_start_hz: float, max_hz: float, cfg: ProcessingConfig
                     ) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """The speed model's slow basis up to ``max_hz`` [Hz], the tracked rotation orders of
    both speeds above it and their frequencies [Hz] (:func:`tracked_orders`)."""
    n, nq = wheel.size, cfg.notch
    # the same first design for both speeds, and for every cycle of this length: made and
    # factored once (the same numbers as each time)
    slow, base, base_factor = _slow_and_base(int(n), float(fs_hz), float(max(max_hz, 0.0)),
                                             float(f_start_hz), int(cfg.slow.extra_sequences),
                                             int(cfg.slow.polynomial_degree))
    both = _both_by_block(wheel, platform, float(fs_hz), slow, base,
                          tuple(nq.wheel_harmonics), tuple(nq.platform_harmonics),
                          above_hz=float(max_hz), avoid_hz=float(f_start_hz))
    if both is not None:  # both speeds in one compiled call (the same numbers as below)
        return slow, *both
    cols, rotation_hz = [], []
    for speed, harmonics in ((wheel, nq.wheel_harmonics), (platform, nq.platform_harmonics)):
        if speed is not None:
            c, f_rot = _tracked_orders(speed, fs_hz, slow, harmonics, base, base_factor,
                                       above_hz=max_hz, avoid_hz=f_start_hz)
            cols.append(c)
            rotation_hz += [h * f_rot for h in harmonics]
    return slow, np.column_stack(cols), rotation_hz


@functools.lru_cache(maxsize=32)
def _slow_and_base(n: int, fs_hz: float, max_hz: float, f_start_hz: float, extra: int,
                   degree: int) -> tuple[np.ndarray, np.ndarray, filters.LstsqFactor | None]:
    """The slow basis (:func:`~torquemod.dsp.filters.slow_basis`), the first design of
    :func:`tracked_orders` with the modulation at ``f_start_hz`` (:func:`_order_base`) and its
    least-squares factor, for an ``n``-sample record; cached, read-only."""
    slow = filters.slow_basis(n, fs_hz, max_hz, extra=extra, degree=degree)
    base = _order_base(n, fs_hz, slow, f_start_hz)
    base.setflags(write=False)
    fac = filters.LstsqFactor.of(base)
    if fac is not None:
        fac.factor.setflags(write=False)
    return slow, base, fac


_BLOCK_INPUTS: dict[int, tuple] = {}


def _block_inputs(base: np.ndarray, slow: np.ndarray) -> tuple[np.ndarray, ...] | None:
    """:func:`_tracked_orders_fwl`'s arguments that depend on the read-only first design
    ``base`` and its slow basis alone: ``Q_b'``, ``Q_b'base``
    (:func:`~torquemod.dsp.blockbasis.slow_basis_t`), ``Q_b`` and ``slow`` in C order;
    kept by the design's identity (one per record length and band). None where that
    basis is not made."""
    hit = _BLOCK_INPUTS.get(id(base))
    if hit is not None and hit[0] is base and hit[1] is slow:
        return hit[2]
    basis_t = blockbasis.slow_basis_t(base)
    if basis_t is None:
        return None
    out = (basis_t[0], basis_t[1], np.ascontiguousarray(basis_t[0].T),
           np.ascontiguousarray(slow))
    for a in out[2:]:
        a.setflags(write=False)
    if len(_BLOCK_INPUTS) >= 32:
        _BLOCK_INPUTS.clear()
    _BLOCK_INPUTS[id(base)] = (base, slow, out)
    return out


@functools.lru_cache(maxsize=16)
def _orders_array(harmonics: tuple[int, ...]) -> np.ndarray:
    """The rotation orders as a read-only int64 array (cached)."""
    out = np.array([int(h) for h in harmonics], dtype=np.int64)
    out.setflags(write=False)
    return out


def _both_by_block(wheel: np.ndarray, platform: np.ndarray | None, fs_hz: float,
                   slow: np.ndarray, base: np.ndarray, wheel_harmonics: tuple[int, ...],
                   platform_harmonics: tuple[int, ...], *, above_hz: float, avoid_hz: float
                   ) -> tuple[np.ndarray, list[float]] | None:
    """:func:`_slow_and_orders`' orders of both speeds (the platform's: None for none) by
    :func:`_tracked_orders_block` in one compiled call (:func:`_both_orders_fwl`): the
    orders' columns side by side and their frequencies [Hz]; None where that route does
    not serve both (the caller takes each speed's own)."""
    speeds = (wheel,) if platform is None else (wheel, platform)
    if (base.flags.writeable or slow.shape[1] < 1
            or any(s.ndim != 1 or s.dtype != np.float64 or s.size < 2 or not
                   s.flags.c_contiguous or s.size != wheel.size for s in speeds)):
        return None
    inputs = _block_inputs(base, slow)
    if inputs is None:
        return None
    qb_t, rb, qb, slow_c = inputs
    cols, f_w, f_p, status = _both_orders_fwl(
        wheel, wheel if platform is None else platform, platform is not None, fs_hz, slow_c,
        _orders_array(wheel_harmonics), _orders_array(platform_harmonics), qb_t, rb, qb,
        above_hz, avoid_hz, blockbasis.MIN_PIVOT)
    if status != 0:
        return None
    rotation_hz = [h * float(f_w) for h in wheel_harmonics]
    if platform is not None:
        rotation_hz += [h * float(f_p) for h in platform_harmonics]
    return cols, rotation_hz


@numba.njit(cache=True, nogil=True)
def _both_orders_fwl(wheel, platform, has_platform, fs_hz, slow, wheel_harmonics,
                     platform_harmonics, qb_t, rb, qb, above_hz, avoid_hz, min_pivot):
    """:func:`_tracked_orders_fwl` of the wheel's speed and, ``has_platform``, the
    platform's: ``(columns, f_wheel, f_platform, status)``, the columns side by side
    (``np.column_stack``'s), status 1 where either speed's pivot is too small."""
    n = wheel.size
    c_w, f_w, s_w = _tracked_orders_fwl(wheel, fs_hz, slow, wheel_harmonics, qb_t, rb, qb,
                                        above_hz, avoid_hz, min_pivot)
    c_p, f_p, s_p = np.empty((n, 0)), np.nan, 0
    if has_platform:
        c_p, f_p, s_p = _tracked_orders_fwl(platform, fs_hz, slow, platform_harmonics, qb_t,
                                            rb, qb, above_hz, avoid_hz, min_pivot)
    k_w = c_w.shape[1]
    cols = np.empty((n, k_w + c_p.shape[1]))
    cols[:, :k_w] = c_w
    cols[:, k_w:] = c_p
    return cols, f_w, f_p, max(s_w, s_p)


def _tracked_orders_block(speed_rad_s: np.ndarray, fs_hz: float, slow: np.ndarray,
                          harmonics: tuple[int, ...], base: np.ndarray, *, above_hz: float,
                          avoid_hz: float) -> tuple[np.ndarray, float] | None:
    """:func:`_tracked_orders` by an orthonormal basis of its first design ``base`` (made
    once per read-only design, :func:`~torquemod.dsp.blockbasis.slow_basis_t`), extended
    by the orders for the refit (Frisch-Waugh-Lovell) instead of factoring ``[base,
    orders]``: the same least squares to rounding. None where that basis is not made or a
    pivot falls below :data:`~torquemod.dsp.blockbasis.MIN_PIVOT` (the caller then takes
    the factor route, whose decision it is)."""
    if (base.flags.writeable or speed_rad_s.ndim != 1 or speed_rad_s.dtype != np.float64
            or slow.shape[1] < 1 or speed_rad_s.size < 2):
        return None
    inputs = _block_inputs(base, slow)
    if inputs is None:
        return None
    qb_t, rb, qb, slow_c = inputs
    cols, f_rot, status = _tracked_orders_fwl(
        np.ascontiguousarray(speed_rad_s), float(fs_hz), slow_c, _orders_array(tuple(harmonics)),
        qb_t, rb, qb, float(above_hz), float(avoid_hz), blockbasis.MIN_PIVOT)
    return (cols, float(f_rot)) if status == 0 else None


@numba.njit(cache=True, nogil=True)
def _tracked_orders_fwl(speed, fs_hz, slow, harmonics, qb_t, rb, qb, above_hz, avoid_hz,
                        min_pivot):
    """:func:`_tracked_orders`'s steps with its least squares on ``Q_b`` (``qb_t``, ``rb =
    Q_b'base``, ``qb`` its transpose in C order) and, for the refit, Q_b extended by the
    orders: ``(cols, f_rot, status)``, status 1 where a pivot is too small."""
    n = speed.size
    n_slow = slow.shape[1]
    resolution = fs_hz / n
    y = np.empty((n, 1))
    y[:, 0] = speed
    qy = np.dot(qb_t, y)
    cols = np.empty((n, 0))
    f_rot = np.nan
    for it in range(2):
        if it == 0:
            coef = blockbasis.upper_solve(rb, qy)
        else:
            ext, ok = blockbasis.extension_t(qb_t, cols, min_pivot)
            if not ok:
                return cols, f_rot, 1
            qc = np.dot(ext, cols)  # Q_c'cols, upper triangular
            c_c = blockbasis.upper_solve(qc, np.dot(ext, y))
            coef = blockbasis.upper_solve(rb, qy - np.dot(np.dot(qb_t, cols), c_c))
        w_s = np.dot(slow, np.ascontiguousarray(coef[:n_slow, 0]))
        mean = w_s.sum() / n
        f_rot = abs(mean) / (2 * np.pi)
        cols = _speed_scaled_orders(w_s, mean, f_rot, harmonics, fs_hz, above_hz, avoid_hz,
                                    resolution)
        if cols.shape[1] == 0:
            return cols, f_rot, 0
        # _separable_orders: each column's residual on base
        cols = _separable_kept(cols, cols - np.dot(qb, np.dot(qb_t, cols)))
        if not cols.shape[1]:
            return cols, f_rot, 0
    return cols, f_rot, 0
