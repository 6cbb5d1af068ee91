"""mu from the phase (issue 8): known-truth recovery, the honesty rule, interval coverage.

Truth: phases generated from the rigid-wheel law tan(phi) = C/k(CoA) on Polach curves (and,
with the modulation's creepage swing, from the describing-function slope), at the V-Track
step proportions (0.0035, 0.35, 0.68, 0.84, 0.92, 1.0) x the highest utilisation, with
0.1 deg of phase noise per step (the chain's sine-fit standard error per step is 0.03-0.1 deg).
"""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.errors import InputError
from torquemod.phasefit import _invert, fit_mu_from_phase, polach_h, polach_h_slope
from torquemod.testing import synthetic_phase_progression

C = 10.2  # Omega*J*V/(R^2*N) of V-Track with J = 4 kg m^2
FRACTIONS = np.array([0.0035, 0.35, 0.68, 0.84, 0.92, 1.0])


def truth(mu, r, k_scale, u_max, *, swing=False):
    return synthetic_phase_progression(mu, r, k_scale, u_max, constant=C, swing=swing)


def test_h_and_its_inverse():
    x = np.array([0.0, 0.01, 0.3, 1.0, 4.0])
    for r in (0.5, 1.0, 2.5):
        rising = np.concatenate([[True], np.cumprod(polach_h_slope(x[1:], r) > 0) > 0])
        # (with r = 2.5, h has a hump: x = 4 lies beyond it, on the falling branch)
        np.testing.assert_allclose(_invert(polach_h(x[rising], r), r), x[rising], atol=1e-9)
        h = 1e-6
        np.testing.assert_allclose(polach_h_slope(x[1:], r),
                                   (polach_h(x[1:] + h, r) - polach_h(x[1:] - h, r)) / (2 * h),
                                   rtol=1e-6)
    # initial slope 2(kA+kS)/pi relative to kS: (2/pi)(r + 1) (FACTS §2)
    assert polach_h_slope(0.0, 2.5) == pytest.approx(2 / np.pi * 3.5)


@pytest.mark.parametrize("r,k_scale", [(2.5, 60.0), (3.0, 40.0)])
@pytest.mark.parametrize("known", [True, False])
def test_noise_free_recovery(r, k_scale, known):
    coa, phase, _ = truth(0.25, r, k_scale, 0.8)
    fit = fit_mu_from_phase(coa, phase, np.full(6, 0.1), constant=C if known else None)
    assert fit.mu_determined
    assert fit.mu == pytest.approx(0.25, rel=2e-3)
    lo, hi = fit.mu_interval_95
    assert lo < 0.25 < hi
    np.testing.assert_allclose(fit.phase_curve(coa), phase, atol=0.01)
    np.testing.assert_allclose(fit.utilisation, FRACTIONS * 0.8, rtol=3e-3)
    if known:
        assert fit.constant == C


def test_swing_is_what_is_measured():
    """With the modulation's creepage swing the phases rise faster near saturation; fitted
    with the swing, mu is right; ignoring it biases it."""
    coa, phase, sw = truth(0.25, 2.5, 60.0, 0.86, swing=True)
    small, _, _ = truth(0.25, 2.5, 60.0, 0.86)
    assert phase[-1] - small[-1] > 0.5  # the swing's effect at the top step [deg]
    fit = fit_mu_from_phase(coa, phase, np.full(6, 0.1), constant=C, creepage_swing=sw)
    assert fit.mu == pytest.approx(0.25, rel=2e-3)
    unused = fit_mu_from_phase(coa, phase, np.full(6, 0.1), creepage_swing=sw)
    assert any("swing is not used" in w for w in unused.warnings)
    plain = fit_mu_from_phase(coa, phase, np.full(6, 0.1))
    assert abs(plain.mu_estimate / 0.25 - 1) > abs(fit.mu / 0.25 - 1)


def test_low_utilisation_does_not_determine_mu():
    coa, phase, _ = truth(0.25, 2.5, 60.0, 0.3)
    rng = np.random.default_rng(0)
    fit = fit_mu_from_phase(coa, phase + 0.1 * rng.standard_normal(6), np.full(6, 0.1))
    assert not fit.mu_determined and fit.mu is None
    lo, hi = fit.mu_interval_95
    assert hi is None and coa.max() <= lo <= 0.25
    assert fit.warnings and "does not determine" in fit.warnings[0]
    d = fit.to_dict()
    assert d["mu"] is None and d["mu_interval_95"][1] is None


def test_interval_coverage_monte_carlo():
    """95 % intervals over dry and wet curves up to 80 % and 86 % with 0.1 deg noise: at
    least 36 of 40 contain the truth (90 %; with a true rate of 95 % fewer than 36 happens
    with probability 5 %)."""
    rng = np.random.default_rng(42)
    hits = 0
    for t in range(40):
        r, k_scale = ((2.5, 60.0), (3.0, 40.0))[t % 2]
        mu = float(rng.uniform(0.15, 0.4))
        coa, phase, _ = truth(mu, r, k_scale, (0.8, 0.86)[(t // 2) % 2])
        fit = fit_mu_from_phase(coa, phase + 0.1 * rng.standard_normal(6), np.full(6, 0.1),
                                n_grid=20)
        lo, hi = fit.mu_interval_95
        if fit.mu_determined:
            hits += lo <= mu <= hi
            assert abs(fit.mu / mu - 1) < 0.03
        else:
            hits += lo <= mu
    assert hits >= 36


def test_bad_input():
    with pytest.raises(InputError, match="at least 4 steps"):
        fit_mu_from_phase([0.1, 0.2, 0.3], [10, 20, 30], [0.1, 0.1, 0.1])
    with pytest.raises(InputError, match="expected 4"):
        fit_mu_from_phase([0.1, 0.2, 0.3, 0.4], [10, 20, 30], [0.1] * 4)
