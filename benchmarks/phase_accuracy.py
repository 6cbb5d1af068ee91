"""Monte Carlo accuracy of the two phase estimators against the Cramér-Rao bound.

Each trial is one V-Track cycle (one platform revolution, 6.46 s at 16 670 Hz) of a torque and
a wheel-speed sinusoid with a known lag, random modulation phase, a frequency off nominal by
up to +-4 mHz and white noise of a set per-sample SNR eta = A^2/(2 sigma^2) on both channels.
It runs through the whole per-cycle chain (resample, frequency, notches, filters, phase).
The bound is var(dphi) = (1/N)(1/eta1 + 1/eta2) for the N samples of the record (FACTS.md §5).

    python benchmarks/phase_accuracy.py [--trials 300]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from torquemod.dsp.phase import phase_crb_deg
from torquemod.errors import InputError
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Recording, Rig
from torquemod.processing import chain

FS = 16_670.0
RIG = Rig(0.0675, 2.0)
OMEGA_P = (7 / 3.6) / RIG.platform_radius_m
OMEGA_W = (7 / 3.6) / RIG.wheel_radius_m
N = round(2 * np.pi / OMEGA_P * FS)
LAG_DEG = 25.0


def trial(rng: np.random.Generator, eta: float) -> Recording:
    t = np.arange(N) / FS
    f = 2.0 + rng.uniform(-4e-3, 4e-3)
    ph = rng.uniform(0, 2 * np.pi)
    a_t, a_w = 8.0, 2e-3
    s_t, s_w = a_t / np.sqrt(2 * eta), a_w / np.sqrt(2 * eta)
    ch = {
        "torque_nm": 30 + a_t * np.cos(2 * np.pi * f * t + ph) + s_t * rng.standard_normal(N),
        "wheel_speed_rad_s": OMEGA_W + a_w * np.cos(2 * np.pi * f * t + ph - np.radians(LAG_DEG))
        + s_w * rng.standard_normal(N),
        "platform_speed_rad_s": np.full(N, OMEGA_P),
        "fx_n": np.full(N, 400.0), "fy_n": np.zeros(N), "fz_n": np.full(N, 4200.0),
    }
    return Recording(ch, FS)


def run(method: str, eta: float, trials: int, seed: int, sinefit_input: str
        ) -> tuple[np.ndarray, np.ndarray]:
    cfg = ProcessingConfig().with_phase_method(method)
    cfg = dataclasses.replace(cfg, phase=dataclasses.replace(cfg.phase,
                                                             sinefit_input=sinefit_input))
    rng = np.random.default_rng(seed)
    est, se = [], []
    for _ in range(trials):
        try:
            sig = chain.process_cycle(trial(rng, eta), RIG, cfg, where="benchmark")
        except InputError:  # "no modulation found": counted as a rejected cycle
            est.append(np.nan)
            se.append(np.nan)
            continue
        phase, stderr, _ = chain.cycle_phase(sig, cfg, center_index=sig.torque_filtered.size / 2)
        est.append(phase)
        se.append(stderr)
    return np.asarray(est), np.asarray(se)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=300)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sinefit-input", choices=["bandpassed", "notched", "model"],
                    default=ProcessingConfig().phase.sinefit_input)
    args = ap.parse_args()
    print(f"record: N = {N} samples at {FS:.0f} Hz ({N / FS:.2f} s), lag {LAG_DEG} deg, "
          f"{args.trials} trials per row, sine fit on the {args.sinefit_input} signals")
    print(f"{'eta [dB]':>8} {'CRB [deg]':>10} | {'method':>8} {'bias':>8} {'std':>8} "
          f"{'std/CRB':>8} {'mean se/std':>11} {'ms/cycle':>9} {'no line':>9}")
    for eta_db in (-25.0, -15.0, -5.0, 5.0):
        eta = 10 ** (eta_db / 10)
        crb = phase_crb_deg(1.0, 1.0, 1 / np.sqrt(2 * eta), 1 / np.sqrt(2 * eta), N)
        for method in ("paper", "sinefit"):
            t0 = time.perf_counter()
            est, se = run(method, eta, args.trials, args.seed + int(eta_db * 10) + 1000,
                          args.sinefit_input)
            ms = 1e3 * (time.perf_counter() - t0) / args.trials
            rejected = int(np.isnan(est).sum())
            err = est[np.isfinite(est)] - LAG_DEG
            std = err.std(ddof=1)
            se_ratio = (f"{np.nanmean(se) / std:11.2f}" if np.isfinite(se).any()
                        else f"{'-':>11}")
            print(f"{eta_db:8.1f} {crb:10.4f} | {method:>8} {err.mean():8.4f} {std:8.4f} "
                  f"{std / crb:8.3f} {se_ratio} {ms:9.1f} {rejected:9d}")


if __name__ == "__main__":
    main()
