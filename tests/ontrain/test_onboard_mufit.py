"""The available adhesion from the creep-coefficient progression (onboard.mufit, the on-board
use of torquemod.analysis.friction) and the friction-change detector, against curves computed
independently of the fit's tables, the phase path of the same estimator, and Monte Carlo
coverage."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from torquemod.analysis.contact.polach import force_function
from torquemod.analysis.phasefit import fit_mu_from_phase
from torquemod.dsp.phase import periodogram_density
from torquemod.ontrain.estimator import ChangeDetector
from torquemod.ontrain.mufit import fit_creep_progression, fit_segment, group_points
from torquemod.ontrain.window import WindowResult


def _curve(r: float, a_ratio: float, beta: float, mu0: float, k0: float):
    """(CoA, k, mu at the slip) along a Polach curve with falling friction, by brute force:
    CoA(x) = mu0*phi(x)*h(x/phi(x)) on a fine grid, k = k0*dCoA/dx / dCoA/dx(0) by central
    differences (independent of the fit's analytic table)."""
    x = np.linspace(0.0, 60.0, 600001)
    phi = (1 - a_ratio) * np.exp(-beta * x) + a_ratio
    coa = mu0 * phi * force_function(x / phi, k_a=r, k_s=1.0)
    slope = np.gradient(coa, x)
    top = np.flatnonzero(slope <= 0)
    n = top[0] if top.size else x.size
    return coa[:n], k0 * slope[:n] / slope[0], mu0 * phi[:n]


def _sample(curve, fractions, rel_noise, rng):
    """(CoA, k, its standard error, the available adhesion: the curve's peak, or mu0 for a
    constant-friction curve that rises to it)."""
    coa, k, _ = curve
    peak = coa[-1] if curve[0][-1] < 0.999 * curve[2][0] else curve[2][0]
    c = np.asarray(fractions) * peak
    kk = np.interp(c, coa, k)
    noisy = kk * (1 + rel_noise * rng.standard_normal(c.size)) if rng is not None else kk
    return c, noisy, np.maximum(rel_noise, 1e-3) * kk, float(peak)


def test_constant_friction_recovered_and_agrees_with_phasefit():
    curve = _curve(2.5, 1.0, 0.0, 0.40, 50.0)
    coa, k, se, mu_true = _sample(curve, np.linspace(0.1, 0.85, 8), 0.02, None)
    fit = fit_creep_progression(coa, k, se, coa_now=coa[-1])
    # exact data stated with 2 % errors: determined, within 2 %
    assert fit.determined
    assert abs(fit.mu / mu_true - 1) < 0.02
    assert fit.mu_low <= mu_true <= fit.mu_high
    # the phase path of the same estimator on the same points (as phases at a constant C)
    c = 0.5
    ph = np.degrees(np.arctan(c / k))
    ph_se = np.degrees(c / (k * k + c * c) * se)
    ref = fit_mu_from_phase(coa, ph, ph_se, constant=c)
    assert abs(fit.mu / ref.mu_estimate - 1) < 0.02


def test_falling_friction_not_claimed_from_low_utilisation():
    """Up to 60 % of the peak the curve's fall does not fix mu once the friction may fall
    with the slip: no mu, and the interval's lower end stays at or below the truth."""
    curve = _curve(2.5, 0.4, 0.15, 0.55, 80.0)
    coa, k, se, mu_true = _sample(curve, np.linspace(0.15, 0.6, 8), 0.05, None)
    fit = fit_creep_progression(coa, k, se, coa_now=coa[-1])
    assert not fit.determined
    assert fit.mu_low <= mu_true


@pytest.mark.parametrize("shape", [(2.5, 1.0, 0.0), (3.0, 0.7, 0.05)],
                         ids=["constant", "falling"])
def test_interval_coverage_monte_carlo(shape):
    """95 % intervals over 60 noisy replicates (5 % per point, to 85 % of the peak): the
    truth inside in >= 52 of 60 (binomial: P(X < 52 | p = 0.95) ~ 1 %)."""
    rng = np.random.default_rng(7)
    curve = _curve(*shape, 0.35, 40.0)
    inside = given = 0
    for _ in range(60):
        coa, k, se, mu_true = _sample(curve, np.linspace(0.1, 0.85, 8), 0.05, rng)
        fit = fit_creep_progression(coa, k, se, coa_now=coa[-1])
        hi = fit.mu_high if math.isfinite(fit.mu_high) else np.inf
        inside += fit.mu_low <= mu_true <= hi
        given += fit.determined
    print(shape, "inside", inside, "determined", given)
    assert inside >= 52


def _window(pos: float, coa: float, k: float, rel: float = 0.05) -> WindowResult:
    return WindowResult(time_s=pos / 20, position_m=pos, speed_m_s=20.0,
                        wheel_speed_rad_s=43.0, dc_torque_nm=coa * 9.2e4, accel_m_s2=0.0,
                        coa=coa, coa_se=1e-3, creepage=0.0, phase_deg=10.0,
                        phase_se_deg=0.5, creep_coefficient=k, creep_coefficient_se=rel * k,
                        creepage_swing=1e-4, wheel_excess_accel_m_s2=0.0)


def test_change_detector_alarms_at_a_change_and_not_on_scatter():
    rng = np.random.default_rng(3)
    dry = _curve(2.5, 1.0, 0.0, 0.5, 80.0)
    coa, k, se, _ = _sample(dry, np.linspace(0.1, 0.8, 8), 0.01, None)
    model = fit_creep_progression(coa, k, se)
    det = ChangeDetector(drift=1.0, threshold=10.0)
    levels = np.linspace(0.05, 0.35, 4)
    # 600 windows on the fitted curve with 20 % scatter: no alarm
    for i in range(600):
        c = levels[(i // 12) % 4]
        kk = float(model.creep_coefficient(c)) * (1 + 0.2 * rng.standard_normal())
        assert det.update(_window(5.0 * i, c, kk), model) is None
    # then rail with a quarter of the creep coefficient from 3000 m: an alarm within 8 windows
    # that dates the change within 15 m
    for j in range(8):
        c = 0.1
        kk = 0.25 * float(model.creep_coefficient(c))
        start = det.update(_window(3000.0 + 5.0 * j, c, kk), model)
        if start is not None:
            break
    assert start is not None and abs(start - 3000.0) <= 15.0
    # a window whose adhesion lies beyond the fitted curve counts even while stepping
    det.reset()
    alarms = [det.update(_window(4000.0 + 5 * j, 0.6, 5.0), model, steady=False)
              for j in range(3)]
    assert alarms[-1] is not None


@pytest.mark.parametrize("n", [1000, 777, 4096])
def test_periodogram_density_matches_scipy(n):
    rng = np.random.default_rng(n)
    x = rng.standard_normal(n) + 2.0
    f_ref, p_ref = signal.periodogram(x - x.mean(), 1000.0, window="hann", detrend=False,
                                      scaling="density")
    f, p = periodogram_density(x, 1000.0)
    np.testing.assert_array_equal(f, f_ref)
    np.testing.assert_allclose(p, p_ref, rtol=1e-12, atol=1e-15 * p_ref.max())


def _burckhardt_k(coa, mu, k0, d_over_mu=3.0):
    """k at the CoA values of Burckhardt's law CoA = mu_B*(1 - exp(-c*xi)) - d*xi scaled
    so that its peak is mu and its initial slope k0, by inverting the curve on a fine grid
    (an independent reference: no use of the fit's tables)."""
    d = d_over_mu * mu
    c = (k0 - d * np.log1p(k0 / d)) / mu
    mub = (k0 + d) / c
    xi = np.linspace(0.0, 1.0, 200_001)
    curve = mub * (1 - np.exp(-c * xi)) - d * xi
    top = int(np.argmax(curve))
    x = np.interp(coa, curve[:top], xi[:top])
    return mub * c * np.exp(-c * x) - d


@pytest.mark.parametrize("law", ["burckhardt", "exponential", "tanh"])
def test_saturating_laws_outside_polach_are_covered(law):
    """Creep laws other than Polach's (Burckhardt, a pure exponential approach, tanh), k
    measured to 4 % with the estimator's 5 % model error, 8 points up to 85 % of mu, 40
    replicates: the 95 % interval of the default family (Polach + the saturating
    g = 1 - u^p) holds the true mu in >= 36/40 (binomial: 90 % coverage is what the issue
    asks; at a true 95 % rate fewer than 36 happens with probability ~5 %). The exponential
    law is determined in most replicates (29 of these 40), within 5 % (median); Burckhardt's
    in about half (21 of 40; 28 before the family held the hyperbolic fall ``(1 - u)^2``,
    which with these 6.4 % errors fits the points as well while peaking 1.3-1.5 times
    higher, so the interval must hold it); tanh's mu stays undetermined (honestly: the data
    do not fix it)."""
    mu, k0 = 0.2, 60.0
    u = np.linspace(0.1, 0.85, 8)
    coa = u * mu
    k_true = {"burckhardt": _burckhardt_k(coa, mu, k0), "exponential": k0 * (1 - u),
              "tanh": k0 * (1 - u ** 2)}[law]
    covered, errors = 0, []
    for rep in range(40):
        rng = np.random.default_rng(rep)
        k = k_true * (1 + 0.04 * rng.standard_normal(u.size))
        fit = fit_creep_progression(coa, k, math.hypot(0.04, 0.05) * k_true,
                                    coa_now=coa[-1], max_rel_half_width=0.25)
        high = fit.mu_high if math.isfinite(fit.mu_high) else math.inf
        covered += fit.mu_low <= mu <= high
        if fit.determined:
            errors.append(abs(fit.mu / mu - 1))
    assert covered >= 36
    if law == "tanh":
        assert not errors
    else:
        assert len(errors) >= {"exponential": 25, "burckhardt": 18}[law]
        assert np.median(errors) < 0.05


def test_group_points_keeps_staircase_levels_apart():
    """Windows at four torque levels (13 each, CoA scatter 0.3 %) give four points, one per
    level, each the mean of its own windows (an equal-count split would put windows of two
    levels into one point: 52/12 = 5 per group, 13 per level); a continuous spread of CoA
    (a driver's demand) is cut into at most n_bins groups of at least 4 windows."""
    rng = np.random.default_rng(1)
    levels = np.array([0.07, 0.14, 0.21, 0.28])
    coa = np.repeat(levels, 13) * (1 + 0.003 * rng.standard_normal(52))
    k = 110 * (1 - (coa / 0.35) ** 2)
    pts = group_points(coa, k, 0.015 * k, overlap=5.0, n_bins=12)
    assert pts.shape == (4, 3)
    np.testing.assert_allclose(pts[:, 0], levels, rtol=0.003)
    for (_, kb, _), lev in zip(pts, levels, strict=True):
        own = np.abs(coa / lev - 1) < 0.05
        assert kb == pytest.approx(np.average(k[own], weights=1 / (0.015 * k[own]) ** 2))
    spread = np.linspace(0.02, 0.3, 100)
    pts = group_points(spread, 100 - 200 * spread, np.ones(100), n_bins=12)
    assert 4 <= len(pts) <= 12 and np.all(np.diff(pts[:, 0]) > 0)


def test_segment_fit_gives_the_available_adhesion_only_where_determined():
    """A segment's windows on Polach's constant-friction curve (kA/kS = 2.5, mu = 0.2,
    computed by brute force, not from the fit's tables) at the staircase's levels 20-80 %:
    determined, within 5 % (the issue's target for this case), the truth inside the
    interval; the same windows only to 40 % are not determined, their lower bound at or
    below the truth."""
    rng = np.random.default_rng(2)
    curve = _curve(2.5, 1.0, 0.0, 0.2, 70.0)
    peak = 0.2
    for depth, determined in ((0.8, True), (0.4, False)):
        lv = np.repeat(np.linspace(0.2, depth, 4), 12) * peak
        k = np.interp(lv, curve[0], curve[1]) * (1 + 0.01 * rng.standard_normal(lv.size))
        seg = fit_segment(lv, k, 0.015 * k, 0.0, 600.0, overlap=5.0, model_rel_error=0.02,
                          max_rel_half_width=0.25, speed_m_s=22.0)
        row = seg.to_dict(1)
        assert row["determined"] is determined and seg.windows == lv.size
        assert row["adhesion_available_lower_bound"] <= peak
        assert row["adhesion_available_low_95"] <= peak
        if determined:
            assert row["adhesion_available"] == pytest.approx(peak, rel=0.05)
            assert peak <= row["adhesion_available_high_95"]
        else:
            assert math.isnan(row["adhesion_available"])
