"""Step 8's creepage fit in one compiled call (torquemod.processing.creepage) against the
numpy route step by step."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Rig
from torquemod.processing import chain, creepage
from torquemod.testing import SyntheticSpec, synthetic_recording


def _model(spec: SyntheticSpec):
    cfg = ProcessingConfig()
    sig = chain.process_cycle(synthetic_recording(spec), Rig(0.0675, 2.0), cfg, where="t")
    return sig.extra["speed_model"], sig.fs_hz, cfg


@pytest.mark.parametrize("spec", [SyntheticSpec(seed=3),
                                  SyntheticSpec(seed=5, speed_wobble=(), speed_wobble_rev=()),
                                  SyntheticSpec(seed=7, acceleration_m_s2=0.05),
                                  SyntheticSpec(seed=8, n_revolutions=2.0),
                                  SyntheticSpec(seed=9, creepage_rate_per_s=2e-4)],
                         ids=["default", "no-wobble", "ramp", "two-revolutions", "slip"])
def test_compiled_creepage_equals_the_numpy_route(spec):
    model, fs, cfg = _model(spec)
    kw = dict(wheel_radius_m=0.0675, platform_radius_m=2.0,
              platform_harmonics=cfg.notch.platform_harmonics)
    xi, drift = creepage.creepage_and_drift(model, fs, **kw)
    xi_ref, drift_ref = creepage.creepage_and_drift_reference(model, fs, **kw)
    # the normal matrix by another BLAS product: c0 moves by ~1e-16 relative and xi = 1/c0 - 1
    # (~2e-3) by ~500 times that, measured up to 1.1e-13; bound 1e-11. The drift is ~1e-5
    # of the creepage's scale: measured up to 1.8e-11 relative, bound 1e-9.
    assert xi == pytest.approx(xi_ref, rel=1e-11)
    assert drift == pytest.approx(drift_ref, rel=1e-9, abs=1e-18)
    assert xi == pytest.approx(spec.creepage, abs=2e-5)  # and it measures the creepage


def test_a_standing_wheel_gives_nan_on_both_routes():
    model, fs, cfg = _model(SyntheticSpec(seed=3))
    standing = dataclasses.replace(model)  # a fresh cache of parts, the wheel's set to 0
    standing._parts[("wheel_speed_rad_s", "slow")] = np.zeros(model.design.shape[0])
    kw = dict(wheel_radius_m=0.0675, platform_radius_m=2.0,
              platform_harmonics=cfg.notch.platform_harmonics)
    for fn in (creepage.creepage_and_drift, creepage.creepage_and_drift_reference):
        assert all(np.isnan(v) for v in fn(standing, fs, **kw))
