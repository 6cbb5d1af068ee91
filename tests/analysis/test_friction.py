"""The one estimator of the available adhesion (torquemod.analysis.friction): its compiled kernel
against the array formula and an NNLS solver, its swing tables against the library's own
describing function, recovery and honesty on curves made by code apart from it
(benchmarks/_independent_laws.py), and the named outputs."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq, nnls

from torquemod.analysis import frictiongrid as fg
from torquemod.analysis.contact.polach import (
    adhesion_curve,
    adhesion_slope,
    swing_average,
    swing_slope,
)
from torquemod.analysis.creeplaws import KAPPA_GRID, SWING_A, family, family_tables
from torquemod.analysis.friction import (
    CHI2_95,
    MODEL_REL_ERROR,
    PROBE_DEPTHS,
    fit_available_adhesion,
    fit_available_adhesion_from_phase,
)
from torquemod.analysis.frictiongrid import _chi_kernel

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import _independent_laws as laws


def test_kernel_equals_nonnegative_least_squares():
    """For single members and for pairs, chi2 and the amplitude of the compiled kernel equal
    scipy's NNLS on the weighted design (s by linear interpolation of the table): 1e-9."""
    tabs = family_tables()
    rng = np.random.default_rng(3)
    ug = np.linspace(0.0, 1.0, tabs.s.shape[1])
    pairs = np.array([[0, 0], [5, 6], [40, 41], [300, 301], [340, 349]], dtype=np.int64)
    for _ in range(4):
        coa = np.sort(rng.uniform(0.02, 0.2, 7))
        y = rng.uniform(5.0, 80.0, 7)
        se = rng.uniform(0.5, 3.0, 7)
        p_grid = coa.max() * np.array([1.05, 1.3, 2.0])
        chi, amp, _frac = _chi_kernel(tabs.s_t, tabs.ds_t, np.zeros((1, 0, 1)), SWING_A,
                                     tabs.f_peak, pairs, coa, y, se * se, 0.01, np.zeros(7),
                                     np.zeros(7), p_grid, 1.0, 0.0, 1, tabs.beta_h, 0.0)
        w = 1.0 / np.sqrt(se**2 + (0.01 * y) ** 2)
        for q, (a, b) in enumerate(pairs):
            for m, p in enumerate(p_grid):
                ga, gb = (np.interp(coa / p, ug, tabs.s[i]) for i in (a, b))
                if not (np.all(ga > 0) and np.all(gb > 0)):
                    assert not np.isfinite(chi[q, m])
                    continue
                x, rnorm = nnls(np.c_[ga * w, gb * w], y * w)
                assert chi[q, m] == pytest.approx(rnorm**2, rel=1e-9)
                assert amp[q, m] == pytest.approx(x.sum(), rel=1e-9)


def test_swing_table_matches_the_library_describing_function():
    """The tabulated describing-function slope of the constant-friction Polach member (kA/kS
    = 2.5) at a mean CoA: against brentq on the library's 32-node swing average and
    swing slope (torquemod.analysis.contact.polach), within 2e-3 of k0 (bilinear interpolation on
    the
    table's grid) for swings up to 0.7 in reduced units."""
    tabs = family_tables(swing=True)
    members = family()
    i = min(range(len(members)), key=lambda j: abs(members[j].params[0] - 2.5)
            if members[j].law == "polach" else 1e9)
    r = members[i].params[0]
    mu, k0 = 0.3, 100.0
    stiff = np.pi * k0 / (2 * (r + 1.0))

    def curve(xi):
        return adhesion_curve(xi, mu=mu, k_a=r, k_s=1.0, stiffness=stiff)

    ug = np.linspace(0.0, 1.0, tabs.s.shape[1])
    us = np.linspace(0.0, 1.0, tabs.swing.shape[1])
    for u in (0.3, 0.6, 0.8):
        for red in (0.1, 0.35, 0.7):
            a = red * mu / k0  # reduced swing a*k0/mu0 (F_pk = 1 for r >= 1)
            xm = brentq(lambda x, a=a, u=u: float(swing_average(curve, x, a)) - u * mu,
                        -a, 1.0, xtol=1e-15)
            ref = float(swing_slope(curve, xm, a)) / k0
            j = np.searchsorted(SWING_A, red) - 1
            fa = (red - SWING_A[j]) / (SWING_A[j + 1] - SWING_A[j])
            d = ((1 - fa) * np.interp(u, us, tabs.swing[i, :, j])
                 + fa * np.interp(u, us, tabs.swing[i, :, j + 1]))
            assert np.interp(u, ug, tabs.s[i]) + d == pytest.approx(ref, abs=2e-3)


