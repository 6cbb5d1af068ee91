"""The compiled kernels of the chain's per-cycle steps (issue 11, fourth round) against the
scipy/numpy computations they replace. Bit for bit where the kernel repeats the reference's
arithmetic; otherwise the tolerance is stated with where it comes from."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import optimize, signal

from torquemod._util.blas import one_blas_thread
from torquemod.dsp import filters, phase, resampling, spectrum, tonemodel
from torquemod.processing import speedmodel

FS = 53.344


def _record(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    f = rng.uniform(1.6, 2.4)
    return (rng.uniform(0.01, 10) * np.sin(2 * np.pi * f * t + rng.uniform(0, 6))
            + 0.3 * np.sin(2 * np.pi * rng.uniform(3, 20) * t) + rng.standard_normal(n))


@pytest.mark.parametrize("seed", range(20))
def test_dtft_peak_is_fminbound_bit_for_bit(seed):
    x = _record(300 + 7 * seed, seed)
    wx = signal.get_window("hann", x.size, fftbins=False) * x
    rng = np.random.default_rng(seed)
    lo = rng.uniform(1.7, 2.1)
    hi = lo + rng.uniform(0.005, 0.2)
    xtol = 10 ** rng.uniform(-9, -4)

    def neg_mag(f: float) -> float:
        return -spectrum._dtft_magnitude(wx, 2 * math.pi * f / FS)

    got = spectrum._dtft_peak(wx, FS, lo, hi, xtol, 500)
    assert got == optimize.fminbound(neg_mag, lo, hi, xtol=xtol, maxfun=500, disp=0)


@pytest.mark.parametrize("seed", range(4))
def test_strict_extrema_times_are_find_peaks_and_the_vertex_bit_for_bit(seed):
    x = _record(400, 10 + seed)
    # a plateau (two equal neighbours) leaves the kernel for find_peaks (its middle sample)
    plateau = np.array([0.0, 1.0, 1.0, 1.0, 0.0, -1.0, -1.0, 0.0, 2.0, 0.5])
    for rec in (x, plateau):
        pk, vl = phase.extrema_times(rec, FS)
        for sgn, got in ((1.0, pk), (-1.0, vl)):
            idx, _ = signal.find_peaks(sgn * rec)
            d = phase.parabolic_vertex(rec[idx - 1], rec[idx], rec[idx + 1])
            np.testing.assert_array_equal(got, (idx + d) / FS)
    assert phase.extrema_times(plateau, 1.0)[0].size == 2


def test_order_columns_match_the_direct_cos_sin():
    rng = np.random.default_rng(4)
    theta = np.cumsum(rng.uniform(0.2, 0.8, 2000))  # up to ~1000 rad
    orders = [1, 2, 3, 5]
    got = filters.order_design(theta, orders)
    for j, k in enumerate(orders):
        # the direct argument k*theta is itself rounded (half a unit in the last place of
        # k*max(theta), 5.7e-14 rad at 5000 rad), and each of the k - 1 complex products adds
        # about one unit in the last place of 1
        tol = 4 * np.spacing(k * theta.max()) + 4 * k * np.spacing(1.0)
        np.testing.assert_allclose(got[:, 2 * j], np.cos(k * theta), rtol=0, atol=tol)
        np.testing.assert_allclose(got[:, 2 * j + 1], np.sin(k * theta), rtol=0, atol=tol)
    assert filters.order_design(theta, []).shape == (theta.size, 0)


def test_model_padded_rows_against_the_direct_tone_model():
    n, pad = 331, 700
    rng = np.random.default_rng(5)
    t = np.arange(n) / FS
    tones = [2.03, 4.6, 9.2]
    rows = [30 + 0.2 * t + sum(rng.uniform(0.1, 1) * np.cos(2 * np.pi * f * t + rng.uniform(0, 6))
                               for f in tones) + 0.01 * rng.standard_normal(n) for _ in range(2)]
    got = tonemodel.model_padded_rows(rows, FS, tones, pad)
    t_all = np.arange(-pad, n + pad) / FS
    for x, (out, level, slope) in zip(rows, got, strict=True):
        design = tonemodel.tone_design(t, tones, line=True)  # the direct evaluation
        coef = np.linalg.lstsq(design, x, rcond=None)[0]
        ref = sum(coef[2 + 2 * k] * np.cos(2 * np.pi * f * t_all)
                  + coef[3 + 2 * k] * np.sin(2 * np.pi * f * t_all)
                  for k, f in enumerate(tones))
        ref[pad:pad + n] = x - coef[0] - coef[1] * (t - t.mean())
        # the SVD and the normal equations agree to ~1e-13 of the data's size, and the
        # tones by rotation to ~1e-14 of their amplitude: 1e-11 absolute at a level of 30
        np.testing.assert_allclose(out, ref, rtol=0, atol=1e-11)
        assert level == pytest.approx(coef[0], rel=1e-13)
        assert slope == pytest.approx(coef[1], rel=1e-9, abs=1e-12)
        # model_padded is the same computation for one record
        single = tonemodel.model_padded(x, FS, tones, pad)
        np.testing.assert_array_equal(single[0], out)


def test_model_statistics_reuse_the_fits_normal_matrix():
    n = 331
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * np.arange(n) / FS, [1, 2])
    model = speedmodel.fit_speed_model({"a": _record(n, 7), "b": _record(n, 8)}, FS, 2.03, slow,
                                  orders)
    d = model.design
    np.testing.assert_array_equal(model.factor.dn, d / np.sqrt(np.einsum("ij,ij->j", d, d)))
    bare = speedmodel.SpeedModel(model.modulation_hz, model.fs_hz, d, model.n_slow, model.coef,
                            model.names)  # no factor: the model computes dn itself
    assert model.noise_depletion() == bare.noise_depletion()
    # the other columns' fit from the kept normal matrix (trailing) or from scratch: 1e-12
    assert model.variance_factor() == pytest.approx(bare.variance_factor(), rel=1e-10)


def _line_search_numpy(spec, freqs, idx, wide, lobe):
    """The former numpy route of peak_frequency's bin checks."""
    k = int(idx[np.argmax(spec[idx])])
    near = np.flatnonzero(np.abs(freqs - freqs[k]) <= 2 * lobe)
    j = int(near[np.argmax(spec[near])])
    sel = np.flatnonzero(wide & (np.abs(freqs - freqs[k]) > lobe))
    floor = float(np.median(spec[sel] ** 2)) if sel.size else float("nan")
    return k, j, floor


