"""The chain's fast paths (issue 11, throughput) against the straightforward computations they
replace. Each reference below is the plain scipy/numpy route (the code before the speed-up,
written out here); the fast path must give the same bits unless a tolerance is stated."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg, optimize, signal

from torquemod.dsp import filters, resampling, spectrum, tonemodel
from torquemod.processing import speedmodel, trackedorders

FS = 53.344
RNG = np.random.default_rng(11)


def _record(n: int = 331, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    return (30.0 + 0.2 * t + 0.01 * np.sin(2 * np.pi * 2.03 * t + 0.4)
            + 0.05 * np.sin(2 * np.pi * 4.6 * t) + 1e-3 * rng.standard_normal(n))


def test_zero_phase_cascade_is_filtfilt_in_sequence_bit_for_bit():
    fs = FS
    bas = [filters.design_notch(4.6, 3.0, fs), filters.design_highpass(0.5, 2, fs),
           filters.design_bandpass(2.03, 0.36, 2, fs)]
    rows = np.vstack([_record(900, 1), _record(900, 2)])
    got = filters.zero_phase_cascade(bas, rows)
    for i in range(2):
        ref = rows[i]
        for ba in bas:
            ref = signal.filtfilt(*ba, ref, padlen=0)
        np.testing.assert_array_equal(got[i], ref)
    np.testing.assert_array_equal(filters.zero_phase_cascade(bas[:1], rows[0]),
                                  signal.filtfilt(*bas[0], rows[0], padlen=0))


@pytest.mark.parametrize("n_rows", [1, 2, 3])
def test_zero_phase_cascade_of_every_order_and_row_count_is_filtfilt(n_rows):
    # orders 2 and 4 take the kernel with the state in registers, two rows at a time (an
    # odd row count leaves one alone); orders 1 and 3 the general loop
    bas = [signal.butter(1, 3.0, fs=FS), signal.butter(3, [1.5, 2.5], "bandpass", fs=FS),
           filters.design_notch(4.6, 3.0, FS), filters.design_bandpass(2.03, 0.36, 2, FS)]
    rows = np.vstack([_record(700, 10 + i) for i in range(n_rows)])
    for ba in bas:
        got = filters.zero_phase_cascade([ba], rows)
        for i in range(n_rows):
            np.testing.assert_array_equal(got[i], signal.filtfilt(*ba, rows[i], padlen=0))


@pytest.mark.parametrize("method", ["two_stage", "polyphase"])
def test_resample_rows_is_resample_of_the_stack_bit_for_bit(method):
    n = 40_000
    rows = [100.0 + RNG.standard_normal(n), 3.0 * RNG.standard_normal(n) - 7.0]
    ref = resampling.resample(np.vstack(rows), 2, 625, method=method, padtype="constant")
    got, means = resampling.resample_rows(rows, 2, 625, method=method, padtype="constant",
                                       return_means=True)
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(means, [np.mean(r) for r in rows])


def test_model_padded_rows_is_model_padded_of_each_row_bit_for_bit():
    rows = [_record(331, 3), _record(331, 4) * 0.01]
    tones, pad = [2.03, 4.6, 9.2], 500
    got = tonemodel.model_padded_rows(rows, FS, tones, pad)
    for x, (out, level, slope) in zip(rows, got, strict=True):
        ref_out, ref_level, ref_slope = tonemodel.model_padded(x, FS, tones, pad)
        np.testing.assert_array_equal(out, ref_out)
        assert (level, slope) == (ref_level, ref_slope)


def _lstsq_scipy(design, y):
    """The former route: scipy's cho_factor/cho_solve with two refinement steps."""
    scale = np.sqrt(np.einsum("ij,ij->j", design, design))
    dn = design / scale
    factor = linalg.cho_factor(dn.T @ dn, check_finite=False)
    coef = linalg.cho_solve(factor, dn.T @ y, check_finite=False)
    for _ in range(2):
        coef += linalg.cho_solve(factor, dn.T @ (y - dn @ coef), check_finite=False)
    return (coef.T / scale).T


