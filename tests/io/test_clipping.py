"""A clipped sensor gets a warning naming file and channel; live signals get none."""

from __future__ import annotations

import numpy as np

from torquemod.io.experiment import Recording
from torquemod.io.validate import clipping_notes


def _rec(torque):
    n = torque.size
    rng = np.random.default_rng(0)
    return Recording({"torque_nm": torque,
                      "wheel_speed_rad_s": 28.8 + 0.01 * rng.standard_normal(n)}, 10_000.0)


def test_clipped_torque_is_named_and_live_signals_are_not():
    t = np.arange(60_000) / 10_000.0
    rng = np.random.default_rng(1)
    torque = 40.0 + 8.0 * np.sin(2 * np.pi * 2.0 * t) + 0.05 * rng.standard_normal(t.size)
    assert clipping_notes(_rec(torque), path="run.h5") == []
    # 16-bit quantization over +-100 N*m of a noisy signal: still no warning
    q = 200.0 / 2**16
    assert clipping_notes(_rec(np.round(torque / q) * q), path="run.h5") == []
    clipped = np.minimum(torque, 46.0)  # a logger range ending at 46 N*m
    notes = clipping_notes(_rec(clipped), path="run.h5")
    assert len(notes) == 1
    assert "run.h5: channel 'torque_nm' sits at its maximum 46" in notes[0]
    assert "clipped" in notes[0]
