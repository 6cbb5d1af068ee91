"""The compiled pieces of the twin's ground truth (rig/truth.py) against plain numpy."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from torquemod.twins.vtrack.rig.dynamics import wobble_basis, wobble_table
from torquemod.twins.vtrack.rig.truth import _fit_basis, _span_moments
from torquemod.twins.vtrack.simulate import load_config


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


def _fit_inputs(seed: int, n_rows: int, fs: float, t0: float, *, spread: float,
                offset: float):
    """(wobble table, raw rows, the generator that made them) for the fit-sum tests: nine
    noisy columns spread apart by ``spread``, the platform angle a line from ``t0`` [s]."""
    from torquemod.twins.vtrack.rig.truth import _FIT_COLS

    cfg = load_config()
    wob = wobble_table(cfg.disturbances, cfg.rig.platform_speed_rad_s,
                       np.random.default_rng(4))
    rng = np.random.default_rng(seed)
    raw = rng.standard_normal((n_rows, 9)) + np.arange(9) * spread
    raw[:, _FIT_COLS[0]] = 0.97 * (t0 + np.arange(n_rows) / fs) + offset
    return wob, raw, rng


def test_fit_sums_match_the_basis_matrix():
    """The truth fit's normal equations over overlapping windows (the whole and its
    revolutions, each sample summed once per piece between window edges) and the speed
    reference, against numpy's products of the basis matrix of :func:`_fit_basis` over each
    window: summation order only (1e-12 of the largest entry of each matrix; the sums run
    over ~400 samples of values up to ~60)."""
    from torquemod.twins.vtrack.rig.truth import _FIT_COLS, _fit_sums

    n_rows, stride, fs, t0 = 3301, 8, 16670.0, 12.5
    wob, raw, rng = _fit_inputs(6, n_rows, fs, t0, spread=7.0, offset=0.2)
    lo, hi = np.array([0, 0, 150, 290]), np.array([410, 140, 280, 413])
    m = 3 + 2 * wob.shape[0]
    gram, rhs = np.empty((4, m, m)), np.empty((4, m, 2))
    coef = rng.standard_normal(m - 3)
    ref = np.empty(413)
    w = 2 * np.pi * 2.0024
    _fit_sums(raw, t0, fs, stride, w, wob, coef, _FIT_COLS, lo, hi, gram, rhs, ref)
    idx = np.arange(0, n_rows, stride)
    x = np.empty((idx.size, m))
    _fit_basis(t0 + idx / fs, w, wob, raw[idx, _FIT_COLS[0]], x)
    y = raw[idx][:, _FIT_COLS[1:]]
    for j in range(4):
        xs = x[lo[j]:hi[j]]
        g, r = xs.T @ xs, xs.T @ y[lo[j]:hi[j]]
        np.testing.assert_allclose(gram[j], g, rtol=0, atol=1e-12 * np.abs(g).max())
        np.testing.assert_allclose(rhs[j], r, rtol=0, atol=1e-12 * np.abs(r).max())
    np.testing.assert_allclose(ref, x[:, 3:] @ coef, rtol=0, atol=1e-14 * np.abs(coef).sum())


def _moments_reference(raw, edges, cols, std_cols):
    """Plain-Python two-pass moments, adding in the kernel's order (row by row per part;
    the whole's mean from the parts' sums; its squared deviations over the parts in turn)."""
    m, nc = len(edges) - 1, len(cols)
    sums = [[0.0] * nc for _ in range(m)]
    for j in range(m):
        for k in range(edges[j], edges[j + 1]):
            for c in range(nc):
                sums[j][c] += float(raw[k, cols[c]])
    whole = [0.0] * nc
    for j in range(m):
        for c in range(nc):
            whole[c] += sums[j][c]
    means = [[s / (edges[j + 1] - edges[j]) for s in sums[j]] for j in range(m)]
    whole = [w / (edges[m] - edges[0]) for w in whole]
    part_sq = [[0.0] * len(std_cols) for _ in range(m)]
    whole_sq = [0.0] * len(std_cols)
    for j in range(m):
        for k in range(edges[j], edges[j + 1]):
            for c, sc in enumerate(std_cols):
                x = float(raw[k, cols[sc]])
                d, e = x - means[j][sc], x - whole[sc]
                part_sq[j][c] += d * d
                whole_sq[c] += e * e
    mean = np.array([whole, *means])
    std = np.sqrt(np.array([[w / (edges[m] - edges[0]) for w in whole_sq],
                            *([q / (edges[j + 1] - edges[j]) for q in part_sq[j]]
                              for j in range(m))]))
    return mean, std


@pytest.mark.parametrize(("cols", "std_cols"), [([8, 0, 3, 4, 5, 2], [0, 5]),
                                                ([1, 7, 6, 2], [3])])
def test_partition_moments_add_in_order(cols, std_cols):
    """The truth's 6-mean/2-deviation layout (sums in local variables) and any other layout
    (sums in the arrays) give exactly the plain-Python sums in the same order (bit for bit:
    the register sums change the speed, not the arithmetic)."""
    from torquemod.twins.vtrack.rig.truth import _partition_moments

    rng = np.random.default_rng(9)
    raw = rng.standard_normal((2000, 9)) * np.arange(1, 10) + 30.0
    edges = np.array([17, 640, 1300, 1999])
    cols, std_cols = np.array(cols), np.array(std_cols)
    mean, std = np.empty((4, cols.size)), np.empty((4, std_cols.size))
    _partition_moments(raw, edges, cols, mean, std_cols, std)
    ref_mean, ref_std = _moments_reference(raw, edges.tolist(), cols.tolist(),
                                           std_cols.tolist())
    np.testing.assert_array_equal(mean, ref_mean)
    np.testing.assert_array_equal(std, ref_std)


def test_fit_sums_add_row_by_row():
    """The fit's sums taken eight rows per load of each sum (_add_rows8) are exactly those of
    one row at a time in row order, piece by piece between window edges (plain Python over
    the kernel's own basis; pieces of 3, 4, 5 and 130 rows cover the remainder loop)."""
    from torquemod.twins.vtrack.rig.truth import _FIT_COLS, _fit_sums

    n_rows, stride, fs, t0 = 1130, 8, 16670.0, 3.25
    wob, raw, _ = _fit_inputs(8, n_rows, fs, t0, spread=5.0, offset=0.4)
    lo, hi = np.array([0, 3, 7, 12]), np.array([142, 7, 12, 142])
    m = 3 + 2 * wob.shape[0]
    gram, rhs, ref = np.empty((4, m, m)), np.empty((4, m, 2)), np.empty(142)
    w = 2 * np.pi * 2.0024
    _fit_sums(raw, t0, fs, stride, w, wob, np.zeros(m - 3), _FIT_COLS, lo, hi, gram, rhs, ref)
    idx = np.arange(0, n_rows, stride)
    x = np.empty((idx.size, m))
    _fit_basis(t0 + idx / fs, w, wob, raw[idx, _FIT_COLS[0]], x)
    edges = [0, 3, 7, 12, 142]
    pieces = []
    for a, b in itertools.pairwise(edges):
        g, r = [[0.0] * m for _ in range(m)], [[0.0, 0.0] for _ in range(m)]
        for i in range(a, b):
            u, v = float(raw[idx[i], _FIT_COLS[1]]), float(raw[idx[i], _FIT_COLS[2]])
            for p in range(m):
                bp = float(x[i, p])
                r[p][0] += bp * u
                r[p][1] += bp * v
                for q in range(p, m):
                    g[p][q] += bp * float(x[i, q])
        pieces.append((np.array(g), np.array(r)))
    for j in range(4):
        g_ref, r_ref = np.zeros((m, m)), np.zeros((m, 2))
        for (a, b), (g, r) in zip(itertools.pairwise(edges), pieces, strict=True):
            if lo[j] <= a and b <= hi[j]:
                g_ref += g
                r_ref += r
        np.testing.assert_array_equal(np.triu(gram[j]), np.triu(g_ref))
        np.testing.assert_array_equal(gram[j], gram[j].T)
        np.testing.assert_array_equal(rhs[j], r_ref)


@pytest.mark.parametrize(("n_rows", "edges"), [(9001, [0, 2999, 6010, 9001]),
                                               (4103, [5, 2048, 2049, 4100])])
def test_step_sums_are_the_fit_sums_and_moments(n_rows, edges):
    """The one-sweep kernel (blocks of 256 fit rows; the moments' parts, the fit's pieces
    and the blocks' edges falling anywhere, the basis's resync inside the sweep) gives
    exactly the fit's sums, speed reference and moments of the separate kernels."""
    from torquemod.twins.vtrack.rig.truth import (
        _FIT_COLS,
        _MEAN_COLS,
        _STD_COLS,
        _fit_sums,
        _partition_moments,
        step_sums,
    )

    stride, fs, t0 = 8, 16670.0, 7.75
    wob, raw, rng = _fit_inputs(11, n_rows, fs, t0, spread=3.0, offset=0.1)
    n_fit = (n_rows + stride - 1) // stride
    third = n_fit // 3
    lo = np.array([0, 0, third + 3, 2 * third + 5])
    hi = np.array([n_fit - 3, third - 7, 2 * third - 1, n_fit - 1])
    m = 3 + 2 * wob.shape[0]
    coef = rng.standard_normal(m - 3)
    w = 2 * np.pi * 3.0011
    edges = np.array(edges)
    out = {}
    for name in ("apart", "fused"):
        gram, rhs, ref = np.empty((4, m, m)), np.empty((4, m, 2)), np.empty(n_fit)
        mean, std = np.empty((4, _MEAN_COLS.size)), np.empty((4, _STD_COLS.size))
        args = (raw, t0, fs, stride, w, wob, coef, _FIT_COLS, lo, hi, gram, rhs, ref)
        if name == "apart":
            _fit_sums(*args)
            _partition_moments(raw, edges, _MEAN_COLS, mean, _STD_COLS, std)
        else:
            step_sums(*args, edges, _MEAN_COLS, _STD_COLS, mean, std)
        out[name] = (gram, rhs, ref, mean, std)
    for a, b in zip(out["apart"], out["fused"], strict=True):
        np.testing.assert_array_equal(a, b)
