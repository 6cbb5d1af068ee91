"""Step 6 (torquemod.dsp.align): unbiased cross-correlation and the alignment lag.

MATLAB-convention note: ``xcorr(x, y, maxlag, 'unbiased')`` is r[k] = sum_n x[n+k]*y[n] /
(N - |k|), so a ``y`` that is ``x`` delayed by d samples (y[n] = x[n - d]) peaks at k = -d.
For equal lengths M(k) = N - |k| is the number of overlapping terms and the project's function
is MATLAB's. For unequal lengths MATLAB zero-pads the shorter vector to the longer length N and
still divides by N - |k|; the project divides by the true number of overlapping terms (the
brute-force reference below), which differs from MATLAB there.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from torquemod.dsp.align import alignment_lag, unbiased_xcorr

FS = 53.344


def _brute_xcorr(x: np.ndarray, y: np.ndarray, k: int) -> float:
    """sum over every n with both x[n+k] and y[n] defined, divided by how many there are."""
    acc, count = 0.0, 0
    for n in range(y.size):
        if 0 <= n + k < x.size:
            acc += x[n + k] * y[n]
            count += 1
    return acc / count


@pytest.mark.parametrize(("nx", "ny", "max_lag"), [(40, 40, 12), (40, 40, 39), (37, 25, 30),
                                                   (25, 37, 30), (30, 18, 100), (1, 1, 0)])
def test_unbiased_xcorr_equals_brute_force_double_loop(nx, ny, max_lag):
    rng = np.random.default_rng(nx * 100 + ny)
    x, y = rng.standard_normal(nx), rng.standard_normal(ny)
    lags, r = unbiased_xcorr(x, y, max_lag)
    # every lag with at least one overlapping term, |k| <= max_lag, in increasing order
    expected_lags = [k for k in range(-(ny - 1), nx) if abs(k) <= max_lag]
    np.testing.assert_array_equal(lags, expected_lags)
    ref = np.array([_brute_xcorr(x, y, int(k)) for k in lags])
    # sums of <= 40 products of O(1) numbers: rounding ~1e-15; 1e-12 leaves ample room
    np.testing.assert_allclose(r, ref, rtol=0, atol=1e-12)


def test_unbiased_xcorr_is_matlab_for_equal_lengths():
    # FACTS.md §4: correlate(x, y, 'full') / (N - |lag|), lags from correlation_lags
    rng = np.random.default_rng(5)
    x, y = rng.standard_normal(64), rng.standard_normal(64)
    lags, r = unbiased_xcorr(x, y, 20)
    full = signal.correlate(x, y, mode="full")
    all_lags = signal.correlation_lags(64, 64, mode="full")
    keep = np.abs(all_lags) <= 20
    np.testing.assert_allclose(r, full[keep] / (64 - np.abs(all_lags[keep])), atol=1e-12)
    # MATLAB sign: y = x delayed by 3 -> peak of xcorr(x, y) at k = -3
    xx = rng.standard_normal(500)
    lags, r = unbiased_xcorr(xx[10:410], xx[7:407], 10)  # y[n] = x[n - 3]
    assert lags[np.argmax(r)] == -3
    lags, r = unbiased_xcorr(xx[7:407], xx[10:410], 10)  # y[n] = x[n + 3]
    assert lags[np.argmax(r)] == 3


def _band_limited(n: int, seed: int, band_hz: tuple[float, float]) -> np.ndarray:
    rng = np.random.default_rng(seed)
    sos = signal.butter(4, band_hz, "bandpass", fs=FS, output="sos")
    return signal.sosfiltfilt(sos, rng.standard_normal(n + 400))[200:-200]


@pytest.mark.parametrize("shift", [-9, -4, -1, 0, 1, 5, 11])
def test_alignment_lag_recovers_circular_shift(shift):
    ref = _band_limited(347, 1, (0.5, 6.0))
    other = np.roll(ref, shift)  # other[n] = ref[n - shift]
    assert alignment_lag(ref, other, 15) == shift
    # and other[n + k] then lines up with ref[n] on the overlap
    k = alignment_lag(ref, other, 15)
    if k >= 0:
        np.testing.assert_array_equal(other[k:], ref[:ref.size - k])
    else:
        np.testing.assert_array_equal(other[:k], ref[-k:])


@pytest.mark.parametrize("shift", [-13, -6, 2, 8])
def test_alignment_lag_recovers_linear_shift_of_chain_like_signal(shift):
    """Two cycles cut from one long band-passed 2 Hz record (26.7 samples per period): the
    true lag is the difference of the cut positions; max_lag below half a period keeps the
    neighbouring periods' correlation peaks out."""
    long = _band_limited(2000, 2, (1.82, 2.18))
    start = 700
    ref = long[start:start + 347]
    other = long[start - shift:start - shift + 347]  # other[n] = ref[n - shift]
    assert alignment_lag(ref, other, 13) == shift
