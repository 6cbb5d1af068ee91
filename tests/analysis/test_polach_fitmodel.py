"""The fit's fast model (FitModel) against the reference curve functions, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.analysis.polachcurve import longitudinal_mean, longitudinal_mean_jacobian
from torquemod.analysis.polachfitmodel import FitModel

XI = np.array([0.0, 2e-4, 1e-3, 4e-3, -6e-3, 0.02, 0.08, 3e-3])
SWING = np.array([0.0, 1e-4, 5e-4, 2e-3, 3e-3, 1e-3, 1e-2, 8e-3])
THETAS = [(0.35, 120.0, 30.0), (0.2, 15.0, 40.0), (0.5, 400.0, 5.0), (0.3, 0.0, 1e6)]


def reference(theta, swing, lateral, sigma):
    """hypot(CoA_mean, lateral) and its Jacobian / sigma as the fit computed them before."""
    f = longitudinal_mean(XI, np.asarray(theta, float), swing)
    m = np.hypot(f, lateral)
    ratio = np.divide(f, m, out=np.ones_like(f), where=m > 0)
    return m, ratio[:, None] * longitudinal_mean_jacobian(XI, theta, swing) / sigma[:, None]


@pytest.mark.parametrize("swing", [None, SWING])
@pytest.mark.parametrize("lateral", [np.zeros(XI.size), np.linspace(0.0, 0.05, XI.size)])
def test_fit_model_equals_reference_bit_for_bit(swing, lateral):
    """Same operations in the same order: every value identical (array_equal, not close:
    a different summation order over the swing's nodes already fails it), also when the
    parameters change between calls and when mu stays (the kept |xi|/mu)."""
    model = FitModel(XI, swing, lateral)
    sigma = np.linspace(1e-3, 3e-3, XI.size)
    rng = np.random.default_rng(3)
    rand = np.column_stack([rng.uniform(0.05, 1.0, 40), 10 ** rng.uniform(0, 3.5, (40, 2))])
    # mu held for a few calls (the kept |xi|/mu), then random parameters
    for theta in [*THETAS, *[(0.2, a, s) for a, s in [(10.0, 3.0), (90.0, 7.0)]], *rand]:
        th = np.array(theta, float)
        m_ref, j_ref = reference(th, swing, lateral, sigma)
        with np.errstate(over="ignore"):
            m = model.model(th)
            j = model.jacobian(th, sigma)
            j2 = model.jacobian(th, sigma, full=False)
        assert np.array_equal(m, m_ref)
        assert np.array_equal(j, j_ref)
        assert np.array_equal(j2, j_ref[:, 1:]) and j2.flags.c_contiguous
