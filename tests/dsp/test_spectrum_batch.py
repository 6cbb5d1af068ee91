"""The spectral peaks of several records in one pass (torquemod.dsp.spectrum.peak_frequencies)
against peak_frequency on each record, and against the brute-force maximiser of the
windowed DTFT."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.dsp.spectrum import peak_frequencies, peak_frequency
from torquemod.errors import ProcessingError

FS = 53.344  # the chain's rate [Hz]


def _records(n: int, seed: int) -> np.ndarray:
    """Three (n,) records with a line in 1.5-2.5 Hz, drift, a rotation-order line and noise,
    side by side as columns."""
    t = np.arange(n) / FS
    rng = np.random.default_rng(seed)
    cols = [30 + 0.2 * t + 8 * np.cos(2 * np.pi * 2.013 * t + 0.3) + rng.standard_normal(n),
            30 + 0.05 * np.cos(2 * np.pi * 4.6 * t) + 2e-3 * np.cos(2 * np.pi * 1.987 * t)
            + 2e-4 * rng.standard_normal(n),
            np.cos(2 * np.pi * 1.6123 * t) + 0.1 * rng.standard_normal(n)]
    return np.column_stack(cols)


@pytest.mark.parametrize("n,seed", [(323, 1), (323, 2), (690, 3), (150, 4)])
@pytest.mark.parametrize("detrend", ["linear", "constant"])
def test_equal_to_peak_frequency_of_each_contiguous_record(n, seed, detrend):
    x = _records(n, seed)
    got = peak_frequencies(x, FS, detrend=detrend)
    want = [peak_frequency(np.ascontiguousarray(x[:, i]), FS, detrend=detrend)
            for i in range(x.shape[1])]
    assert got == want  # the same steps on the same numbers: bit for bit


def test_the_maximiser_of_the_windowed_dtft():
    """Against a brute-force grid of the windowed DTFT's magnitude (1e-7 Hz spacing around
    the result): the result is its maximiser to the refinement's tolerance, 1e-6 Hz."""
    n = 323
    x = _records(n, 5)
    got = peak_frequencies(x, FS)
    idx = np.arange(n)
    w = 0.5 - 0.5 * np.cos(2 * np.pi * idx / (n - 1))  # the symmetric Hann window
    for col, f in zip(x.T, got, strict=True):
        d = np.column_stack([np.ones(n), idx / FS])
        xd = col - d @ np.linalg.lstsq(d, col, rcond=None)[0]
        grid = f + np.arange(-20, 21) * 1e-7
        mag = [abs(np.sum(w * xd * np.exp(-2j * np.pi * g * idx / FS))) for g in grid]
        assert abs(grid[int(np.argmax(mag))] - f) <= 1e-6


def test_a_column_without_a_line_raises_as_peak_frequency():
    n = 323
    x = _records(n, 6)
    x[:, 1] = np.random.default_rng(7).standard_normal(n)  # white noise only
    with pytest.raises(ProcessingError) as batch:
        peak_frequencies(x, FS)
    with pytest.raises(ProcessingError) as single:
        peak_frequency(np.ascontiguousarray(x[:, 1]), FS)
    assert str(batch.value) == str(single.value)


def test_one_dimensional_input_is_refused():
    with pytest.raises(ValueError, match=r"\(n, k\)"):
        peak_frequencies(np.ones(10), FS)


def test_band_magnitudes_are_the_ffts():
    # Goertzel's recurrence over the bins the checks read against numpy's FFT: the same
    # magnitudes to rounding (measured <= 7e-13 of the largest on 300 records with a DC
    # offset), so the same bins chosen
    from torquemod.dsp import spectrum
    rng = np.random.default_rng(7)
    for n, fs in ((323, 53.344), (160, 53.344), (700, 40.0)):
        nfft = 1 << (8 * n - 1).bit_length()
        k_lo, k_hi = spectrum._bins_read(nfft, fs, 1.5, 2.5, n)
        x = np.sin(2 * np.pi * 2.01 * np.arange(n) / fs) + 0.3 * rng.standard_normal(n)
        got = np.zeros(nfft // 2 + 1)
        spectrum._band_magnitudes(x, nfft, k_lo, k_hi, got)
        ref = np.abs(np.fft.rfft(x, nfft))
        np.testing.assert_allclose(got[k_lo:k_hi + 1], ref[k_lo:k_hi + 1], rtol=0,
                                   atol=1e-11 * ref.max())
        _, idx, wide = spectrum._grid(nfft, fs, 1.5, 2.5, n)
        assert k_lo <= min(idx[0], np.flatnonzero(wide)[0])
        assert k_hi >= max(idx[-1], np.flatnonzero(wide)[-1])


@pytest.mark.parametrize("seed", range(6))
def test_bin_checks_are_the_line_search_of_the_full_spectrum(seed):
    # the checks on the bins read only (zeros elsewhere) against _line_search on the
    # whole FFT spectrum: the same bins and the same floor, bit for bit
    from torquemod.dsp import peakkernels, spectrum
    rng = np.random.default_rng(seed)
    n = int(rng.integers(150, 700))
    nfft = 1 << (8 * n - 1).bit_length()
    lo, hi = 1.5, float(rng.uniform(2.0, 3.0))
    freqs, idx, wide = spectrum._grid(nfft, FS, lo, hi, n)
    k_lo, k_hi = spectrum._bins_read(nfft, FS, lo, hi, n)
    x = _records(n, seed)[:, seed % 3] * np.hanning(n)
    spec = np.abs(np.fft.rfft(x, nfft))
    if seed % 2:
        spec = np.round(spec, 1)  # ties: the first maximum wins in both
    read = np.zeros_like(spec)
    read[k_lo:k_hi + 1] = spec[k_lo:k_hi + 1]
    wide_bins = np.flatnonzero(wide)
    got = peakkernels._bin_checks(spec[k_lo:k_hi + 1].copy(), k_lo, freqs,
                                  (int(idx[0]), int(idx[-1])),
                                  (int(wide_bins[0]), int(wide_bins[-1])), 2.0 * FS / n)
    ref = spectrum._line_search(read, freqs, idx, wide, 2.0 * FS / n)
    assert got[:2] == ref[:2] and got[2] == ref[2]


def test_median_is_numpys():
    from torquemod.dsp import peakkernels
    rng = np.random.default_rng(3)
    for m in [1, 2, 3, 4, 7, 8, 100, 229, 230]:
        for v in (rng.standard_normal(m), np.round(rng.standard_normal(m), 0)):  # ties
            assert peakkernels._median(v.copy()) == np.median(v)
