"""The numba decimation kernels of dsp/filters.py (issue 11, throughput) against independent
references: ``np.convolve`` for the first stage and ``scipy.signal.resample_poly`` for the
second. The kernels reorder their sums (numba fast-math ``reassoc``), so they agree with the
references to rounding: the tolerances are 1e-13 of the data's size (measured up to 1.6e-15)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from torquemod.dsp import filters, resampling, tonemodel


@pytest.mark.parametrize("n", [50, 1_000, 1_013, 5_003])
@pytest.mark.parametrize(("up", "down"), [(2, 25), (3, 7), (1, 4), (5, 3), (4, 9)])
def test_stage2_kernel_is_resample_poly(n, up, down):
    x = np.random.default_rng(n + up).standard_normal(n)
    ref = signal.resample_poly(x, up, down, window=filters._resampling_fir(up, down, 5.0),
                               padtype="constant")
    phases, taps = filters._stage2_phases(up, down, 5.0)
    got = np.full(ref.size, np.nan)
    filters._upfirdn_centred_row(x, phases, taps, up, down, got)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-13 * np.abs(x).max())


@pytest.mark.parametrize("n", [100, 5_003, 5_025])
def test_stage1_kernel_removes_the_offset_and_pads_with_zeros(n):
    rng = np.random.default_rng(n)
    x = 30.0 + rng.standard_normal(n)
    offset = float(x.mean())
    h = filters.stage1_fir(25, 2, 625)
    half = (h.size - 1) // 2
    got = np.full((n - 1) // 25 + 1, np.nan)
    filters._fir_decimate_row(x, offset, h, 25, got)
    full = np.convolve(x - offset, h)[half:half + n]  # centred; zeros outside the record
    np.testing.assert_allclose(got, full[::25], rtol=0, atol=1e-13 * 30.0)


def test_two_stage_equals_the_former_route():
    """stage 1 by a full convolution, stage 2 by resample_poly (the code before the kernels),
    on a DC-heavy record with a line and a tone, each row's mean removed and restored."""
    rng = np.random.default_rng(2)
    n = 60_013
    t = np.arange(n) / 16_670.0
    rows = [30.0 + 0.3 * t + 1e-3 * np.sin(2 * np.pi * 2.0 * t) + 1e-3 * rng.standard_normal(n),
            5.0 * rng.standard_normal(n) - 7.0]
    got, means = resampling.resample_rows(rows, 2, 625, method="two_stage", padtype="constant",
                                       return_means=True)
    q1, down2 = filters.two_stage_plan(2, 625)
    h = filters.stage1_fir(q1, 2, 625)
    half = (h.size - 1) // 2
    n_out = -(-n * 2 // 625)
    for row, m, y in zip(rows, means, got, strict=True):
        y1 = np.convolve(row - m, h)[half:half + n][::q1]
        ref = signal.resample_poly(y1, 2, down2, window=filters._resampling_fir(2, down2, 5.0),
                                   padtype="constant")[:n_out] + m
        np.testing.assert_allclose(y, ref, rtol=0, atol=1e-13 * np.abs(row).max())
    # the stacked entry point gives the same bits as the rows
    np.testing.assert_array_equal(
        resampling.resample(np.vstack(rows), 2, 625, method="two_stage", padtype="constant"), got)


@pytest.mark.parametrize("order", [1, 2, 3, 4])
@pytest.mark.parametrize(("center", "width"), [(2.0, 0.36), (1.6, 0.1), (2.5, 1.0), (10.0, 3.0)])
def test_bandpass_design_is_scipy_butter(order, center, width):
    fs = 53.344
    b, a = filters.design_bandpass(center, width, order, fs)
    rb, ra = signal.butter(order, [center - width / 2, center + width / 2], "bandpass", fs=fs)
    # rounding only: measured <= 5e-16 of the largest coefficient
    np.testing.assert_allclose(b, rb, rtol=0, atol=1e-14 * np.abs(rb).max())
    np.testing.assert_allclose(a, ra, rtol=0, atol=1e-14 * np.abs(ra).max())


def test_steady_state_is_lfilter_zi_bit_for_bit():
    fs = 53.344
    for b, a in (filters.design_bandpass(2.0, 0.36, 2, fs), filters.design_notch(4.6, 3.0, fs),
                 (np.array([0.5, 0.2]), np.array([2.0, -0.3, 0.1])),
                 (np.array([0.3, 0.2, 0.1, 0.05]), np.array([1.0, -0.5]))):
        np.testing.assert_array_equal(filters._steady_state(b, a), signal.lfilter_zi(b, a))


def test_extrema_times_match_find_peaks_with_and_without_plateaus():
    from torquemod.dsp import phase
    rng = np.random.default_rng(4)
    fs = 53.344
    for case in range(40):
        x = np.sin(2 * np.pi * 2.0 * np.arange(400) / fs) + 0.3 * rng.standard_normal(400)
        if case % 2:  # plateaus (equal neighbours): find_peaks takes their middle sample
            x = np.round(x, 1)
        got = phase.extrema_times(x, fs)
        for sgn, times in zip((1.0, -1.0), got, strict=True):
            idx, _ = signal.find_peaks(sgn * x)
            y_m1, y_0, y_p1 = sgn * x[idx - 1], sgn * x[idx], sgn * x[idx + 1]
            den = y_m1 - 2.0 * y_0 + y_p1  # the former vertex formula
            with np.errstate(invalid="ignore", divide="ignore"):
                d = 0.5 * (y_m1 - y_p1) / den
            d = np.where(den != 0, np.clip(d, -0.5, 0.5), 0.0)
            np.testing.assert_array_equal(times, (idx + d) / fs)


def test_cos_sin_blocks_match_direct_evaluation():
    fs, pad, n = 53.344, 1008, 323
    t = np.arange(-pad, n + pad) / fs
    for f in (0.3, 2.003, 9.22, 26.0):
        cos, sin = tonemodel._cos_sin(2 * np.pi * f / fs, -pad, n + 2 * pad)
        # the direct argument 2*pi*f*t is itself rounded (a few units in the last place of
        # the largest argument, up to 9e-13 rad at 26 Hz here)
        tol = 4 * np.spacing(2 * np.pi * f * np.abs(t).max())
        np.testing.assert_allclose(cos, np.cos(2 * np.pi * f * t), rtol=0, atol=tol)
        np.testing.assert_allclose(sin, np.sin(2 * np.pi * f * t), rtol=0, atol=tol)


def test_numba_zero_phase_cascade_is_filtfilt_bit_for_bit():
    fs = 53.344
    rng = np.random.default_rng(6)
    rows = 30.0 + rng.standard_normal((3, 2_000))
    bas = [filters.design_notch(4.6, 3.0, fs), filters.design_highpass(0.5, 2, fs),
           filters.design_bandpass(2.03, 0.36, 2, fs), filters.design_bandpass(2.0, 1.0, 3, fs),
           (np.array([0.2, 0.1]), np.array([2.0, -0.5, 0.1]))]  # scipy's general case
    got = filters.zero_phase_cascade(bas, rows)
    for i in range(3):
        ref = rows[i]
        for b, a in bas:
            ref = signal.filtfilt(b, a, ref, padlen=0)
        np.testing.assert_array_equal(got[i], ref)
    np.testing.assert_array_equal(filters.zero_phase_cascade(bas[2:3], rows[1]),
                                  signal.filtfilt(*bas[2], rows[1], padlen=0))
    assert rows[0, 0] != got[0, 0]  # the input is left alone


def _neg_numpy_dtft(f, wx, fs):
    return -abs(np.dot(wx, np.exp(-2j * np.pi * f / fs * np.arange(wx.size))))


def test_dtft_magnitude_and_peak_frequency_against_the_numpy_route():
    """|DTFT| by angle addition against numpy's complex exponentials (a few ulp), and the
    peak search built on it against the former one (scipy's fminbound on the numpy |DTFT|):
    within 5e-10 Hz on random records (measured up to 2.1e-10 Hz over 2805 records; the
    search's own distance to the true maximiser is ~2e-8 Hz)."""
    from scipy import optimize

    from torquemod.dsp import spectrum
    from torquemod.errors import ProcessingError
    fs = 53.344
    rng = np.random.default_rng(123)
    worst = 0.0
    for _ in range(150):
        n = int(rng.integers(200, 700))
        t = np.arange(n) / fs
        x = (rng.uniform(-50, 50) + rng.uniform(-1, 1) * t
             + rng.uniform(1e-3, 1) * np.sin(2 * np.pi * rng.uniform(1.6, 2.4) * t + 1.0)
             + rng.uniform(0, 0.5) * np.sin(2 * np.pi * rng.uniform(3, 20) * t)
             + rng.uniform(1e-4, 0.3) * rng.standard_normal(n))
        step = 2 * np.pi * 2.01 / fs
        direct = abs(np.dot(x, np.exp(-1j * step * np.arange(n))))
        assert spectrum._dtft_magnitude(x, step) == pytest.approx(direct, rel=1e-13)
        try:
            got = spectrum.peak_frequency(x, fs)
        except ProcessingError:
            continue
        # the former search: the same detrending, window and grid, fminbound on numpy's |DTFT|
        design, fac = spectrum._trend_design(n, fs, True)
        xd = x - design @ fac.solve(x)
        w = signal.get_window("hann", n, fftbins=False)
        nfft = int(2 ** np.ceil(np.log2(8 * n)))
        freqs = np.fft.rfftfreq(nfft, 1.0 / fs)
        spec = np.abs(np.fft.rfft(xd * w, nfft))
        idx = np.flatnonzero((freqs >= 1.5) & (freqs <= 2.5))
        k = int(idx[np.argmax(spec[idx])])
        df = freqs[1] - freqs[0]
        ref = optimize.fminbound(_neg_numpy_dtft, freqs[k] - df, freqs[k] + df,
                                 args=(w * xd, fs), xtol=1e-6, maxfun=500, disp=0)
        worst = max(worst, abs(got - ref))
    assert worst < 5e-10


@pytest.mark.parametrize("n", [323, 331, 1000])
@pytest.mark.parametrize("max_hz", [0.4, 1.2, 2.5])
def test_dpss_is_scipy_dpss(n, max_hz):
    from scipy.signal.windows import dpss
    nw = n / 53.344 * max_hz
    k = round(2 * nw) + 2
    got = filters._dpss(n, nw, k)
    # eigenvalues to 1e-9 of their size instead of full precision: the vectors agree to
    # rounding (measured <= 4.5e-14 at these sizes) and stay orthonormal (as scipy's own:
    # 2.1e-14 at n = 323, 2.5 Hz; ours 1.3e-14 at n = 331)
    ref = dpss(n, nw, k)
    np.testing.assert_allclose(got, ref, rtol=0, atol=2e-13)
    orth = max(5e-14, 2 * np.max(np.abs(ref @ ref.T - np.eye(k))))
    np.testing.assert_allclose(got @ got.T, np.eye(k), rtol=0, atol=orth)
