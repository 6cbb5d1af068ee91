"""Rotation orders next to the slow band: the step-8 means must not depend on whether an
order that the slow basis already spans is also fitted as an order."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.dsp import filters
from torquemod.processing import chain, speedmodel, trackedorders

FS = 53.344  # the chain's resampled rate for the V-Track recordings [Hz]
N = 262  # one platform revolution at 8.5 km/h after the resampler's edges [samples]
F_MOD = 1.0  # modulation [Hz]
#: the slow band's top: SLOW_GAP_RESOLUTIONS resolutions below the modulation (chain rule)
MAX_HZ = F_MOD - chain.SLOW_GAP_RESOLUTIONS * FS / N


def _cycle(f_rot: float, seed: int) -> dict[str, np.ndarray]:
    """Platform speed [rad/s] of an eccentric encoder (2e-3 and 1e-3 rad, the twin's
    defaults) turning at ``f_rot`` [Hz] with a slow speed-loop wobble, and a load cell's
    normal force [N]: 4200 N with sleeper passing (100 per revolution) and 5 N noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(N) / FS
    w = 2 * np.pi * f_rot * (1 + 2e-3 * np.sin(2 * np.pi * 0.05 * t + 1.0))
    theta = np.cumsum(w) / FS
    plat = w * (1 + 2e-3 * np.cos(theta + 0.7) + 2e-3 * np.cos(2 * theta + 2.1)) \
        + 1e-4 * rng.standard_normal(N)
    fz = 4200.0 + 60.0 * np.sin(100 * theta) + 5.0 * rng.standard_normal(N)
    return {"platform_speed_rad_s": plat, "fz_n": fz}


@pytest.mark.parametrize("offset", [-0.01, 0.003, 0.01, 0.03])
def test_means_stay_put_when_an_order_sits_at_the_slow_bands_top(offset):
    # the platform's first order at the slow band's top (8.5 km/h, 1 Hz on the V-Track:
    # 0.188 Hz against 0.186 Hz); before the order was left to the slow basis, a joint
    # fit with it gave a mean normal force of -1110 N on the twin's 4200 N record
    slow = filters.slow_basis(N, FS, MAX_HZ)
    for seed in range(3):
        ch = _cycle(MAX_HZ * (1 + offset), seed)
        orders, f_rot = trackedorders.tracked_orders(ch["platform_speed_rad_s"], FS, slow, (1, 2),
                                             above_hz=MAX_HZ, avoid_hz=F_MOD,
                                             modulation_hz=F_MOD)
        assert f_rot == pytest.approx(MAX_HZ * (1 + offset), rel=5e-3)
        model = speedmodel.fit_speed_model(ch, FS, F_MOD, slow, orders)
        # 2 N: 7x the noise's standard error of the mean (5 N/sqrt(262)); the sleeper line
        # adds < 0.2 N over a fractional number of its periods
        assert model.mean("fz_n") == pytest.approx(4200.0, abs=2.0)
        # platform speed: the eccentricity's tones over ~0.9 revolution may shift the
        # slow part's mean by up to their amplitude (2e-3 relative) over 2*pi*0.9
        assert model.mean("platform_speed_rad_s") == pytest.approx(
            2 * np.pi * f_rot, rel=1e-3)
        assert np.isfinite(model.noise_depletion())


def test_noise_depletion_of_a_rank_deficient_design_is_that_of_its_span():
    # a design whose fit fell back to the SVD (here a slow column given twice) has no
    # Cholesky factor; the fraction kept depends on the design's span only. 1e-4: the
    # normal-equation route of the full-rank design is ~1.5e-5 relative off an SVD's
    # (SpeedModel.noise_depletion)
    slow = filters.slow_basis(N, FS, MAX_HZ)
    ch = _cycle(0.3, 0)
    full = speedmodel.fit_speed_model(ch, FS, F_MOD, slow, np.empty((N, 0)))
    twice = speedmodel.fit_speed_model(ch, FS, F_MOD, np.column_stack([slow, slow[:, -1]]),
                                  np.empty((N, 0)))
    assert twice.factor is None and full.factor is not None
    assert twice.noise_depletion() == pytest.approx(full.noise_depletion(), rel=1e-4)
