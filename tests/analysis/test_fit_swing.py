"""The modulation's own bias on the creep curve (issue 8, part 2).

An 8 N*m modulation swings the creepage sinusoidally, so a step's mean (creepage, CoA) lies
below the static curve where it bends. Noise-free points are generated here from the period
average of the static Polach curve computed by ``scipy.integrate.quad`` (independent of the
32-node rule in ``swing_average``), with V-Track-like swings (3e-4 at low torque to 5e-3 near
saturation). A static fit misses mu by > 2 %, the swing-aware fit is within 0.5 % (the issue's
target). The averaging itself is checked against quadrature, including swings past zero.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from torquemod.analysis.contact.polach import adhesion_curve, swing_average
from torquemod.analysis.fit import fit_polach
from torquemod.analysis.polachcurve import longitudinal_mean, polach_coa
from torquemod.errors import InputError

MU = 0.25
# theta = (mu, kA*s, kS*s): dry kA = 1, kS = 0.4 with s = 150 (initial slope
# 2*(kA + kS)*s/pi = 134); wet kA = 0.3, kS = 0.1 with s = 500 (initial slope 127)
SHAPES = {"dry": (MU, 1.0 * 150.0, 0.4 * 150.0), "wet": (MU, 0.3 * 500.0, 0.1 * 500.0)}
FRACTIONS = (0.05, 0.3, 0.55, 0.7, 0.8, 0.86)  # mean CoA / mu of the six torque steps


def _signed(theta, speed_m_s=None):
    def f(x):
        return np.sign(x) * polach_coa(np.abs(x), theta, speed_m_s=speed_m_s)
    return f


def _quad_mean(curve, xi0, a):
    """Brute-force period average (1/2pi) * int_0^2pi f(xi0 + a cos t) dt."""
    val, _ = quad(lambda t: float(curve(xi0 + a * np.cos(t))), 0.0, 2.0 * np.pi,
                  limit=200, epsabs=1e-13, epsrel=1e-10)
    return val / (2.0 * np.pi)


def _points(theta, fractions=FRACTIONS):
    """Mean creepage [-] of each step whose quadrature-averaged CoA is ``fraction * mu``,
    with a swing [-] growing towards saturation as the wheel-speed answer does."""
    curve = _signed(theta)
    swing = np.interp(fractions, [0.0, 0.55, 0.86], [3e-4, 1.5e-3, 5e-3])
    xi = np.array([brentq(lambda x, f=f, a=a: _quad_mean(curve, x, a) - f * theta[0],
                          0.0, 0.5, xtol=1e-15) for f, a in zip(fractions, swing, strict=True)])
    coa = np.array([_quad_mean(curve, x, a) for x, a in zip(xi, swing, strict=True)])
    return xi, coa, swing


@pytest.fixture(scope="module", params=list(SHAPES))
def case(request):
    theta = np.array(SHAPES[request.param])
    xi, coa, swing = _points(theta)
    return theta, xi, coa, swing, fit_polach(xi, coa, creepage_swing=swing)


def test_swing_average_against_quadrature():
    for name, theta in SHAPES.items():
        curve = _signed(np.array(theta))
        # (mean creepage, swing): bent part, swings crossing zero, saturation, tiny swing
        for xi0, a in ((0.004, 0.002), (0.001, 0.003), (-0.0005, 0.002), (0.0005, 0.005),
                       (0.02, 0.005), (0.003, 1e-5)):
            ref = _quad_mean(curve, xi0, a)
            # the signed Polach curve is odd and analytic, but has poles at
            # xi = +-i*mu/(kA*s) (1.7e-3 dry); swings wider than that slow the 32-node
            # trapezoidal rule (measured 1.4e-5 relative at a = 5e-3 about 5e-4, < 1e-8 for
            # a <= 3e-3 about >= 1e-3). 1e-4 is 50x below the fit's 0.5 % target; an unsigned
            # curve or a coarse rule is off by > 1e-2 in the zero-crossing cases.
            assert swing_average(curve, xi0, a) == pytest.approx(ref, rel=1e-4, abs=1e-15), \
                (name, xi0, a)
            assert longitudinal_mean(np.array([xi0]), np.array(theta), np.array([a]))[0] == \
                pytest.approx(abs(ref), rel=1e-4, abs=1e-15)
    # zero swing is the static curve itself, against the independent adhesion_curve
    x = np.linspace(-0.02, 0.02, 41)
    ref = adhesion_curve(x, mu=MU, k_a=1.0, k_s=0.4, stiffness=150.0)
    np.testing.assert_allclose(swing_average(_signed(np.array(SHAPES["dry"])), x, 0.0), ref,
                               rtol=1e-14, atol=1e-15)


def test_swing_crossing_zero_pulls_towards_zero():
    """Swinging through zero with an odd curve: the mean is below the linear-part value
    and of the sign of the mean creepage; a symmetric swing about zero averages to 0."""
    theta = np.array(SHAPES["dry"])
    curve = _signed(theta)
    assert abs(swing_average(curve, 0.0, 0.004)) < 1e-15
    m = swing_average(curve, 5e-4, 0.004)
    assert 0 < m < curve(5e-4)


def test_static_fit_is_biased_swing_fit_is_not(case):
    theta, xi, coa, swing, aware = case
    static = fit_polach(xi, coa)
    # the premise: the static fit is at least 2 % off on these points (measured
    # +5.4 % dry, +2.6 % wet, both flagged not determined); the swing-aware fit meets the
    # 0.5 % target (measured < 1e-13: the 32-node rule is exact to ~1e-15 at these points)
    assert abs(static.mu_estimate / MU - 1) >= 0.02, static.mu_estimate
    assert aware.mu_determined
    assert aware.mu == pytest.approx(MU, rel=5e-3)
    # the whole shape is recovered, not only mu (noise free: far tighter than 0.5 %)
    np.testing.assert_allclose(aware.theta, theta, rtol=1e-3)
    # the fitted model reproduces the quadrature means; the static curve lies above them
    np.testing.assert_allclose(aware.mean_curve(xi, swing), coa, rtol=1e-7, atol=1e-10)
    assert np.all(aware.curve(xi) >= coa)
    assert aware.options["creepage_swing"] == pytest.approx(list(swing))
    d = json.loads(json.dumps(aware.to_dict()))
    assert d["data"]["creepage_swing"] == pytest.approx(list(swing))


def test_swing_fit_weighted_and_lateral(case):
    """The effective-variance pass and the lateral combination use the swing model too."""
    _, xi, coa, swing, _ = case
    # noise free: se only sets how wide the profile interval of mu is; 1e-4 keeps its 95 %
    # range inside +-10 % so mu counts as determined (at 1e-3 six points leave it open)
    se = np.full(xi.size, 1e-4)
    w = fit_polach(xi, coa, coa_std=se, xi_std=1e-5 * np.ones(xi.size), creepage_swing=swing)
    assert w.mu == pytest.approx(MU, rel=5e-3)
    lateral = np.linspace(0.03, 0.01, xi.size)
    total = np.hypot(coa, lateral)
    lat = fit_polach(xi, total, lateral_coa=lateral, creepage_swing=swing)
    assert lat.mu == pytest.approx(MU, rel=5e-3)
    np.testing.assert_allclose(lat.residuals, 0.0, atol=1e-8)


def test_zero_swing_is_the_plain_fit():
    theta = np.array(SHAPES["dry"])
    xi, coa, _ = _points(theta)
    a = fit_polach(xi, coa)
    b = fit_polach(xi, coa, creepage_swing=np.zeros(xi.size))
    c = fit_polach(xi, coa, creepage_swing=np.full(xi.size, np.nan))
    np.testing.assert_array_equal(a.theta, b.theta)
    np.testing.assert_array_equal(a.theta, c.theta)
    assert a.mu_interval_95 == b.mu_interval_95 == c.mu_interval_95
    assert b.swing is None and b.options["creepage_swing"] is None
    np.testing.assert_array_equal(b.mean_curve(xi, 0.0), b.curve(xi))


def test_swing_length_checked():
    xi, coa, swing = _points(np.array(SHAPES["dry"]))
    with pytest.raises(InputError):
        fit_polach(xi, coa, creepage_swing=swing[:-1])


def test_velocity_dependent_model_with_swing():
    """Polach Eq. 9 (friction falling with slip velocity |xi|*V) averaged over the swing:
    points from quadrature at V = 1 m/s; the swing-aware fit returns the parameters."""
    theta = np.array([0.3, 150.0, 60.0, 0.4, 0.6])  # mu0, kA*s, kS*s, A, B [s/m]
    xi = np.array([2e-4, 1e-3, 2e-3, 3.5e-3, 5e-3, 7e-3, 9e-3, 0.012])
    speed = np.ones(xi.size)
    swing = np.interp(xi, [0.0, 0.012], [3e-4, 5e-3])
    curve = _signed(theta, speed_m_s=1.0)
    coa = np.array([_quad_mean(curve, x, a) for x, a in zip(xi, swing, strict=True)])
    fit = fit_polach(xi, coa, velocity_dependent=True, speeds_m_s=speed,
                     creepage_swing=swing)
    # noise free and a unique optimum: parameters to 1e-3 (measured ~1e-6)
    np.testing.assert_allclose(fit.theta, theta, rtol=1e-3)
    assert fit.mu == pytest.approx(0.3, rel=5e-3)
