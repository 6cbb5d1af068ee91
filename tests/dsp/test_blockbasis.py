"""Step 1's basis of [slow basis, orders] extended from the slow basis's own
(dsp.blockbasis) against an SVD of the whole design and against the route that factors the
whole design (LstsqFactor.of and CholeskyQR2)."""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from torquemod.dsp import blockbasis, filters, projection
from torquemod.processing import speedmodel

FS = 53.344


def _design(n: int, seed: int, near: float = 0.0):
    """The slow basis up to 1.2 Hz, two orders of a wobbling rotation (and, with ``near``,
    a tone ``near`` Hz from the slow band's top), two records."""
    t = np.arange(n) / FS
    rng = np.random.default_rng(seed)
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * t * (1 + 0.01 * t), [1, 2])
    if near:
        orders = np.hstack([orders, np.column_stack([np.cos(2 * np.pi * (1.2 + near) * t),
                                                     np.sin(2 * np.pi * (1.2 + near) * t)])])
    y = np.column_stack([30 + 0.3 * t + 8 * np.cos(2 * np.pi * 2.013 * t)
                         + rng.standard_normal(n),
                         30 + 2e-3 * np.cos(2 * np.pi * 2.013 * t) + 0.05 * np.cos(
                             2 * np.pi * 4.6 * t) + 2e-3 * rng.standard_normal(n)])
    return slow, orders, y


@pytest.mark.parametrize("n,seed", [(323, 0), (331, 1), (690, 2)])
def test_the_extended_basis_is_orthonormal_and_spans_the_design(n, seed):
    slow, orders, y = _design(n, seed)
    qs_t = projection.orthonormal_basis_t(filters.LstsqFactor.of(slow))
    qt, r_y, qy, pivot = blockbasis.extended_basis_t(qs_t, orders, y)
    assert qt.shape == (slow.shape[1] + orders.shape[1], n)
    # CholeskyQR2 and Gram-Schmidt twice: orthonormal to rounding (~1e-15 measured)
    np.testing.assert_allclose(qt @ qt.T, np.eye(qt.shape[0]), rtol=0, atol=1e-13)
    # the projection on the design's span: that of the route that factors the whole
    # design (1.3-2.8e-12 apart, measured; bound 1e-11), and as close to an SVD's as it
    # (both 1.1-3.1e-11 from it, the SVD's own rounding at condition number ~1e3; 1e-10)
    b = np.hstack([slow, orders])
    q_ref = projection.orthonormal_basis_t(filters.LstsqFactor.of(b))
    np.testing.assert_allclose(qt.T @ qt, q_ref.T @ q_ref, rtol=0, atol=1e-11)
    u = np.linalg.svd(b / np.linalg.norm(b, axis=0), full_matrices=False)[0]
    np.testing.assert_allclose(qt.T @ qt, u @ u.T, rtol=0, atol=1e-10)
    # the records (~30) less their projection: the whole-design route's to 1.4e-11 -
    # 2.9e-10 absolute (measured), bound 1e-9
    np.testing.assert_allclose(r_y, y - q_ref.T @ (q_ref @ y), rtol=0, atol=1e-9)
    np.testing.assert_allclose(qy, 0.0, rtol=0, atol=1e-9)
    # the pivot: the smallest squared diagonal element of the whole normalised design's
    # triangular factor past the slow basis's block, as Householder QR gives it (1.1e-13
    # relative apart, measured; bound 1e-11). LstsqFactor.of's, from the normal equations,
    # is 1e-9 - 1e-5 relative off it here: far inside the factor 100 between the block
    # route's threshold and the one at which LstsqFactor.of refuses a design
    r = np.linalg.qr(b / np.linalg.norm(b, axis=0), mode="r")
    want = float(np.min(np.diag(r)[slow.shape[1]:] ** 2))
    assert pivot == pytest.approx(want, rel=1e-11)


def test_a_column_nearly_in_the_slow_span_leaves_the_decision_to_the_factor():
    # a tone at 0.9 Hz, inside the slow band, lies in the slow basis's span to ~1e-7 of
    # its norm: the pivot falls below the block route's threshold, so step 1 takes the
    # whole design's route (which refuses it: the SVD)
    slow, orders, y = _design(323, 3, near=-0.3)
    qs_t = projection.orthonormal_basis_t(filters.LstsqFactor.of(slow))
    out = blockbasis.extended_basis_t(qs_t, orders, y)
    assert out is None or out[3] < blockbasis.MIN_PIVOT
    assert blockbasis.removal_basis(y, slow, orders) is None
    removal = speedmodel._SlowOrdersRemoval(y, slow, orders, FS)
    assert removal.qt is None and removal.fac is None


def test_a_zero_column_is_refused():
    slow, orders, y = _design(323, 4)
    orders[:, 1] = 0.0
    qs_t = projection.orthonormal_basis_t(filters.LstsqFactor.of(slow))
    assert blockbasis.extended_basis_t(qs_t, orders, y) is None


