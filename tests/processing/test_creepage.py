"""Step 8's creepage fit in one compiled call (torquemod.processing.creepage) against the
numpy route step by step, and the compiled least squares it uses
(torquemod.dsp.lstsq.lstsq_compiled) against the SVD."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from torquemod.dsp.lstsq import lapack_addresses, lstsq, lstsq_compiled
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Rig
from torquemod.processing import chain, creepage
from torquemod.testing import SyntheticSpec, synthetic_recording


@pytest.mark.parametrize("n,m,seed", [(323, 2, 0), (323, 8, 1), (690, 12, 2)])
def test_lstsq_compiled_against_the_svd(n, m, seed):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 53.344
    d = np.column_stack([np.ones(n), t, *[np.cos((k + 1) * t + k) for k in range(m - 2)]])
    y = d @ rng.standard_normal(m) + 1e-3 * rng.standard_normal(n)
    coef, status = lstsq_compiled(d, y, *lapack_addresses())
    assert status == 0
    ref = np.linalg.lstsq(d, y, rcond=None)[0]
    # condition numbers here ~1e2-1e3: both agree to ~1e-13 relative; bound 1e-10
    np.testing.assert_allclose(coef, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
    np.testing.assert_allclose(coef, lstsq(d, y)[0], rtol=1e-12, atol=0)


def test_lstsq_compiled_reports_what_needs_the_svd():
    n = 100
    d = np.column_stack([np.ones(n), np.arange(n), np.zeros(n)])  # a zero column
    assert lstsq_compiled(d, np.ones(n), *lapack_addresses())[1] == 1
    d = np.column_stack([np.ones(n), np.arange(n), np.arange(n) + 1e-9])  # collinear
    assert lstsq_compiled(d, np.ones(n), *lapack_addresses())[1] in (2, 3)


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