@pytest.mark.parametrize("seed", range(8))
def test_line_search_is_the_numpy_route(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(200, 700))
    nfft = int(2 ** np.ceil(np.log2(8 * n)))
    x = _record(n, seed)
    spec = np.abs(np.fft.rfft(x * signal.get_window("hann", n, fftbins=False), nfft))
    if seed % 2:
        spec = np.round(spec, 1)  # ties: the first maximum wins in both
    lo, hi = 1.5, rng.uniform(2.0, 3.0)
    freqs, idx, wide = spectrum._grid(nfft, FS, lo, hi, n)
    lobe = 2.0 * FS / n
    got = spectrum._line_search(spec, freqs, idx, wide, lobe)
    ref = _line_search_numpy(spec, freqs, idx, wide, lobe)
    assert got[:2] == ref[:2] and got[2] == ref[2]


def test_trailing_factor_is_the_factor_of_the_remaining_columns():
    n = 331
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * np.arange(n) / FS, [1, 2])
    t = np.arange(n) / FS
    design = np.column_stack([np.cos(4 * t), np.sin(4 * t), slow, orders])
    y = np.column_stack([_record(n, 1) + 30, _record(n, 2)])
    sub = filters.LstsqFactor.of(design, keep_gram=True).trailing(2)
    other = design[:, 2:]
    got = other @ sub.solve(y)
    # this design's normalised condition number is 6e5: the SVD, a QR and the refined normal
    # equations (filters.lstsq) give fitted values up to 4e-11 of the data's size apart here
    # (measured), so the bound is 1e-10 of it against each
    for ref in (np.linalg.lstsq(other, y, rcond=None)[0], filters.lstsq(other, y)[0]):
        np.testing.assert_allclose(got, other @ ref, rtol=0, atol=1e-10 * np.abs(y).max())
    assert filters.LstsqFactor.of(design).trailing(2) is None  # no normal matrix kept