def test_the_removal_takes_the_block_route_and_keeps_the_factor_for_fallbacks():
    slow, orders, y = _design(323, 5)
    slow.setflags(write=False)
    removal = speedmodel._SlowOrdersRemoval(y, slow, orders, FS, (2,))
    assert removal._fac is speedmodel._NOT_YET  # not made: the block route
    assert removal._b is speedmodel._NOT_YET  # (nor the design B)
    assert blockbasis.slow_basis_t(slow) is blockbasis.slow_basis_t(slow)  # kept
    # the removal at a frequency against the least-squares fit of the whole model
    m = speedmodel.modulation_columns(323, FS, 2.01, (2,))
    d = np.hstack([m, slow, orders])
    coef = np.linalg.lstsq(d / np.linalg.norm(d, axis=0), y, rcond=None)[0]
    coef /= np.linalg.norm(d, axis=0)[:, None]
    want = y - np.hstack([slow, orders]) @ coef[m.shape[1]:]
    # records ~30: the two routes' rounding amplified by the condition number, 1.5e-10
    # measured (the SVD's own share as large, see above); bound 1e-9
    np.testing.assert_allclose(removal.at(2.01), want, rtol=0, atol=1e-9)
    assert removal.fac is not None  # made on demand


@pytest.mark.parametrize("seed,wobble", [(0, 0.0), (1, 0.02), (2, 0.1)])
def test_tracked_orders_by_the_block_route_are_the_factor_routes(seed, wobble, monkeypatch):
    from torquemod.processing import trackedorders
    n = 323
    t = np.arange(n) / FS
    rng = np.random.default_rng(seed)
    slow, base, fac = trackedorders._slow_and_base(n, FS, 1.2, 2.0, 2, 5)
    f_rot = 4.6
    w = 2 * np.pi * f_rot * (1 + wobble * np.sin(2 * np.pi * 0.3 * t))
    speed = w * (1 + 1e-3 * np.cos(np.cumsum(w) / FS)) + 1e-3 * np.cos(
        2 * np.pi * 2.0 * t) + 1e-4 * rng.standard_normal(n)
    kw = dict(above_hz=1.2, avoid_hz=2.0)
    got = trackedorders._tracked_orders_block(speed, FS, slow, (1, 2, 3), base, **kw)
    assert got is not None
    monkeypatch.setattr(trackedorders, "_tracked_orders_block", lambda *a, **k: None)
    ref = trackedorders._tracked_orders(speed, FS, slow, (1, 2, 3), base, fac, **kw)
    # the slow part's mean, its frequency: 0.8-1.5e-15 relative apart measured, bound 1e-13
    assert got[1] == pytest.approx(ref[1], rel=1e-13)
    # the orders' columns (the angle, ~180 rad here, from the slow part): 1.3-6.1e-13
    # apart measured, bound 1e-10
    assert got[0].shape == ref[0].shape
    np.testing.assert_allclose(got[0], ref[0], rtol=0, atol=1e-10)



@numba.njit(cache=False)
def _extension_q_column_by_column(qs_t, qs, cols):
    """:func:`blockbasis._extension_q` as it was with each column's norm summed alone over
    the samples (the former kernel, compiled the same way)."""
    n = qs_t.shape[1]
    k = cols.shape[1]
    rt = np.empty((k, n))
    for j in range(k):
        s = 0.0
        for t in range(n):
            s += cols[t, j] * cols[t, j]
        if not (s > 0.0 and s < np.inf):
            return rt, 0.0, False
        inv = 1.0 / math.sqrt(s)
        for t in range(n):
            rt[j, t] = cols[t, j] * inv
    for _ in range(2):
        c = np.dot(rt, qs)
        rt = rt - np.dot(c, qs_t)
    u, ok = blockbasis._cholesky_upper(np.dot(rt, rt.T))
    if not ok:
        return rt, 0.0, False
    pivot = 1.0
    for j in range(k):
        pivot = min(pivot, u[j, j] * u[j, j])
    q1 = blockbasis._times_inverse_t(u, rt)
    u2, ok = blockbasis._cholesky_upper(np.dot(q1, q1.T))
    if not ok:
        return rt, 0.0, False
    return blockbasis._times_inverse_t(u2, q1), pivot, True


@pytest.mark.parametrize("k", [2, 5, 13])
def test_extension_is_the_former_kernel_bit_for_bit(k):
    """The extension with the columns' norms summed four columns at a time
    (``lstsq._sums_of_squares``): the numbers of the former kernel, one column at a time."""
    rng = np.random.default_rng(k)
    n = 61
    t = np.linspace(-1.0, 1.0, n)
    qs_t = np.linalg.qr(np.column_stack([t ** j for j in range(4)]))[0].T.copy()
    qs = np.ascontiguousarray(qs_t.T)
    cols = rng.standard_normal((n, k)) * rng.uniform(0.01, 100.0, k)
    got = blockbasis._extension_q(qs_t, qs, cols)
    want = _extension_q_column_by_column(qs_t, qs, cols)
    assert got[2] and want[2]
    np.testing.assert_array_equal(got[0], want[0])
    assert got[1] == want[1]
