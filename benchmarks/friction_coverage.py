"""Coverage of the available adhesion's 95 % interval on laws made apart from the estimator
(benchmarks/_independent_laws.py): prints tables, asserts nothing.

For every law x deepest utilisation x noise x (rig, train): the share of records whose
stated range holds the truth (the 95 % interval when closed, else from the lower bound up),
the share determined, the median and worst |error| of the estimate where determined. Rig:
six steps at V-Track's proportions, phases ``tan(phi) = C/k`` with the 8 N*m modulation's
creepage swing (describing function), C given (``--rig-c unknown``: C not given, the rig
without forces and inertia; ``--rig-c measured``: C as measured from the amplitudes without
an inertia, drawn with a relative error of ``MODEL_REL_CONSTANT`` (2 %) about the truth and
stated with that standard error). Train: creep coefficients at four staircase levels, three
points each.

The fits do not depend on the "determined" rule (closed and half width <= a fraction of
the estimate), so every record is fitted once and the rule is applied afterwards at several
fractions: the second table is the trade-off between the share determined, the error and
the coverage of what is reported as determined, per law over the 80-95 % cells. Polach's
constant-friction law is split by kA/kS: below 1 (kA < kS, the curve overshoots its
friction and peaks inside) and from 1 up (Polach's published sets, kS <= kA).

Records are fitted in ``--workers`` processes (concurrent.futures); the raw results can be
kept (``--save file.npz``) and tabulated again without fitting (``--load``).

    python benchmarks/friction_coverage.py [--trials 200 40] [--laws ...] [--modes rig train]
        [--depths 0.95 0.9 0.86 0.8 0.7 0.6] [--noise 0 1 3] [--workers 2] [--save f.npz]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
import zlib
from concurrent.futures import ProcessPoolExecutor

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
import _independent_laws as laws

#: the fractions of the estimate tried as the widest half interval that counts as determined
THRESHOLDS = (0.05, 0.075, 0.10, 0.125, 0.15, 0.20)
FIELDS = ("P", "estimate", "low", "high", "lower_bound", "closed", "r")


def fit_record(r: dict, mode: str, rig_c: str, ratio_max: float = 7.0, knee: bool = True):
    """The fit of one record (None when it fits nothing); ``ratio_max``: the largest kA/kS
    of the family's Polach members (a shape prior; 7 is the estimator's default)."""
    from torquemod.analysis.friction import (
        fit_available_adhesion,
        fit_available_adhesion_from_phase,
    )
    bounds = (0.3, ratio_max)
    if mode == "train":
        return fit_available_adhesion(r["coa"], r["y"], r["se"], probe=False,
                                      speed_m_s=r["speed_m_s"], ratio_bounds=bounds,
                                      knee=knee)
    c, c_rel = (r["constant"] if rig_c in ("given", "measured") else None), 0.0
    if rig_c == "measured":
        from torquemod.analysis.phasefit import MODEL_REL_CONSTANT
        c_rel = MODEL_REL_CONSTANT
        c = c * (1.0 + c_rel * r["c_draw"])
    return fit_available_adhesion_from_phase(
        r["coa"], r["y"], r["se"], constant=c, constant_rel_se=c_rel,
        creepage_swing=r["swing"], probe=False, speed_m_s=r["speed_m_s"],
        ratio_bounds=bounds, knee=knee)


def run_cell(task: tuple) -> tuple:
    """Fit ``trials`` records of one cell: (task, (n, 7) array of FIELDS, skipped)."""
    law, mode, depth, noise, trials, rig_c, ratio_max, knee = task
    seed = zlib.crc32(repr((mode, law, depth, noise)).encode())
    rng, rng_c = np.random.default_rng(seed), np.random.default_rng([seed, 1])
    rows, skipped = [], 0
    for _ in range(trials):
        r = laws.record(law, rng, depth, mode=mode, noise=noise)
        if r is not None:  # its own stream: the records are those of the other --rig-c
            r["c_draw"] = rng_c.standard_normal()
        f = None if r is None else fit_record(r, mode, rig_c, ratio_max, knee)
        if f is None:
            skipped += 1
            continue
        ratio = float(r["desc"].split()[0][2:]) if r["desc"].startswith("r=") else math.nan
        rows.append((r["P"], f.estimate, f.low, f.high, f.lower_bound, float(f.closed),
                     ratio))
    return task, np.array(rows, dtype=float).reshape(-1, len(FIELDS)), skipped


def judge(a: np.ndarray, thr: float) -> dict:
    """Coverage, determined share and errors of the rows ``a`` (FIELDS) under the rule
    'closed and half width <= thr x estimate'."""
    p, est, low, high, lb, closed = (a[:, i] for i in range(6))
    closed = closed > 0
    top = np.where(closed, high, np.inf)
    tol = 1e-9 * p
    covered = (lb <= p + tol) & (p <= top + tol)
    det = closed & (0.5 * (high - low) <= thr * est)
    err = np.abs(est[det] / p[det] - 1.0)
    return {"n": p.size, "cov": covered.mean() if p.size else math.nan,
            "det": det.mean() if p.size else math.nan,
            "cov_det": covered[det].mean() if det.any() else math.nan,
            "med": np.median(err) if err.size else math.nan,
            "p90": np.percentile(err, 90) if err.size else math.nan,
            "worst": err.max() if err.size else math.nan,
            "within5": (err <= 0.05).mean() if err.size else math.nan}


def _pct(x: float, d: int = 1) -> str:
    return "-" if not math.isfinite(x) else f"{100 * x:.{d}f}%"


def _groups(law: str, a: np.ndarray) -> list[tuple[str, np.ndarray]]:
    if law != "polach":
        return [(law, a)]
    return [("polach r<1", a[a[:, 6] < 1.0]), ("polach r>=1", a[a[:, 6] >= 1.0])]


def tabulate(results: dict, thr: float) -> None:
    """The cell table (markdown) and the trade-off table."""
    print(f"\n### Cells (determined = closed and half width <= {thr:g} x estimate)\n")
    print("| mode | law | depth | noise | n | coverage | determined | median err | worst err |")
    print("|---|---|---|---|---|---|---|---|---|")
    worst = (2.0, "")
    for (law, mode, depth, noise), a in sorted(results.items(),
                                               key=lambda kv: (kv[0][1], kv[0][0],
                                                               -kv[0][2], kv[0][3])):
        if not a.size:
            continue
        j = judge(a, thr)
        if j["cov"] < worst[0]:
            worst = (j["cov"], f"{mode} {law} {depth:g} noise {noise:g} (n = {j['n']})")
        flag = " **<90%**" if j["cov"] < 0.9 else ""
        print(f"| {mode} | {law} | {depth:.2f} | {noise:g} | {j['n']} | {_pct(j['cov'])}{flag} "
              f"| {_pct(j['det'])} | {_pct(j['med'], 2)} | {_pct(j['worst'], 2)} |")
    print(f"\nlowest coverage of any cell: {_pct(worst[0])} ({worst[1]})")
    print("\n### Trade-off over the 80-95 % cells, every noise level run: determined share / "
          "coverage where determined / median, 90th percentile and worst error where "
          "determined / share of those within 5 %\n")
    modes = sorted({k[1] for k in results})
    laws_ = [name for name in laws.LAWS if any(k[0] == name for k in results)]
    print("| mode | law | n | coverage | " + " | ".join(f"{t:g}" for t in THRESHOLDS) + " |")
    print("|---|---|---|---|" + "---|" * len(THRESHOLDS))
    for mode in modes:
        for law in laws_:
            a = [v for k, v in results.items() if k[0] == law and k[1] == mode and k[2] >= 0.8]
            if not a:
                continue
            for name, g in _groups(law, np.concatenate(a)):
                if not g.size:
                    continue
                cells = []
                for t in THRESHOLDS:
                    j = judge(g, t)
                    cells.append(f"{_pct(j['det'], 0)} / {_pct(j['cov_det'], 0)} / "
                                 f"{_pct(j['med'], 1)}, {_pct(j['p90'], 1)}, "
                                 f"{_pct(j['worst'], 1)} / {_pct(j['within5'], 0)}")
                j = judge(g, thr)
                print(f"| {mode} | {name} | {j['n']} | {_pct(j['cov'])} | "
                      + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, nargs=2, default=[200, 40],
                    help="records per cell at 80-90 %% depth, and elsewhere")
    ap.add_argument("--laws", nargs="+", default=list(laws.LAWS))
    ap.add_argument("--modes", nargs="+", default=["rig", "train"])
    ap.add_argument("--depths", type=float, nargs="+", default=[0.95, 0.9, 0.86, 0.8, 0.7, 0.6])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.0, 1.0, 3.0])
    ap.add_argument("--rig-c", choices=("given", "unknown", "measured"), default="given")
    ap.add_argument("--ratio-max", type=float, default=7.0,
                    help="largest kA/kS of the family's Polach members (default 7)")
    ap.add_argument("--no-knee", dest="knee", action="store_false",
                    help="leave the family's knee members (Dugoff's law) out")
    ap.add_argument("--threshold", type=float, default=None,
                    help="the half width rule of the cell table (default: the estimator's)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--save", default=None, help="keep the raw results (.npz)")
    ap.add_argument("--load", default=None, help="tabulate saved raw results, no fitting")
    args = ap.parse_args()
    from torquemod.analysis.friction import MAX_REL_HALF_WIDTH, MODEL_REL_COA, MODEL_REL_ERROR
    thr = MAX_REL_HALF_WIDTH if args.threshold is None else args.threshold
    t0 = time.perf_counter()
    results: dict = {}
    if args.load:
        with np.load(args.load, allow_pickle=False) as z:
            for key in z.files:
                law, mode, depth, noise = key.split("|")
                results[(law, mode, float(depth), float(noise))] = z[key]
    else:
        tasks = [(law, mode, depth, noise,
                  args.trials[0] if 0.8 <= depth <= 0.9 else args.trials[1], args.rig_c,
                  args.ratio_max, args.knee)
                 for mode in args.modes for law in args.laws for depth in args.depths
                 for noise in args.noise]
        tasks.sort(key=lambda t: -t[4] * (4 if t[1] == "rig" else 1))  # long ones first
        skipped = 0
        with ProcessPoolExecutor(max_workers=args.workers) as pool:
            for k, (task, rows, sk) in enumerate(pool.map(run_cell, tasks, chunksize=1)):
                results[task[:4]] = rows
                skipped += sk
                print(f"\r{k + 1}/{len(tasks)} cells, {time.perf_counter() - t0:.0f} s",
                      end="", file=sys.stderr, flush=True)
        print(file=sys.stderr)
        if args.save:
            np.savez(args.save, **{f"{k[0]}|{k[1]}|{k[2]}|{k[3]}": v
                                   for k, v in results.items()})
        print(f"{skipped} records skipped (the swing-averaged curve cannot reach the depth)")
    print(f"model_rel_error = {MODEL_REL_ERROR}, model_rel_coa = {MODEL_REL_COA}; base "
          f"standard errors {laws.BASE_SE} (rig: deg per step; train: relative); rig C "
          f"{args.rig_c}; Polach members' kA/kS up to {args.ratio_max:g}; knee members "
          f"{'in' if args.knee else 'out'}; coverage counts "
          "the lower bound when the interval is open")
    tabulate(results, thr)
    print(f"\nwall time {time.perf_counter() - t0:.0f} s with {args.workers} workers")


if __name__ == "__main__":
    main()
