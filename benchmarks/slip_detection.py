"""False-flag and detection rates of the per-step slip rules on simulated cycles (issue 8).

A step is three V-Track cycles (one platform revolution each, 16 670 Hz, the default synthetic
noise, encoder eccentricity and vibration). Without slip, every cycle carries a random slow
speed wobble (0.1-0.5 % RMS, two terms in 0.1-1.2 Hz), revolution harmonics and a random ramp
within +-0.05 m/s^2; the wheel follows the platform, so the creepage only follows the speed.
The cycles of a step share the creepage, torque and modulation response. With slip,
the last cycle's creepage runs away linearly by ``rise`` over the cycle while the creep force
falls 5 %. Prints the fraction of steps flagged (``steptable.detect_slip``).

    python benchmarks/slip_detection.py [--steps 100]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Rig
from torquemod.processing import chain
from torquemod.processing.steptable import detect_slip
from torquemod.testing import SyntheticSpec, synthetic_recording

#: creepage runaways over one cycle [-]
RISES = (2e-3, 5e-3, 1e-2, 2e-2)


def random_spec(rng: np.random.Generator, seed: int, step: dict) -> SyntheticSpec:
    rms = rng.uniform(1e-3, 5e-3)
    wobble = tuple((rms * float(rng.uniform(0.5, 1.0)), float(rng.uniform(0.1, 1.2)),
                    float(rng.uniform(0, 2 * np.pi))) for _ in range(2))
    rev = ((float(rng.uniform(0, 3e-3)), float(rng.uniform(0, 6.3))),
           (float(rng.uniform(0, 2e-3)), float(rng.uniform(0, 6.3))))
    return SyntheticSpec(speed_wobble=wobble, speed_wobble_rev=rev,
                         acceleration_m_s2=float(rng.uniform(-0.05, 0.05)),
                         modulation_phase_rad=float(rng.uniform(0, 6.3)), seed=seed, **step)


def cycle(spec: SyntheticSpec, cfg: ProcessingConfig) -> chain.CycleSignals:
    return chain.process_cycle(synthetic_recording(spec), Rig(spec.wheel_radius_m, 2.0), cfg,
                               where="bench", nominal_hz=2.0, normal_load_n=4200.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--steps", type=int, default=100)
    args = ap.parse_args()
    cfg = ProcessingConfig()
    rng = np.random.default_rng(2026)
    t0 = time.perf_counter()
    rows = {"no slip": 0, **{f"rise {r:.0e}": 0 for r in RISES}}
    worst_drift = 0.0
    for k in range(args.steps):
        step = {"creepage": float(rng.uniform(1e-3, 1e-2)),
                "dc_torque_nm": float(rng.uniform(5, 60)),
                "wheel_mod_amplitude_rad_s": float(rng.uniform(0.03, 0.12))}
        specs = [random_spec(rng, 1000 * k + j, step) for j in range(3)]
        sigs = [cycle(s, cfg) for s in specs]
        worst_drift = max(worst_drift, *(abs(s.creepage_drift) for s in sigs))
        flags = detect_slip([s.creepage for s in sigs], [s.coa for s in sigs],
                            [s.creepage_drift for s in sigs], cfg.slip)
        rows["no slip"] += any(flags)
        for rise in RISES:
            slip = dataclasses.replace(specs[2], creepage_rate_per_s=rise / 6.46,
                                       slip_force_drop=0.05)
            s3 = cycle(slip, cfg)
            flags = detect_slip([sigs[0].creepage, sigs[1].creepage, s3.creepage],
                                [sigs[0].coa, sigs[1].coa, s3.coa],
                                [sigs[0].creepage_drift, sigs[1].creepage_drift,
                                 s3.creepage_drift], cfg.slip)
            rows[f"rise {rise:.0e}"] += bool(flags[2])
    print(f"{args.steps} steps of 3 cycles each ({time.perf_counter() - t0:.0f} s); "
          f"drift threshold {cfg.slip.within_cycle_abs:g}")
    print(f"largest |creepage drift| without slip: {worst_drift:.2e}")
    print("| case | steps flagged |")
    print("|---|---|")
    for name, count in rows.items():
        print(f"| {name} | {count}/{args.steps} ({100 * count / args.steps:.1f} %) |")


if __name__ == "__main__":
    main()
