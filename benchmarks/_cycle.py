"""The cycle the chain's benchmarks time (``throughput.py --ratio-only``, ``chain_split.py``,
``chain_kernels.py``): one synthetic cycle (seed 3: 107 733 samples x 6 channels at
16 670 Hz), the default configuration with the two-stage decimator, a wheel of 67.5 mm
radius, and the call that runs it through steps 1-8 and the phase."""

from __future__ import annotations

import dataclasses


def benchmark_cycle():
    """``(rig, cfg, rec, run)``: the rig, the configuration, the recording and a function
    that runs the recording through ``process_cycle`` and ``cycle_phase`` once."""
    from torquemod.io.config import ProcessingConfig
    from torquemod.io.experiment import Rig
    from torquemod.processing import chain
    from torquemod.testing import SyntheticSpec, synthetic_recording

    cfg = ProcessingConfig()
    cfg = dataclasses.replace(cfg, resample=dataclasses.replace(cfg.resample,
                                                                method="two_stage"))
    rig, rec = Rig(0.0675, 2.0), synthetic_recording(SyntheticSpec(seed=3))

    def run() -> None:
        sig = chain.process_cycle(rec, rig, cfg, where="bench")
        chain.cycle_phase(sig, cfg, center_index=sig.torque_filtered.size / 2)

    return rig, cfg, rec, run
