"""The compiled pieces of the twin's ground truth (rig/truth.py) against plain numpy."""

from __future__ import annotations

import numpy as np

from torquemod.rig.dynamics import wobble_basis, wobble_table
from torquemod.rig.truth import _fit_basis, _span_moments
from torquemod.simulate import load_config


def test_fit_basis_matches_numpy():
    """Rotated sines (exact every 256 samples) against numpy's sin/cos of every argument:
    rounding only (1e-12 over 5000 samples, i.e. ~20 rotations of ~1e-16 between resyncs)."""
    cfg = load_config()
    wob = wobble_table(cfg.disturbances, cfg.rig.platform_speed_rad_s,
                       np.random.default_rng(1))
    assert (wob[:, 3] > 0.5).any() and (wob[:, 3] < 0.5).any()  # band and revolution rows
    t = 3.0 + np.arange(5000) * 8 / 16670.0
    rng = np.random.default_rng(2)
    theta = 0.97 * t + 1e-4 * np.cumsum(rng.standard_normal(t.size))  # uneven increments
    theta[2500] += 0.3  # a jump larger than the small-angle range: exact there
    w = 2 * np.pi * 2.0024
    x = np.empty((t.size, 3 + 2 * wob.shape[0]))
    _fit_basis(t, w, wob, theta, x)
    ref = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones(t.size),
                           wobble_basis(wob, t, theta)])
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-12)


def test_span_moments_match_numpy():
    rng = np.random.default_rng(3)
    raw = rng.standard_normal((1000, 9)) * [1, 2, 3, 4, 5, 6, 7, 8, 9] + 100.0
    cols = np.array([8, 0, 3, 4, 5, 2])
    mean, std = np.empty(cols.size), np.empty(2)
    _span_moments(raw, 100, 700, cols, mean, np.array([0, 5]), std)
    np.testing.assert_allclose(mean, raw[100:700, cols].mean(axis=0), rtol=1e-14)
    np.testing.assert_allclose(std, raw[100:700, cols[[0, 5]]].std(axis=0), rtol=1e-12)
