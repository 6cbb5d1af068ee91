"""The compiled least squares for kernels (torquemod.dsp.lstsq.lstsq_compiled,
leading_residual) against the SVD and the step-by-step route."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.dsp.lstsq import (
    LstsqFactor,
    lapack_addresses,
    leading_residual,
    lstsq,
    lstsq_compiled,
)


@pytest.mark.parametrize("n,m,seed", [(323, 2, 0), (323, 8, 1), (690, 12, 2)])
def test_lstsq_compiled_against_the_svd(n, m, seed):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 53.344
    d = np.column_stack([np.ones(n), t, *[np.cos((k + 1) * t + k) for k in range(m - 2)]])
    y = d @ rng.standard_normal(m) + 1e-3 * rng.standard_normal(n)
    coef, status = lstsq_compiled(d, y, *lapack_addresses())
    assert status == 0
    ref = np.linalg.lstsq(d, y, rcond=None)[0]
    # condition numbers here ~1e2-1e3: both agree to ~1e-13 relative; bound 1e-10
    np.testing.assert_allclose(coef, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
    np.testing.assert_allclose(coef, lstsq(d, y)[0], rtol=1e-12, atol=0)


def test_lstsq_compiled_reports_what_needs_the_svd():
    n = 100
    d = np.column_stack([np.ones(n), np.arange(n), np.zeros(n)])  # a zero column
    assert lstsq_compiled(d, np.ones(n), *lapack_addresses())[1] == 1
    d = np.column_stack([np.ones(n), np.arange(n), np.arange(n) + 1e-9])  # collinear
    assert lstsq_compiled(d, np.ones(n), *lapack_addresses())[1] in (2, 3)



@pytest.mark.parametrize("k,seed", [(1, 0), (2, 1), (3, 2)])
def test_leading_residual_is_the_projection_off_the_other_columns(k, seed):
    rng = np.random.default_rng(seed)
    n = 323
    t = np.arange(n) / 53.344
    d = np.ascontiguousarray(np.column_stack(
        [np.cos(2.0 * t + j) for j in range(k)]
        + [np.ones(n), t, *[np.cos(0.3 * (j + 1) * t) for j in range(6)]]))
    d[:, 0] += 0.1 * rng.standard_normal(n)
    fac = LstsqFactor.of(d, keep_gram=True)
    got, status = leading_residual(d, fac.gram, fac.dn, fac.scale, k, *lapack_addresses())
    assert status == 0
    # the route it replaces: the trailing factor's solve, numpy's product
    sub = fac.trailing(k)
    ref = d[:, :k] - d[:, k:] @ sub.solve(d[:, :k])
    # the same solve; the product by another BLAS call: ~1e-16 of the columns' scale
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-13 * np.abs(d[:, :k]).max())
    # and the projection off the other columns by the SVD (condition number ~1e3 here)
    other = d[:, k:]
    u = np.linalg.svd(other, full_matrices=False)[0]
    np.testing.assert_allclose(got, d[:, :k] - u @ (u.T @ d[:, :k]), rtol=0, atol=1e-11)


def test_leading_residual_reports_a_singular_block():
    n = 50
    d = np.ascontiguousarray(np.column_stack([np.arange(n) % 3, np.ones(n), np.ones(n)]),
                             dtype=float)
    gram = d.T @ d / np.outer(np.linalg.norm(d, axis=0), np.linalg.norm(d, axis=0))
    dn = d / np.linalg.norm(d, axis=0)
    assert leading_residual(d, gram, dn, np.linalg.norm(d, axis=0), 1,
                            *lapack_addresses())[1] != 0