def test_knee_member_follows_dugoffs_law():
    """The knee members' tables against the closed form of their creep coefficient,
    ``s(u) = 1`` up to kappa and ``((1 - u)/(1 - kappa))^2`` beyond (Dugoff, Fancher and
    Segel 1970 at kappa = 1/2): within 2e-3 (the table's slope by central differences on
    the member's curve, interpolated onto the u grid) away from the knee itself, and
    F_pk = 1 (the supremum)."""
    tabs = family_tables()
    ug = np.linspace(0.0, 1.0, tabs.s.shape[1])
    rows = [i for i, m in enumerate(tabs.members) if m.law == "knee"]
    assert [tabs.members[i].params[0] for i in rows] == list(KAPPA_GRID)
    for i in rows:
        kappa = tabs.members[i].params[0]
        exact = np.where(ug <= kappa, 1.0, ((1.0 - ug) / (1.0 - kappa)) ** 2)
        away = (np.abs(ug - kappa) > 0.01) & (ug < 0.99)
        assert np.max(np.abs(tabs.s[i][away] - exact[away])) < 2e-3
        assert tabs.f_peak[i] == pytest.approx(1.0, abs=1e-3)


def _polach_points(mu, k_a, k_s, k0, fractions):
    stiff = np.pi * k0 / (2 * (k_a + k_s))
    coa = np.asarray(fractions) * mu
    xi = np.array([brentq(lambda x, c=c: float(adhesion_curve(
        x, mu=mu, k_a=k_a, k_s=k_s, stiffness=stiff)) - c, 0, 1, xtol=1e-15) for c in coa])
    return coa, adhesion_slope(xi, mu=mu, k_a=k_a, k_s=k_s, stiffness=stiff)


def test_polach_points_to_86_percent_determine_the_adhesion():
    """Exact creep coefficients of Polach's dry set (kA/kS = 2.5, library curve) to 86 % of
    the available adhesion, stated with 2 % errors: determined, the truth inside, the
    estimate within 1 % (the interval's half width is ~3 %); the named keys are strict
    JSON."""
    coa, k = _polach_points(0.3, 1.0, 0.4, 80.0, np.repeat([0.2, 0.42, 0.64, 0.86], 2))
    fit = fit_available_adhesion(coa, k, 0.02 * k)
    assert fit.determined and fit.low <= 0.3 <= fit.high
    assert fit.estimate == pytest.approx(0.3, rel=0.01)
    d = fit.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["adhesion_available"] == fit.estimate and d["adhesion_available_determined"]
    assert d["estimand"].startswith("available adhesion")


def test_low_utilisation_gives_a_lower_bound_and_the_probe_depth():
    """Points to 50 % only: not determined, the lower bound is at least the largest CoA and
    at most the truth, and a probe depth beyond the present one is named (one of
    PROBE_DEPTHS) or NaN when none would do."""
    coa, k = _polach_points(0.3, 1.0, 0.4, 80.0, np.repeat([0.1, 0.23, 0.37, 0.5], 2))
    fit = fit_available_adhesion(coa, k, 0.02 * k)
    assert not fit.determined and fit.value is None
    assert coa.max() <= fit.lower_bound <= 0.3
    assert math.isnan(fit.probe_depth) or (fit.probe_depth in PROBE_DEPTHS
                                           and fit.probe_depth > 0.5)


def test_scatter_beyond_the_errors_widens_the_interval():
    """Errors understated three times: the reduced chi2 exceeds 1 and the level is
    widened by it (Wilks with the scatter), never narrowed."""
    coa, k = _polach_points(0.3, 1.0, 0.4, 80.0, np.repeat([0.2, 0.42, 0.64, 0.86], 3))
    noisy = k * (1 + 0.06 * np.random.default_rng(4).standard_normal(k.size))
    fit = fit_available_adhesion(coa, noisy, 0.02 * k)
    assert fit.chi2_scale > 1.0
    assert fit.level == pytest.approx(fit.chi2 + CHI2_95 * fit.chi2_scale)


@pytest.mark.parametrize("mode", ["rig", "train"])
def test_coverage_on_laws_made_apart(mode):
    """The small version of benchmarks/friction_coverage.py: 9 laws (Polach constant and
    falling friction, Burckhardt, exponential, tanh, Shen-Hedrick-Elkins, Dugoff, a
    hyperbolic saturation; the magic formula outside the estimator's family) x 3 records at
    86 % depth, noise at the chain's level, written by code that shares nothing with the
    estimator. The stated range holds the truth in all but at most 2 of the 27 (>= 92.6 %:
    the 90 % target per cell; the full table is the benchmark's). The default family, as the
    benchmark's tables."""
    rng = np.random.default_rng(11 if mode == "rig" else 12)
    hit = n = 0
    for law in laws.LAWS:
        for depth in (0.86,):
            for _ in range(3):
                r = laws.record(law, rng, depth, mode=mode, noise=1.0)
                if r is None:
                    continue
                if mode == "rig":
                    f = fit_available_adhesion_from_phase(
                        r["coa"], r["y"], r["se"], constant=r["constant"],
                        creepage_swing=r["swing"], probe=False, speed_m_s=r["speed_m_s"])
                else:
                    f = fit_available_adhesion(r["coa"], r["y"], r["se"], probe=False,
                                               speed_m_s=r["speed_m_s"])
                hi = f.high if f.closed else math.inf
                n += 1
                hit += f.lower_bound <= r["P"] * (1 + 1e-9) <= hi * (1 + 2e-9)
    assert n >= 22 and hit >= n - 2
    assert MODEL_REL_ERROR > 0


