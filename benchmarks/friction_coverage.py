"""Coverage of the available adhesion's 95 % interval on laws made apart from the estimator
(benchmarks/_independent_laws.py): prints a table, asserts nothing.

For every law x deepest utilisation x noise x (rig, train): the share of records whose
interval holds the truth (where P is not determined, the stated range: from the lower bound
to the upper end when closed, else open), the share determined, the median and worst
|error| of the estimate where determined, and the median probe depth that would determine
it where not. Rig: six steps at V-Track's proportions, phases ``tan(phi) = C/k`` with the
8 N*m modulation's creepage swing (describing function), C given. Train: creep coefficients
at four staircase levels, three points each.

    python benchmarks/friction_coverage.py [--trials 200 60] [--laws ...] [--modes rig train]
        [--depths 0.95 0.9 0.86 0.8 0.7 0.6] [--noise 0 1 3] [--model-rel 0.01]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
import zlib

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
import _independent_laws as laws

from torquemod.analysis.friction import (
    MODEL_REL_COA,
    MODEL_REL_ERROR,
    fit_available_adhesion,
    fit_available_adhesion_from_phase,
)


def run_cell(law: str, mode: str, depth: float, noise: float, trials: int, seed: int,
             model_rel: float, probe: bool, model_rel_coa: float = MODEL_REL_COA) -> dict:
    rng = np.random.default_rng(seed)
    cov = det = n = skipped = 0
    errs, depths = [], []
    for _ in range(trials):
        r = laws.record(law, rng, depth, mode=mode, noise=noise)
        if r is None:
            skipped += 1
            continue
        if mode == "train":
            f = fit_available_adhesion(r["coa"], r["y"], r["se"], model_rel_error=model_rel,
                                       model_rel_coa=model_rel_coa, max_rel_half_width=0.10,
                                       probe=probe, speed_m_s=r["speed_m_s"])
        else:
            f = fit_available_adhesion_from_phase(
                r["coa"], r["y"], r["se"], constant=r["constant"], creepage_swing=r["swing"],
                model_rel_error=model_rel, model_rel_coa=model_rel_coa,
                max_rel_half_width=0.10, probe=probe, speed_m_s=r["speed_m_s"])
        if f is None:
            skipped += 1
            continue
        n += 1
        hi = f.high if f.closed else math.inf
        cov += f.lower_bound <= r["P"] * (1 + 1e-9) and r["P"] <= hi * (1 + 1e-9)
        if f.determined:
            det += 1
            errs.append(abs(f.estimate / r["P"] - 1))
        elif math.isfinite(f.probe_depth):
            depths.append(f.probe_depth)
    return {"n": n, "cov": cov, "det": det, "errs": errs, "skipped": skipped,
            "depths": depths}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, nargs=2, default=[200, 60],
                    help="records per cell at 80-90 %% depth, and elsewhere")
    ap.add_argument("--laws", nargs="+", default=list(laws.LAWS))
    ap.add_argument("--modes", nargs="+", default=["rig", "train"])
    ap.add_argument("--depths", type=float, nargs="+", default=[0.95, 0.9, 0.86, 0.8, 0.7, 0.6])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.0, 1.0, 3.0])
    ap.add_argument("--model-rel", type=float, default=MODEL_REL_ERROR)
    ap.add_argument("--model-rel-coa", type=float, default=MODEL_REL_COA)
    ap.add_argument("--probe", action="store_true", help="also find the probe depth needed")
    args = ap.parse_args()
    t0 = time.perf_counter()
    print(f"model_rel_error = {args.model_rel}, model_rel_coa = {args.model_rel_coa}; "
          f"base standard errors {laws.BASE_SE}; "
          "determined = closed and half width <= 10 %")
    print(f"{'mode':>5} {'law':>15} {'depth':>5} {'noise':>5} {'n':>4} {'coverage':>8} "
          f"{'determ.':>7} {'med err':>7} {'worst':>7} {'probe':>6}")
    worst_cov = 1.0
    for mode in args.modes:
        for law in args.laws:
            for depth in args.depths:
                for noise in args.noise:
                    trials = args.trials[0] if 0.8 <= depth <= 0.9 else args.trials[1]
                    seed = zlib.crc32(repr((mode, law, depth, noise)).encode())
                    c = run_cell(law, mode, depth, noise, trials, seed, args.model_rel,
                                 args.probe, args.model_rel_coa)
                    if not c["n"]:
                        continue
                    share = c["cov"] / c["n"]
                    worst_cov = min(worst_cov, share)
                    med = f"{100 * np.median(c['errs']):.2f}%" if c["errs"] else "-"
                    wst = f"{100 * np.max(c['errs']):.2f}%" if c["errs"] else "-"
                    pd_ = f"{np.median(c['depths']):.2f}" if c["depths"] else "-"
                    flag = "  <90%" if share < 0.9 else ""
                    print(f"{mode:>5} {law:>15} {depth:>5.2f} {noise:>5g} {c['n']:>4} "
                          f"{100 * share:>7.1f}% {100 * c['det'] / c['n']:>6.1f}% {med:>7} "
                          f"{wst:>7} {pd_:>6}{flag}", flush=True)
    print(f"lowest coverage of any cell: {100 * worst_cov:.1f} %; "
          f"wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
