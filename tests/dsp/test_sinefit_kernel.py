"""The sine fit's compiled route (torquemod.dsp.phase._sine_fit: least squares and the
residual's noise density from DFT sums over the band's bins) against numpy's route and a
brute-force periodogram."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from torquemod.dsp import phase

FS = 53.344  # the chain's rate [Hz]


@pytest.mark.parametrize("n", [201, 321, 322, 690])
@pytest.mark.parametrize("f_hz", [1.0, 2.0, 2.37])
def test_band_density_is_the_periodogram_mean_near_f(n, f_hz):
    x = np.random.default_rng(n).standard_normal(n) + 0.3 * np.cos(0.7 * np.arange(n))
    got = phase._band_density(x, FS, f_hz, *phase._dft_table(n), 0.75)
    # brute force: scipy's Hann periodogram of the mean-removed record, the bins within
    # 0.75 Hz of f but not within 1.5 bins of it
    f, p = signal.periodogram(x - x.mean(), FS, window="hann", detrend=False)
    off = np.abs(f - f_hz)
    ref = p[(off <= 0.75) & (off > 1.5 * (f[1] - f[0]))].mean()
    # DFT sums against the FFT: ~1e-15 relative per bin; bound 1e-12
    assert got == pytest.approx(ref, rel=1e-12)
    assert got == pytest.approx(phase.local_noise_psd(x, FS, f_hz), rel=1e-12)


def test_band_density_flags_too_few_bins():
    x = np.random.default_rng(0).standard_normal(60)  # 1.1 s: bins 0.89 Hz apart
    assert np.isnan(phase._band_density(x, FS, 2.0, *phase._dft_table(60), 0.75))


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("noise", [False, True])
def test_sinefit_compiled_against_numpy_route(seed, noise):
    rng = np.random.default_rng(seed)
    n = 323
    t = np.arange(n) / FS
    f = 2.0 + 0.01 * seed
    tq = 30 + 8 * np.cos(2 * np.pi * f * t + 0.3) + 0.2 * np.cos(2 * np.pi * 4.6 * t) \
        + 0.5 * rng.standard_normal(n)
    wh = 30 + 2e-3 * np.cos(2 * np.pi * f * t - 0.1) + 1e-3 * rng.standard_normal(n)
    noise_from = (tq + 0.1 * rng.standard_normal(n), wh) if noise else None
    got = phase.sinefit_phase(tq, wh, FS, f, nuisance_hz=(4.6,), noise_from=noise_from)
    start, stop = phase.whole_period_window(n, FS, f)
    design = phase._design(stop - start, FS, f, (4.6,), True)
    cols = [tq[start:stop], wh[start:stop]]
    if noise:
        cols += [noise_from[0][start:stop], noise_from[1][start:stop]]
    coef, psds = phase._sine_fit_numpy(design, np.column_stack(cols), FS, f)
    ref_phase = np.degrees(np.arctan2(-coef[1, 0], coef[0, 0])
                           - np.arctan2(-coef[1, 1], coef[0, 1]))
    t_win = (stop - start) / FS
    ref_se = np.degrees(np.sqrt(sum(p / ((coef[0, c] ** 2 + coef[1, c] ** 2) * t_win)
                                    for c, p in enumerate(psds))))
    # a condition number ~10 here: the two routes agree to ~1e-14; bounds 1e-11 deg, 1e-11
    assert got.phase_deg == pytest.approx(ref_phase, abs=1e-11)
    assert got.phase_stderr_deg == pytest.approx(ref_se, rel=1e-11)


@pytest.mark.parametrize("n_records,tones", [(2, (4.6,)), (4, (4.6, 9.2, 0.15)), (4, ())])
def test_sine_fit_of_the_records_window_is_the_stacked_fit_bit_for_bit(n_records, tones):
    rng = np.random.default_rng(n_records + len(tones))
    n, f = 323, 2.01
    t = np.arange(n) / FS
    recs = [30 + 8 * np.cos(2 * np.pi * f * t + k) + rng.standard_normal(n) for k in range(4)]
    start, stop = phase.whole_period_window(n, FS, f, center_s=3.1)
    m = stop - start
    design = np.ascontiguousarray(phase._design(m, FS, f, tones, True))
    y = np.column_stack([r[start:stop] for r in recs[:n_records]])
    want = phase._sine_fit(design, y, FS, f, *phase._dft_table(m), *phase.lapack_addresses())
    got = phase._sine_fit_records(phase._fixed_columns(m, FS, f, True),
                                  np.array(tones, dtype=np.float64), *recs, n_records, start,
                                  FS, f, *phase._dft_table(m), *phase.lapack_addresses())
    assert got[0] == want[0] == 0
    np.testing.assert_array_equal(got[1], want[1])
    np.testing.assert_array_equal(got[2], want[2])


@pytest.mark.parametrize("n,k", [(320, 4), (321, 1), (690, 6), (64, 3)])
def test_tones_filled_together_are_fill_tones_bit_for_bit(n, k):
    tones = np.linspace(0.15, 9.2, k)
    want = np.zeros((n, 4 + 2 * k))
    got = np.zeros((n, 4 + 2 * k))
    phase._fill_tones(want, 4, FS, tones)
    phase._fill_tones_together(got, 4, FS, tones)
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("n", [17, 321, 690])
@pytest.mark.parametrize("trend", [True, False])
def test_fixed_columns_are_the_window_formula_bit_for_bit(n, trend):
    # the cached times and ones/line columns with fresh cos/sin give the arrays the whole
    # formula gives (t from the window centre), for frequencies never asked before
    t = (np.arange(n) - (n - 1) / 2) / FS
    for f_hz in (0.5 + n * 1e-7, 2.0137 + n * 1e-7):
        want = np.column_stack([np.cos(2 * np.pi * f_hz * t), np.sin(2 * np.pi * f_hz * t),
                                phase.tone_design(t, (), line=trend)])
        got = phase._fixed_columns(n, FS, f_hz, trend)
        assert got.shape == want.shape and got.flags.c_contiguous
        assert np.array_equal(got, want)
        assert not got.flags.writeable


@pytest.mark.parametrize("n,f_hz,width", [(321, 2.0, 0.75), (322, 2.37, 1.5), (200, 1.0, 1.2),
                                          (690, 2.0, 3.0)])
def test_band_density_is_the_bins_one_at_a_time_bit_for_bit(n, f_hz, width):
    """The bins' DFT sums four at a time: the numbers of one bin at a time in plain Python
    (the sums over the samples in order, the same table entries)."""
    x = np.random.default_rng(n).standard_normal(n) + 0.3 * np.cos(0.7 * np.arange(n))
    cos_t, sin_t, w, ss = phase._dft_table(n)
    got = phase._band_density(x, FS, f_hz, cos_t, sin_t, w, ss, width)
    mean = phase._numpy_sum(x, 0, n) / n
    xw = ((x - mean) * w).tolist()
    val = 1.0 / (n * (1.0 / FS))
    vals = []
    for k in range(n // 2 + 1):
        off = abs(k * val - f_hz)
        if off <= width and off > 1.5 * (val - 0.0):
            re = im = 0.0
            j = 0
            for t in range(n):
                re += xw[t] * float(cos_t[j])
                im -= xw[t] * float(sin_t[j])
                j = (j + k) % n
            p = (re * re + im * im) / (FS * ss)
            vals.append(2.0 * p if 1 <= k < n // 2 + (n % 2) else p)
    assert len(vals) >= 2
    assert got == phase._numpy_sum(np.array(vals), 0, len(vals)) / len(vals)
