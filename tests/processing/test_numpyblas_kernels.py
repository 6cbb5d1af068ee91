"""The chain's kernels built on numpy's own BLAS (torquemod.dsp.numpyblas) against the
numpy routes they replace, bit for bit: the tracked rotation orders and whole cycles."""

from __future__ import annotations

import numpy as np
import pytest

from torquemod.dsp import numpyblas
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Rig
from torquemod.processing import chain, trackedorders
from torquemod.testing import SyntheticSpec, synthetic_recording

needs_blas = pytest.mark.skipif(numpyblas.addresses() is None,
                                reason="numpy's BLAS exports no CBLAS64 symbols")
SPECS = [SyntheticSpec(seed=5, speed_wobble=(), speed_wobble_rev=()),
         SyntheticSpec(seed=6, speed_wobble=((6e-3, 0.9, 0.1), (3e-3, 1.1, 1.0))),
         SyntheticSpec(seed=7, creepage_rate_per_s=2e-4),
         SyntheticSpec(seed=8, n_revolutions=2.0)]


@needs_blas
@pytest.mark.parametrize("spec", SPECS, ids=["no-wobble", "wobble", "ramp", "two-revolutions"])
def test_cycle_is_the_numpy_routes_bit_for_bit(spec, monkeypatch):
    rec, rig = synthetic_recording(spec), Rig(0.0675, 2.0)
    cfg = ProcessingConfig().with_phase_method("sinefit")
    used = []
    kernel = trackedorders._tracked_orders_compiled

    def spy(*args):
        out = kernel(*args)
        used.append(out[2])
        return out

    monkeypatch.setattr(trackedorders, "_tracked_orders_compiled", spy)

    def run():
        c = chain.process_cycle(rec, rig, cfg, where="t", nominal_hz=2.0)
        return c, chain.cycle_phase(c, cfg, center_index=c.torque_filtered.size / 2)

    fast, (phase, se, _) = run()
    assert used and all(s == 0 for s in used)  # the kernel ran, and decided
    monkeypatch.setattr(numpyblas, "addresses", lambda: None)
    ref, (phase_ref, se_ref, _) = run()
    assert phase == phase_ref
    assert se == se_ref
    assert fast.modulation_hz == ref.modulation_hz
    m, m_ref = fast.extra["speed_model"], ref.extra["speed_model"]
    np.testing.assert_array_equal(m.design, m_ref.design)
    np.testing.assert_array_equal(m.coef, m_ref.coef)
