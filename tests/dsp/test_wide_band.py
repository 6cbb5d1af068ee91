"""The slow-band decision from cached bases and pseudo-inverse rows against a refined solve
per fit."""

import numpy as np
import pytest

from torquemod.dsp import basis

FS = 53.344


def _speeds(seed: int, wobble: float) -> tuple[np.ndarray, np.ndarray]:
    """Wheel and platform speeds [rad/s] of a 6 s record: a mean, a wobble at 1 Hz and
    0.3 Hz of relative size ``wobble``, the wheel's modulation at 2 Hz, white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(323) / FS
    move = 1 + wobble * (np.sin(2 * np.pi * 1.0 * t + 0.4) + 0.5 * np.sin(2 * np.pi * 0.3 * t))
    platform = 0.97 * move + 1e-4 * rng.standard_normal(t.size)
    wheel = 28.8 * move + 2e-3 * np.sin(2 * np.pi * 2.0 * t + 0.3) \
        + 2e-3 * rng.standard_normal(t.size)
    return wheel, platform


@pytest.mark.parametrize(("seed", "wobble"), [(0, 0.0), (1, 1e-3), (2, 4e-3)])
def test_maps_give_the_refined_fits_statistics(seed, wobble):
    wheel, platform = _speeds(seed, wobble)
    args = (wheel, platform, FS, 2.0, 0.8, 1.2)
    fast = basis._wide_band_statistics(*args, extra=2, degree=5)
    ref = basis._wide_band_statistics(*args, extra=2, degree=5, maps=False)
    # the two routes differ by the rounding of the maps against that of the refined
    # solves; the risk, a difference of two fits' modulation coefficients, is the more
    # sensitive (measured up to 8e-9 relative on the chain's synthetic cycles)
    np.testing.assert_allclose(fast, ref, rtol=1e-7)
    decide = basis.needs_wide_band(*args, extra=2, degree=5)
    assert decide == (ref[0] > ref[1] and ref[2] > basis.WIDE_BAND_RISK_RAD)
    assert decide == (wobble > 0)  # the 1 Hz wobble above the quiet band needs the wide one


def test_the_compiled_sum_is_numpys():
    # the ratios' mean speeds are numpy's sums (pairwise), bit for bit, at every length
    # the chain meets and beyond the pairwise split (128)
    rng = np.random.default_rng(4)
    for n in [*range(1, 300), 323, 1000, 4099]:
        a = 30.0 + rng.standard_normal(n) * 10.0 ** rng.uniform(-4, 1)
        assert basis._numpy_sum(a, 0, n) == a.sum()


@pytest.mark.parametrize("n", [3, 8, 97])
def test_two_fits_are_the_sums_of_one_sample_at_a_time(n):
    """The wide-band test's fits at each sample, four samples advancing together: each sum
    the products in ascending column order, as one sample at a time in plain Python."""
    rng = np.random.default_rng(n)
    p_q, p_w = 5, 9
    maps_t = rng.standard_normal((n, p_q + p_w + 4))
    proj = rng.standard_normal(p_q + p_w + 4) * 10.0
    got = basis._two_fits(maps_t, proj, p_q, p_w)
    for t in range(n):
        row = maps_t[t].tolist()
        for k, cols in enumerate((range(p_q), range(p_q, p_q + p_w))):
            s = 0.0
            for i in cols:
                s += row[i] * float(proj[i])
            assert got[k, t] == s
