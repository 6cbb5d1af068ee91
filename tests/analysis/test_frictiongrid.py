"""The available-adhesion grid's fast path (torquemod.analysis.frictiongrid) against brute
force: the coarse-to-fine pass against the kernel on every trial P and every pair of the
family, and the compiled kernel's cells (with a creepage swing, the CoA error and the bound
on falling friction) against a plain-Python evaluation of one cell written from the model
(torquemod.analysis.friction's module docstring), on small inputs."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.analysis.creeplaws import SWING_A, family_tables, neighbour_pairs
from torquemod.analysis.friction import _p_grid
from torquemod.analysis.frictiongrid import CHI2_95, _chi_all, _chi_kernel, _coarse_to_fine


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