def test_variance_factor_against_the_qr_of_the_design():
    n = 331
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * np.arange(n) / FS, [1, 2])
    model = speedmodel.fit_speed_model({"a": _record(n, 3)}, FS, 2.03, slow, orders)
    r_inv = np.linalg.inv(np.linalg.qr(model.design)[1])
    m = model.design[:, :2]
    ref = np.trace((r_inv @ r_inv.T)[:2, :2]) / np.trace(np.linalg.inv(m.T @ m))
    # the Schur complement by a refined fit: 1e-11 relative measured on the chain's designs
    # (the inverse of the normal matrix would be 6e-5 off)
    assert model.variance_factor() == pytest.approx(ref, rel=1e-9)


def test_steady_state_is_lfilter_zi_bit_for_bit():
    rng = np.random.default_rng(9)
    for _ in range(60):
        designs = [filters.design_notch(rng.uniform(0.2, 20), rng.uniform(1, 40), FS),
                   filters.design_bandpass(rng.uniform(1.5, 2.5), rng.uniform(0.05, 0.5),
                                           int(rng.integers(1, 4)), FS),
                   (rng.standard_normal(3), np.r_[2.0, rng.uniform(-0.5, 0.5, 1)])]
        for b, a in designs:
            np.testing.assert_array_equal(filters._steady_state(np.asarray(b, float),
                                                                np.asarray(a, float)),
                                          signal.lfilter_zi(b, a))


def test_slow_orders_removal_is_the_speed_models_parts():
    n = 323
    slow = filters.slow_basis(n, FS, 1.2)
    t = np.arange(n) / FS
    orders = filters.order_design(2 * np.pi * 4.6 * t * (1 + 0.01 * t), [1, 2])
    rng = np.random.default_rng(12)
    y = np.column_stack([30 + 0.3 * t + 8 * np.cos(2 * np.pi * 2.01 * t + 0.3)
                         + rng.standard_normal(n),
                         30 * (1 + 0.002 * np.sin(2 * np.pi * 0.3 * t)) + 0.05 * np.cos(
                             2 * np.pi * 4.6 * t) + 2e-3 * np.cos(2 * np.pi * 2.01 * t - 0.1)
                         + 2e-3 * rng.standard_normal(n)])
    removal = speedmodel._SlowOrdersRemoval(y, slow, orders, FS)
    for f in (1.95, 2.0, 2.0137):
        model = speedmodel.fit_speed_model({"a": y[:, 0], "b": y[:, 1]}, FS, f, slow, orders)
        ref = np.column_stack([y[:, j] - model.part(k, "slow") - model.part(k, "orders")
                               for j, k in enumerate(("a", "b"))])
        q, r = np.linalg.qr(model.design)
        exact = y - model.design[:, 2:] @ np.linalg.solve(r, q.T @ y)[2:]
        # the design's condition number is 1e6, so the split of a record of level 30 into
        # its parts is determined to ~1e6 * 2.2e-16 * 30 = 7e-9: both routes are within
        # 1.3e-9 of the QR solution (measured), bound 5e-9
        np.testing.assert_allclose(removal.at(f), exact, rtol=0, atol=5e-9)
        np.testing.assert_allclose(ref, exact, rtol=0, atol=5e-9)


def test_design_notch_is_scipy_iirnotch_bit_for_bit():
    rng = np.random.default_rng(13)
    for _ in range(300):
        fs = rng.uniform(20, 20_000)
        f0, q = rng.uniform(1e-3, 0.499) * fs, rng.uniform(0.5, 100)
        got = filters.design_notch(f0, q, fs)
        ref = signal.iirnotch(f0, q, fs=fs)
        for g, r in zip(got, ref, strict=True):
            np.testing.assert_array_equal(g, r)
    with pytest.raises(ValueError):
        filters.design_notch(30.0, 3.0, 50.0)  # above Nyquist: scipy's error
    assert resampling.resample_ratio(16_670.0, 53.344) == (2, 625)


