"""The closed-form parameter derivatives of the fitted Polach curve against central
differences of the curve itself, and the fit that uses them against the fit that
differentiates numerically."""

from __future__ import annotations

import numpy as np
import pytest

import torquemod.analysis.fit as fitmod
from torquemod.analysis.fit import fit_polach
from torquemod.analysis.polachcurve import (
    longitudinal_mean,
    longitudinal_mean_jacobian,
    polach_coa,
    polach_coa_jacobian,
)

THETAS = [(0.35, 120.0, 30.0), (0.2, 15.0, 40.0), (0.5, 400.0, 5.0)]
XI = np.array([0.0, 2e-4, 1e-3, 4e-3, -6e-3, 0.02, 0.08])


def central(f, theta, i, rel=1e-6):
    """Central difference of ``f(theta)`` in parameter ``i`` (truncation error ~ (h^2) f''')."""
    th = np.array(theta, float)
    h = rel * th[i]
    up, dn = th.copy(), th.copy()
    up[i] += h
    dn[i] -= h
    return (f(up) - f(dn)) / (2 * h)


@pytest.mark.parametrize("theta", THETAS)
@pytest.mark.parametrize("swing", [None, np.array([0.0, 1e-4, 5e-4, 2e-3, 3e-3, 1e-3, 1e-2])])
def test_jacobian_matches_central_differences(theta, swing):
    if swing is None:
        jac = polach_coa_jacobian(XI, theta)

        def f(th):
            return polach_coa(XI, th)
    else:
        jac = longitudinal_mean_jacobian(XI, theta, swing)

        def f(th):
            return longitudinal_mean(XI, th, swing)
    assert jac.shape == (XI.size, 3)
    for i in range(3):
        num = central(f, theta, i)
        # central differences with h = 1e-6*theta_i: truncation ~1e-12 relative, rounding
        # ~eps/h ~ 1e-10 of the curve's scale (CoA <= 0.5)
        np.testing.assert_allclose(jac[:, i], num, rtol=1e-6, atol=1e-9 * max(1.0, theta[i]))


def test_fit_with_closed_form_jacobian_matches_finite_differences(monkeypatch):
    """The optimum does not depend on how the Jacobian is obtained nor on the profile's
    solver: the same parameters and profile interval as with scipy's finite differences
    and scipy's trf everywhere, within the solvers' tolerance."""
    rng = np.random.default_rng(7)
    theta = np.array([0.3, 80.0, 25.0])
    xi = np.array([5e-4, 1e-3, 2e-3, 3.5e-3, 5e-3, 8e-3, 1.2e-2])
    swing = np.full(xi.size, 8e-4)
    coa = longitudinal_mean(xi, theta, swing) + rng.normal(0, 1e-3, xi.size)
    exact = fit_polach(xi, coa, creepage_swing=swing, lateral_coa=np.full(xi.size, 0.02))
    monkeypatch.setattr(fitmod.FitModel, "jacobian", None)  # any use would raise
    monkeypatch.setattr(fitmod, "_lm_lower_bounded", lambda *a, **k: None)  # scipy's trf

    def numeric(fn):
        def wrapped(*a, **k):
            k["jac"] = "2-point"
            return fn(*a, **k)
        return wrapped
    monkeypatch.setattr(fitmod, "least_squares", numeric(fitmod.least_squares))
    approx = fit_polach(xi, coa, creepage_swing=swing, lateral_coa=np.full(xi.size, 0.02))
    # least_squares' xtol/ftol 1e-12 (the starts) and 1e-8 (the profile): 1e-6 relative
    np.testing.assert_allclose(exact.theta, approx.theta, rtol=1e-6)
    for a, b in zip(exact.mu_interval_95, approx.mu_interval_95, strict=True):
        assert (a is None) == (b is None)
        if a is not None:
            assert a == pytest.approx(b, rel=1e-6)


@pytest.mark.parametrize("target", [(2.0, 3.0), (-1.0, 2.0), (-1.0, -2.0)])
def test_lower_bounded_solver_matches_scipy(target):
    """A bounded linear least-squares problem whose optimum is inside, on one bound, on
    both: the same minimum as scipy's trf (to its tolerance)."""
    from scipy.optimize import least_squares
    A = np.array([[1.0, 0.2], [0.1, 2.0], [0.5, 0.5]])
    b = A @ np.array(target) + np.array([0.01, -0.02, 0.005])

    def resid(x, scale):
        return scale * (A @ x - b)

    def jac(x, scale):
        return scale * A
    got = fitmod._lm_lower_bounded(resid, jac, np.array([1.0, 1.0]), np.zeros(2), 3.0)
    ref = least_squares(resid, np.array([1.0, 1.0]), jac=jac, args=(3.0,),
                        bounds=(np.zeros(2), np.full(2, np.inf)), xtol=1e-14, ftol=1e-14,
                        gtol=1e-14)
    assert got is not None
    np.testing.assert_allclose(got[0], ref.x, rtol=1e-7, atol=1e-9)
    assert got[1] == pytest.approx(ref.cost, rel=1e-10)
    assert np.all(got[0] >= 0.0)