def test_lstsq_through_lapack_matches_scipy_cho_and_the_svd():
    slow = filters.slow_basis(331, FS, 1.2)
    # a wheel turning at 4.6 Hz: its orders lie above the slow band (well conditioned)
    angle = 2 * np.pi * 4.6 * np.arange(331) / FS
    design = np.column_stack([slow, filters.order_design(angle, [1, 2])])
    assert filters.LstsqFactor.of(design) is not None
    y = np.column_stack([_record(331, 5), _record(331, 6) - 30.0])
    coef, rank = filters.lstsq(design, y)
    np.testing.assert_array_equal(coef, _lstsq_scipy(design, y))
    np.testing.assert_array_equal(filters.LstsqFactor.of(design).solve(y), coef)
    assert rank == design.shape[1]
    ref = np.linalg.lstsq(design, y, rcond=None)[0]
    # the SVD and the refined normal equations agree to rounding of the fitted values
    # (measured 1.0e-12 at a level of 31, i.e. 3e-14 of the data's size)
    np.testing.assert_allclose(design @ coef, design @ ref, rtol=0,
                               atol=1e-13 * np.abs(y).max())
    # a rank-deficient design still falls back to the SVD
    bad = np.column_stack([design[:, :3], design[:, 1]])
    assert filters.LstsqFactor.of(bad) is None
    assert filters.lstsq(bad, y[:, 0])[1] == 3


def _settling_reference(ba, tol=1e-6, max_samples=1_000_000):
    b, a = ba
    n = 256
    while n <= max_samples:
        h = signal.lfilter(b, a, np.r_[1.0, np.zeros(n - 1)])
        above = np.flatnonzero(np.abs(h) > tol * np.abs(h).max())
        if above[-1] < n - n // 4:
            return int(above[-1]) + 1
        n *= 2
    return max_samples


@pytest.mark.parametrize("ba", [filters.design_bandpass(2.0, 0.36, 2, FS),
                                filters.design_bandpass(1.6, 0.1, 2, FS),
                                filters.design_highpass(0.5, 2, FS),
                                filters.design_notch(4.6, 3.0, FS),
                                filters.design_notch(0.4, 30.0, FS)])
def test_settling_samples_equals_the_doubling_search(ba):
    assert filters.settling_samples(ba) == _settling_reference(ba)


def test_settling_kernel_equals_the_lfilter_search():
    rng = np.random.default_rng(3)
    designs = [filters.design_highpass(0.5, 2, FS), filters.design_bandpass(2.0, 0.36, 2, FS)]
    for _ in range(12):
        designs.append(filters.design_notch(rng.uniform(0.2, 20), rng.uniform(1, 40), FS))
        designs.append(filters.design_bandpass(rng.uniform(1.5, 2.5), rng.uniform(0.05, 0.5),
                                               int(rng.integers(1, 4)), FS))
    for ba in designs:
        b, a = (np.array(v, dtype=float) for v in ba)  # writeable: the uncached route
        assert filters.settling_samples((b, a)) == _settling_reference((b, a))
        assert filters.settling_samples((b, a), tol=1e-9) == _settling_reference((b, a), 1e-9)