def _refined_cholesky_lstsq(design, y, skip=0):
    """The least-squares route of filters.lstsq written with scipy's own Cholesky
    routines: normalised columns, cho_factor/cho_solve, two refinement steps; with ``skip``
    the fit on the columns after the first ``skip`` from the whole design's normal matrix
    (LstsqFactor.trailing)."""
    from scipy import linalg
    scale = np.sqrt(np.einsum("ij,ij->j", design, design))
    dn = design / scale
    gram = dn.T @ dn
    dn, scale = dn[:, skip:], scale[skip:]
    factor = linalg.cho_factor(gram[skip:, skip:], lower=False)
    coef = linalg.cho_solve(factor, dn.T @ y)
    for _ in range(2):
        coef += linalg.cho_solve(factor, dn.T @ (y - dn @ coef))
    return (coef.T / scale).T


@pytest.mark.parametrize("layout", ["C", "F"])
@pytest.mark.parametrize("seed", range(4))
def test_compiled_lstsq_factor_is_scipys_cholesky_route(seed, layout):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(250, 700))
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * np.arange(n) / FS, [1, 2])
    t = np.arange(n) / FS
    w = 2 * np.pi * 2.03
    design = np.column_stack([np.cos(w * t), np.sin(w * t), slow, orders])
    design = np.asfortranarray(design) if layout == "F" else np.ascontiguousarray(design)
    y = np.column_stack([_record(n, seed) + 30, _record(n, seed + 1), _record(n, seed + 2)])
    fac = filters.LstsqFactor.of(design, keep_gram=True)
    sub = fac.trailing(2)
    # the compiled route calls the same LAPACK routines (potrf, potrs) and the same BLAS
    # products, on one BLAS thread as the chain runs: bit for bit on the development
    # machine (numpy 2.4 and scipy 1.17 with their own OpenBLAS builds); the bound allows
    # BLAS kernels that sum in another order (condition number ~1e6: coefficients to ~1e-13)
    with one_blas_thread():
        for yy in (y, y[:, 0], y[:, 1].copy(), y[:, :2]):
            np.testing.assert_allclose(fac.solve(yy), _refined_cholesky_lstsq(design, yy),
                                       rtol=1e-12, atol=0)
        np.testing.assert_allclose(sub.solve(y), _refined_cholesky_lstsq(design, y, 2),
                                   rtol=1e-12, atol=0)
    for arr in (fac.dn, fac.scale, fac.factor, fac.gram, sub.dn, sub.factor):
        assert not arr.flags.writeable
    gram = fac.gram.copy()  # LAPACK factors a copy, also of a 1 x 1 block
    assert fac.trailing(design.shape[1] - 1) is not None
    np.testing.assert_array_equal(fac.gram, gram)


def test_lstsq_factor_refuses_what_lstsq_leaves_to_the_svd():
    n = 200
    t = np.arange(n) / FS
    good = np.column_stack([np.ones(n), t, np.cos(3 * t)])
    assert filters.LstsqFactor.of(good) is not None
    assert filters.LstsqFactor.of(np.column_stack([good, np.zeros(n)])) is None  # zero column
    with_nan = good.copy()
    with_nan[5, 1] = np.nan
    assert filters.LstsqFactor.of(with_nan) is None
    assert filters.LstsqFactor.of(np.column_stack([good, good[:, 1] * 2])) is None  # rank 3
    assert filters.LstsqFactor.of(np.empty((n, 0))) is None
    coef, rank = filters.lstsq(np.column_stack([good, good[:, 1] * 2]), np.cos(3 * t))
    assert rank == 3 and np.allclose(np.column_stack([good, good[:, 1] * 2]) @ coef,
                                     np.cos(3 * t))


def test_record_std_is_numpys_bit_for_bit():
    from torquemod.processing.cyclechecks import record_std
    rng = np.random.default_rng(21)
    for n in [1, 2, 7, 8, 9, 127, 128, 129, 323, 1000, 4099]:
        x = 30.0 + rng.standard_normal(n) * 10.0 ** rng.uniform(-4, 1)
        assert record_std(x) == float(np.std(x))
    assert record_std(np.arange(5)) == float(np.std(np.arange(5)))  # numpy's route
