"""The available-adhesion grid's fast path (torquemod.analysis.frictiongrid) against brute
force: the coarse-to-fine pass against the kernel on every trial P and every pair of the
family, and the compiled kernel's cells (with a creepage swing, the CoA error and the bound
on falling friction) against a plain-Python evaluation of one cell written from the model
(torquemod.analysis.friction's module docstring), and the summary of the grid (each rule
on the rows it needs) against the rules applied to whole masked grids, on small inputs."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.analysis import frictiongrid as fg
from torquemod.analysis.creeplaws import SWING_A, family_tables, neighbour_pairs
from torquemod.analysis.friction import CHI2_95_2, _p_grid, _summarise, _vertex
from torquemod.analysis.frictiongrid import (
    CHI2_95,
    _chi_all,
    _chi_kernel,
    _coarse_to_fine,
    new_pairs,
    reference_chi2,
)


def _inputs(seed: int, n: int = 6):
    """Points on a saturating progression (k/k0 falling towards the peak) with noise."""
    rng = np.random.default_rng(seed)
    coa = np.sort(rng.uniform(0.03, 0.27, n))
    y = 40.0 * np.sqrt(np.clip(1.0 - coa / 0.3, 0.02, None)) * (1 + 0.03 * rng.normal(size=n))
    se = 0.03 * y
    c_se = 0.01 * coa
    amp = rng.uniform(2e-4, 2e-3, n)
    return coa, y, se, c_se, amp


def _same(a, b) -> bool:
    return bool(np.all((a == b) | (np.isnan(a) & np.isnan(b))))


@pytest.mark.parametrize("seed", [1, 2])
def test_coarse_to_fine_equals_the_full_grid(seed):
    """Every cell the coarse-to-fine pass evaluates equals the kernel's on the whole grid
    bit for bit, and the profile's minimum and the ends of its 95 % set are the same as on
    the whole grid (every pair, every trial P)."""
    tabs = family_tables(True)
    pairs = neighbour_pairs()
    coa, y, se, c_se, amp = _inputs(seed)
    p_grid = _p_grid(float(coa.max()), 20.0)
    full = _chi_all(tabs, pairs, coa, y, se, c_se, amp, p_grid, 2.0, 0.01, 2.0)
    cols, outs = _coarse_to_fine(tabs, pairs, coa, y, se, c_se, amp, p_grid, 2.0, 0.01, 2.0)
    assert cols.size < p_grid.size
    for o, f in zip(outs, full, strict=True):
        assert _same(o, f[:, cols])
    prof_full = full[0].min(axis=0)
    prof = outs[0].min(axis=0)
    assert np.isfinite(prof_full).any()
    assert prof.min() == prof_full.min()
    assert cols[int(np.argmin(prof))] == int(np.argmin(prof_full))
    dof = coa.size - 3
    level = prof_full.min() + CHI2_95 * max(1.0, prof_full.min() / dof)
    inside_full = np.flatnonzero(prof_full <= level)
    inside = cols[prof <= level]
    assert (inside[0], inside[-1]) == (inside_full[0], inside_full[-1])


def _cell(tabs, a, b, p, coa, y, se, c_se, amp, k_scale, n_iter, bmax_v):
    """One cell by the model: ``y ~ alpha*g_a + beta*g_b`` (alpha, beta >= 0), g the
    tabulated s(CoA/P) plus the swing's change at the reduced swing ``amp*k0*F_pk/P``
    (bilinear in the tables), weights ``1/(se^2 + (0.01*y)^2 + (k'/P*se_CoA)^2)``,
    refitted ``n_iter`` times with k0 from the previous fit."""
    ug = np.linspace(0.0, 1.0, tabs.s.shape[1])
    us = np.linspace(0.0, 1.0, tabs.swing.shape[1])
    u = coa / p
    if np.any(u >= 1.0):
        return np.inf, np.nan
    g0 = [np.interp(u, ug, tabs.s[m]) for m in (a, b)]
    dg = [np.interp(u, ug, tabs.ds[m]) for m in (a, b)]
    if not all(np.all(g > 0) for g in g0):
        return np.inf, np.nan
    al = be = 0.0
    for it in range(n_iter):
        k0 = k_scale * (al + be)
        g = []
        for m, base in zip((a, b), g0, strict=True):
            if it == 0:
                g.append(base)
                continue
            red = np.minimum(amp * k0 * tabs.f_peak[m] / p, SWING_A[-1])
            change = [
                # bilinear: the swing rows at the point's utilisation, then in the swing
                np.interp(red[i], SWING_A, [np.interp(u[i], us, tabs.swing[m, :, j])
                                            for j in range(SWING_A.size)])
                for i in range(u.size)]
            g.append(base + np.array(change))
        slope = (al * dg[0] + be * dg[1]) / p * c_se if it else 0.0 * u
        w = 1.0 / (se**2 + (0.01 * y) ** 2 + slope**2)
        design = np.c_[g[0], g[1]] * np.sqrt(w)[:, None]
        sol = [np.linalg.lstsq(design, y * np.sqrt(w), rcond=None)[0]] if a != b else []
        sol = [s for s in sol if np.all(s >= 0)]
        sol += [np.array([np.sum(w * g[0] * y) / np.sum(w * g[0] ** 2), 0.0]),
                np.array([0.0, np.sum(w * g[1] * y) / np.sum(w * g[1] ** 2)])]
        chi = [np.sum(w * (y - s[0] * g[0] - s[1] * g[1]) ** 2) for s in sol]
        al, be = sol[int(np.argmin(chi))]
    k0 = k_scale * (al + be)
    if bmax_v > 0 and max(tabs.beta_h[m] * k0 * tabs.f_peak[m] for m in (a, b)) > bmax_v * p:
        return np.inf, np.nan
    return min(chi), al + be


def test_kernel_cells_equal_the_model_evaluated_cell_by_cell():
    """chi2 and amplitude of the compiled kernel on a few pairs of every kind (constant and
    falling friction, mixed laws) with a swing, the CoA error and the B bound: within 1e-7
    of the plain evaluation (the tables interpolated by numpy and the fit by least squares
    instead of the closed form: rounding only), and the same cells left out."""
    tabs = family_tables(True)
    pairs = neighbour_pairs()
    pick = pairs[np.linspace(0, len(pairs) - 1, 9).astype(int)]
    coa, y, se, c_se, amp = _inputs(3)
    p_grid = coa.max() * np.array([1.02, 1.2, 1.8])
    k_scale, bmax_v = 2.0, 2.0
    chi, amps, _ = _chi_kernel(tabs.s_t, tabs.ds_t, tabs.swing_t, SWING_A, tabs.f_peak, pick,
                               coa, y, se * se, 0.01, c_se, amp, p_grid, k_scale, 0.0, 3,
                               tabs.beta_h, bmax_v)
    n_finite = 0
    for q, (a, b) in enumerate(pick):
        for m, p in enumerate(p_grid):
            c, amp_ref = _cell(tabs, a, b, p, coa, y, se, c_se, amp, k_scale, 3, bmax_v)
            assert np.isfinite(chi[q, m]) == np.isfinite(c)
            if np.isfinite(c):
                n_finite += 1
                assert chi[q, m] == pytest.approx(c, rel=1e-7)
                assert amps[q, m] == pytest.approx(amp_ref, rel=1e-7)
    assert n_finite >= 10


def _summary_on_whole_grids(tabs, pairs, rail, chi, fracs, p_grid, dof, scale_by_chi2):
    """The summary's rules written on whole (K, m) grids: masked copies, column minima."""
    prof = chi.min(axis=0)
    chi_set = np.where(rail[:, None], chi, np.inf)
    chi_min, rail_only = reference_chi2(float(np.nanmin(prof)), float(np.nanmin(chi_set)))
    if not rail_only:
        chi_set = chi
    prof_set = chi_set.min(axis=0)
    j = int(np.nanargmin(prof_set))
    i = int(np.argmin(chi_set[:, j]))
    scale = max(1.0, chi_min / dof) if scale_by_chi2 else 1.0
    est_prof = prof_set
    falling = tabs.falling[pairs[:, 0]] | tabs.falling[pairs[:, 1]]
    chi_c = np.where(falling[:, None], np.inf, chi_set)
    prof_c = chi_c.min(axis=0)
    if np.isfinite(prof_c).any() and float(prof_c.min()) <= chi_min + CHI2_95_2 * scale:
        j = int(np.argmin(prof_c))
        i = int(np.argmin(chi_c[:, j]))
        est_prof = prof_c
    step = float(p_grid[min(j + 1, p_grid.size - 1)] / p_grid[j])
    est = float(p_grid[j]) * step ** _vertex(est_prof, j)
    level = chi_min + CHI2_95 * scale
    inside = chi <= level
    idx = np.flatnonzero(inside.any(axis=0))
    mix = np.nan_to_num(fracs)
    inv_pk = 1.0 / tabs.f_peak
    m0 = p_grid[None, :] * ((1.0 - mix) * inv_pk[pairs[:, 0]][:, None]
                            + mix * inv_pk[pairs[:, 1]][:, None])
    return {"profile": prof, "chi2": chi_min, "level": level, "pair": i, "column": j,
            "ends": (int(idx[0]), int(idx[-1])), "mu0_low": float(m0[inside].min()),
            "mu0_high": float(m0[inside].max()), "mix": float(mix[i, j]), "estimate": est}


@pytest.mark.parametrize(("margin", "scale_by_chi2"), [(-np.inf, True), (np.inf, True),
                                                      (np.inf, False)])
def test_summary_equals_the_rules_on_whole_grids(monkeypatch, margin, scale_by_chi2):
    """The fit's profile, chi2, level, interval ends, estimate, best pair (through its k0
    and parameters) and mu0 range equal the rules applied to whole masked grids, bit for
    bit, with the level set by the whole family (margin -inf) and by the rail members
    (+inf), the interval widened by the scatter or not."""
    monkeypatch.setattr(fg, "NEW_MEMBER_MARGIN", margin)
    tabs = family_tables(True)
    pairs = neighbour_pairs()
    rail = ~new_pairs(tabs, pairs)
    # flat, then falling beyond a knee: the knee members fit far better than the rail ones
    # (chi2 37 against 102, at other trial P), so the two margins give different levels,
    # estimates and best pairs
    rng = np.random.default_rng(4)
    coa = np.sort(rng.uniform(0.03, 0.27, 7))
    u = coa / 0.3
    y = 40.0 * np.where(u < 0.7, 1.0, np.clip(1.0 - ((u - 0.7) / 0.3) ** 2, 0.02, None))
    y = y * (1.0 + 0.003 * rng.normal(size=coa.size))
    se, c_se, amp = 0.003 * y, 0.01 * coa, rng.uniform(2e-4, 2e-3, coa.size)
    p_grid = _p_grid(float(coa.max()), 20.0)
    cols, (chi, amps, fracs) = _coarse_to_fine(tabs, pairs, coa, y, se, c_se, amp, p_grid,
                                               2.0, 0.01, 2.0, rail=rail)
    pg = p_grid[cols]
    fit = _summarise(tabs, pairs, rail, chi, amps, fracs, pg, coa, y, se, float(coa.max()),
                     0.01, 0.1, scale_by_chi2, False, c_se, amp, 2.0, 20.0, (0.3, 7.0), True,
                     None)
    ref = _summary_on_whole_grids(tabs, pairs, rail, np.array(chi), np.array(fracs), pg,
                                  coa.size - 3, scale_by_chi2)
    assert ref["chi2"] == (chi.min() if margin < 0 else chi[rail].min())
    assert _same(fit.profile, ref["profile"])
    assert (fit.chi2, fit.level, fit.estimate) == (ref["chi2"], ref["level"], ref["estimate"])
    lo, hi = ref["ends"]
    assert fit.low == (float(coa.max()) if lo == 0 else pg[lo - 1])
    assert _same(np.float64(fit.high), np.float64(np.nan if hi == pg.size - 1 else pg[hi + 1]))
    assert fit.k0 == amps[ref["pair"], ref["column"]]
    a, b = pairs[ref["pair"]]
    f = ref["mix"]
    assert fit.params == tuple((1.0 - f) * va + f * vb for va, vb in
                               zip(tabs.members[a].params, tabs.members[b].params, strict=True))
    assert (fit.mu0_low, fit.mu0_high) == (ref["mu0_low"], ref["mu0_high"])
