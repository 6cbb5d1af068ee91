"""The least-squares helpers' compiled kernels against plain Python, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.dsp import lstsq


def _column_sums_of_squares(d):
    """Each column's squares summed over the rows in order, one Python float at a time."""
    out = []
    for j in range(d.shape[1]):
        s = 0.0
        for v in d[:, j].tolist():
            s += v * v
        out.append(s)
    return np.array(out)


@pytest.mark.parametrize("m", [1, 2, 3, 4, 5, 7, 8, 9, 12, 13, 23])
def test_sums_of_squares_are_the_row_order_sums(m):
    rng = np.random.default_rng(m)
    d = rng.standard_normal((97, m)) * rng.uniform(1e-3, 1e3, m)
    want = _column_sums_of_squares(d)
    assert np.array_equal(lstsq._sums_of_squares(d), want)
    # a strided view takes the same route and gives the same numbers
    wide = np.empty((97, 2 * m))
    wide[:, ::2] = d
    assert np.array_equal(lstsq._sums_of_squares(wide[:, ::2]), want)
    if m >= 2:  # einsum's order for two or more columns, which the kernel stands for
        assert np.array_equal(lstsq.column_sums_of_squares(d), np.einsum("ij,ij->j", d, d))


@pytest.mark.parametrize("k", [1, 3, 4, 6, 9])
def test_row_sums_of_squares_are_the_sums_one_row_at_a_time(k):
    rng = np.random.default_rng(10 + k)
    a = rng.standard_normal((k, 83)) * rng.uniform(1e-3, 1e3, (k, 1))
    want = _column_sums_of_squares(np.ascontiguousarray(a.T))  # row i's, in sample order
    assert np.array_equal(lstsq._row_sums_of_squares(a), want)


@pytest.mark.parametrize("shape", [(323, 23), (323, 8), (97, 5), (3, 200), (1, 1), (0, 4)])
def test_normalised_design_is_numpys_division(shape):
    rng = np.random.default_rng(shape[0] + shape[1])
    d = rng.standard_normal(shape) * rng.uniform(1e-3, 1e3, shape[1])
    dn, scale = lstsq._normalised(d)
    if shape[0] == 0:  # no rows: zero norms, no design
        assert dn.shape == (0, shape[1])
        return
    assert np.array_equal(scale, np.sqrt(_column_sums_of_squares(d)))
    assert np.array_equal(dn, d / scale)  # numpy's division, element by element
    # a strided design gives the same numbers
    wide = np.empty((shape[0], 2 * shape[1]))
    wide[:, ::2] = d
    dn2, scale2 = lstsq._normalised(wide[:, ::2])
    assert np.array_equal(dn2, dn) and np.array_equal(scale2, scale)
