"""Statistics of the "no modulation found" decision of spectrum.peak_frequency.

The threshold (peak power >= 20 x the median noise floor) must reject white noise almost
always and accept a modulation line whose phase is still measurable (-25 dB per-sample SNR at
16 670 Hz over one 6.46 s V-Track cycle: Cramér-Rao bound 4.4 deg). Monte Carlo at the
resampled rate (53.344 Hz, 334 samples, noise variance reduced by the 312x decimation).
"""

import numpy as np

from torquemod.dsp.spectrum import peak_frequency
from torquemod.errors import ProcessingError

FS, N = 53.344, 334


def _accepts(x: np.ndarray) -> bool:
    try:
        peak_frequency(x, FS)
    except ProcessingError:
        return False
    return True


def test_white_noise_is_rejected_almost_always():
    rng = np.random.default_rng(7)
    accepted = sum(_accepts(rng.standard_normal(N)) for _ in range(1000))
    # measured 0.27 % in 6000 draws; 1.2 % would be > 5 binomial standard deviations above
    assert accepted <= 12


def test_a_measurable_line_is_always_accepted():
    rng = np.random.default_rng(8)
    t = np.arange(N) / FS
    amp = np.sqrt(2 * 10 ** -2.5 * 312)  # -25 dB per sample at 16 670 Hz, after decimation
    misses = sum(not _accepts(amp * np.cos(2 * np.pi * 2.003 * t + rng.uniform(0, 2 * np.pi))
                              + rng.standard_normal(N)) for _ in range(1000))
    assert misses == 0  # lowest peak-to-floor ratio seen in 7000 draws: 22.7 > 20