def _peak_reference(x, fs_hz, band_hz=(1.5, 2.5), zero_pad=8, xtol_hz=1e-6):
    """The former refinement (detrend, Hann, zero-padded FFT, minimize_scalar on |DTFT|)
    without the line-detection checks."""
    n = x.size
    design = tonemodel.tone_design(np.arange(n) / fs_hz, [], line=True)
    xd = x - design @ filters.lstsq(design, x)[0]
    w = signal.get_window("hann", n, fftbins=False)
    nfft = int(2 ** np.ceil(np.log2(zero_pad * n)))
    spec = np.abs(np.fft.rfft(xd * w, nfft))
    freqs = np.fft.rfftfreq(nfft, 1.0 / fs_hz)
    idx = np.flatnonzero((freqs >= band_hz[0]) & (freqs <= band_hz[1]))
    k = int(idx[np.argmax(spec[idx])])
    df = freqs[1] - freqs[0]
    res = optimize.minimize_scalar(
        lambda f: -abs(spectrum.windowed_dtft(xd, fs_hz, f, w)),
        bounds=(freqs[k] - df, freqs[k] + df), method="bounded", options={"xatol": xtol_hz})
    return float(res.x)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_peak_frequency_equals_the_former_refinement(seed):
    x = _record(331 + seed, seed)
    # the |DTFT| by angle addition (numba) rounds differently from numpy's complex exp: the
    # search lands within 2.1e-10 Hz of the former one over 2805 random records (measured;
    # the search's own distance to the true maximiser is ~2e-8 Hz)
    assert spectrum.peak_frequency(x, FS) == pytest.approx(_peak_reference(x, FS), abs=5e-10)


def test_speed_model_noise_depletion_without_forming_q():
    n = 331
    slow = filters.slow_basis(n, FS, 1.2)
    orders = filters.order_design(2 * np.pi * 4.6 * np.arange(n) / FS, [1, 2])
    model = speedmodel.fit_speed_model({"a": _record(n, 7)}, FS, 2.03, slow, orders)
    got = model.noise_depletion()
    # reference: Q from the SVD of the design (the normal equations' Q = D L^-T, the route
    # before CholeskyQR2, was 2.3e-5 relative off it here)
    d = model.design
    dn = d / np.sqrt(np.einsum("ij,ij->j", d, d))
    q = np.linalg.svd(dn, full_matrices=False)[0]
    df = FS / n
    k = np.arange(n // 2 + 1)
    off = np.abs(k * df - 2.03)
    sel = k[(off <= 0.75) & (off > 1.5 * df)]
    v = signal.get_window("hann", n)[:, None] * np.exp(-2j * np.pi * np.outer(np.arange(n), sel)
                                                        / n)
    kept = 1.0 - np.sum(np.abs(q.T @ v) ** 2, axis=0) / np.sum(np.abs(v) ** 2, axis=0)
    # 1e-10: the two routes round differently (measured <= 1e-12 relative on the synthetic
    # cycles of benchmarks/throughput.py); the value scales only the phase's standard error
    assert got == pytest.approx(float(np.clip(np.mean(kept), 0.05, 1.0)), rel=1e-10)
    # parts are computed once and cannot be changed through the cache
    part = model.part("a", "slow")
    assert part is model.part("a", "slow") and not part.flags.writeable
    np.testing.assert_array_equal(part, model.design[:, 2:2 + model.n_slow]
                                  @ model.coef[2:2 + model.n_slow, 0])


def test_tracked_orders_with_a_shared_first_factor_bit_for_bit():
    n = 331
    slow = filters.slow_basis(n, FS, 1.2)
    base = trackedorders._order_base(n, FS, slow, 2.03)
    fac = filters.LstsqFactor.of(base)
    for seed, f_rot in ((8, 4.6), (9, 0.35)):
        t = np.arange(n) / FS
        speed = 2 * np.pi * f_rot * (1 + 0.01 * np.cos(2 * np.pi * f_rot * t)) \
            + 1e-3 * np.random.default_rng(seed).standard_normal(n)
        ref = trackedorders.tracked_orders(speed, FS, slow, (1, 2), above_hz=1.2, avoid_hz=2.03,
                                   modulation_hz=2.03)
        got = trackedorders._tracked_orders(speed, FS, slow, (1, 2), base, fac, above_hz=1.2,
                                    avoid_hz=2.03)
        np.testing.assert_array_equal(got[0], ref[0])
        assert got[1] == ref[1]
