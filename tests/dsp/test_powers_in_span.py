"""The power of vectors in the span of a basis and further columns, against an SVD."""

import numpy as np
import pytest

from torquemod.dsp import projection
from torquemod.dsp.lstsq import LstsqFactor


@pytest.mark.parametrize("seed", [0, 1])
def test_powers_in_span_are_the_svds(seed):
    rng = np.random.default_rng(seed)
    n = 323
    t = np.linspace(-1, 1, n)
    b = np.column_stack([t ** k for k in range(6)] + [rng.standard_normal((n, 8))])
    m = np.column_stack([np.cos(9 * t), np.sin(9 * t), np.cos(18 * t) + 0.3 * t])
    v = rng.standard_normal((n, 7))
    qt_b = projection.orthonormal_basis_t(LstsqFactor.of(b))
    got = projection.powers_in_span(qt_b, m, v)
    u = np.linalg.svd(np.hstack([b, m]), full_matrices=False)[0]
    ref = ((u.T @ v) ** 2).sum(axis=0)
    np.testing.assert_allclose(got, ref, rtol=1e-12)  # measured ~1e-15


def test_columns_inside_the_span_are_refused():
    rng = np.random.default_rng(2)
    b = rng.standard_normal((100, 5))
    qt_b = projection.orthonormal_basis_t(LstsqFactor.of(b))
    m = b[:, :2] @ np.array([[1.0, 2.0], [0.5, -1.0]])  # inside B's span
    assert projection.powers_in_span(qt_b, m, rng.standard_normal((100, 3))) is None
