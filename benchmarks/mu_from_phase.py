"""Accuracy and honesty of mu from the phase (issue 8) against the highest utilisation
measured.

Each trial: six torque steps at V-Track's proportions up to the utilisation u_max on a Polach
curve (mu drawn in 0.15-0.40), phases by the rigid-wheel law tan(phi) = C/k(CoA) with
V-Track's 8 N*m creepage swing (describing-function slope) plus Gaussian phase noise of the
chain's per-step standard error, CoA exact. Fitted with C known (the rig's inertia) and with
C fitted (no inertia given), both with the measured creepage swing as the chain passes it.
Prints per shape, u_max and case: the median and 90th percentile of |mu error| over the
trials where mu is determined, the fraction determined, and the coverage: the 95 % interval
contains the truth (determined trials) or
the lower bound does not exceed it (undetermined ones).

    python benchmarks/mu_from_phase.py [--trials 20] [--noise-deg 0.1]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from torquemod.analysis.phasefit import fit_mu_from_phase
from torquemod.testing import synthetic_phase_progression

C = 10.2
SHAPES = {"dry (kA/kS = 2.5)": (2.5, 60.0), "wet (kA/kS = 3)": (3.0, 40.0),
          "kA ~ kS": (1.1, 80.0)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--noise-deg", type=float, default=0.1)
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    print(f"{args.trials} trials per row, phase noise {args.noise_deg} deg per step")
    print("| shape | u_max | C | median err | p90 err | determined | 95 % coverage | s/fit |")
    print("|---|---|---|---|---|---|---|---|")
    for shape, (r, k_scale) in SHAPES.items():
        for u_max in (0.86, 0.80, 0.70, 0.60):
            for known in (True, False):
                errs, det, cover = [], 0, 0
                t0 = time.perf_counter()
                for _ in range(args.trials):
                    mu = float(rng.uniform(0.15, 0.40))
                    coa, phase, sw = synthetic_phase_progression(mu, r, k_scale, u_max,
                                                                 constant=C, swing=True)
                    phase = phase + args.noise_deg * rng.standard_normal(phase.size)
                    fit = fit_mu_from_phase(coa, phase, np.full(phase.size, args.noise_deg),
                                            constant=C if known else None,
                                            creepage_swing=sw)
                    lo, hi = fit.mu_interval_95
                    if fit.mu_determined:
                        det += 1
                        errs.append(100 * abs(fit.mu / mu - 1))
                        cover += lo <= mu <= hi
                    else:
                        cover += lo <= mu
                dt = (time.perf_counter() - t0) / args.trials
                med = f"{np.median(errs):.2f} %" if errs else "-"
                p90 = f"{np.percentile(errs, 90):.2f} %" if errs else "-"
                print(f"| {shape} | {u_max:.0%} | {'known' if known else 'fitted'} | {med} | "
                      f"{p90} | {det}/{args.trials} | {cover}/{args.trials} | {dt:.2f} |")


if __name__ == "__main__":
    main()