def test_measured_constant_relaxes_the_falling_friction_bound():
    """With C measured, the bound B <= B_max on falling friction is applied at C's lower
    95 % end: a relative standard error of 0.3 (1 - 1.96*0.3 < 0.5) lifts it, giving the fit
    without a speed; none gives the bounded fit, whose interval is the narrower (the
    falling members that peak low are left out at this speed)."""
    coa, k = _polach_points(0.3, 1.0, 0.4, 80.0, np.repeat([0.2, 0.42, 0.64, 0.86], 2))
    kw = {"probe": False}
    free = fit_available_adhesion(coa, k, 0.02 * k, **kw)
    bound = fit_available_adhesion(coa, k, 0.02 * k, speed_m_s=2.0, **kw)
    lifted = fit_available_adhesion(coa, k, 0.02 * k, speed_m_s=2.0, constant_rel_se=0.3,
                                    **kw)
    exact = fit_available_adhesion(coa, k, 0.02 * k, speed_m_s=2.0, constant_rel_se=0.0,
                                   **kw)
    assert (lifted.estimate, lifted.low, lifted.high) == (free.estimate, free.low, free.high)
    assert (exact.estimate, exact.low, exact.high) == (bound.estimate, bound.low, bound.high)
    assert bound.low > free.low


@pytest.mark.parametrize("law", ["hyperbolic", "dugoff"])
@pytest.mark.parametrize("mode", ["train", "rig"])
def test_default_family_holds_hyperbolic_and_dugoff(law, mode):
    """Noise-free records of two laws drawn by the independent generator (not from the
    family's tables): the hyperbolic saturation ``mu*z/(1 + z)``, whose slope falls as
    ``(1 - u)^2`` from the start, and Dugoff's brush law (linear to half the friction, then
    ``mu*(1 - mu/(4*z))``), probed to 80 and 90 %. With the default family the stated range
    holds the truth (before the p = 1 tail and the knee were in it, both gave narrow
    intervals 6-13 % off the truth at these depths: docs/friction.md)."""
    rng = np.random.default_rng(23)
    for depth in (0.8, 0.9):
        r = laws.record(law, rng, depth, mode=mode, noise=0.0)
        if mode == "rig":
            f = fit_available_adhesion_from_phase(
                r["coa"], r["y"], r["se"], constant=r["constant"], creepage_swing=r["swing"],
                probe=False, speed_m_s=r["speed_m_s"])
        else:
            f = fit_available_adhesion(r["coa"], r["y"], r["se"], probe=False,
                                       speed_m_s=r["speed_m_s"])
        hi = f.high if f.closed else math.inf
        assert f.lower_bound <= r["P"] * (1 + 1e-9) <= hi * (1 + 1e-9), (law, mode, depth, f)


def _train_fit(r):
    return fit_available_adhesion(r["coa"], r["y"], r["se"], probe=False,
                                  speed_m_s=r["speed_m_s"])


def test_new_members_widen_only_unless_they_win_clearly(monkeypatch):
    """The widen-only rule (frictiongrid.reference_chi2). A hyperbolic record (train, 86 %,
    chain's noise) whose best fit is a p = 1 tail member better than the rail members' by
    less than NEW_MEMBER_MARGIN: the level is the rail members' (higher), the interval holds
    the one without the rule, the estimate is a rail member's. A Dugoff record, where the
    knee wins by more than the margin: the knee gives the estimate, as without the rule."""
    margin = fg.NEW_MEMBER_MARGIN
    assert fg.reference_chi2(5.0, 9.0) == (9.0, True)
    assert fg.reference_chi2(5.0, 16.0) == (5.0, False)
    assert fg.reference_chi2(5.0, math.inf) == (5.0, False)
    hyp = laws.record("hyperbolic", np.random.default_rng(3), 0.86, mode="train", noise=1.0)
    dug = laws.record("dugoff", np.random.default_rng(0), 0.86, mode="train", noise=1.0)
    rule_h, rule_d = _train_fit(hyp), _train_fit(dug)
    monkeypatch.setattr(fg, "NEW_MEMBER_MARGIN", -math.inf)  # the whole family, always
    all_h, all_d = _train_fit(hyp), _train_fit(dug)
    monkeypatch.setattr(fg, "NEW_MEMBER_MARGIN", math.inf)  # the rail members, always
    rail_d = _train_fit(dug)
    assert 0.0 < rule_h.chi2 - all_h.chi2 < margin
    assert rule_h.level > all_h.level
    assert rule_h.low <= all_h.low and rule_h.high >= all_h.high
    assert rule_h.law == "saturation" and rule_h.params[0] != 1.0
    assert all_d.chi2 < rail_d.chi2 - margin
    assert rule_d.law == "knee"
    assert (rule_d.estimate, rule_d.low, rule_d.high) == (all_d.estimate, all_d.low,
                                                         all_d.high)
