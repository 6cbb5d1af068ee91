"""The available-adhesion fit on calls captured from a sweep: CPU per fit, and equality.

Three steps, each a separate run (so that two checkouts can be compared on the same calls):

* ``--capture FILE``: evaluates every ``--every``-th point of a sweep (default: the example
  V-Track sweep) and pickles the arguments of each top-level call of
  ``torquemod.analysis.friction.fit_available_adhesion`` (analyze's and the sweep's own fits;
  the probe's refits are inside their caller);
* ``--time FILE``: runs the captured calls ``--repeat`` times with the checkout on
  ``PYTHONPATH`` (after one warm-up pass) and prints the CPU per fit; ``--src OTHER/src``
  alternates with another checkout in fresh processes (e.g. the main branch) and prints
  the ratio;
* ``--results FILE --out OUT``: runs the calls once and pickles every field of every fit
  and every grid the kernel returned (``_coarse_to_fine``'s evaluated columns, chi2,
  amplitudes, mixing fractions); ``--compare OUT_A OUT_B`` prints the largest difference
  of each field between two such files (0 means bit for bit: NaN equals NaN);
* ``--generate FILE [--n 300]``: pickles varied calls made up here (progressions of several
  saturating shapes written in this file, noise, number of steps, with and without C, swing
  and CoA errors, the probe on and off; k0 profiled where a swing comes without C);
* ``--compare-src OTHER/src FILE...``: for each calls file, the results with this checkout
  and with ``OTHER/src`` (fresh processes) and their largest differences, then the CPU per
  fit of both, alternated in the same run, and the ratio.

    python benchmarks/adhesion_fit.py --capture /tmp/calls.pkl [--every 5 | --first 6]
    python benchmarks/adhesion_fit.py --generate /tmp/gen.pkl [--n 300]
    python benchmarks/adhesion_fit.py --compare-src /work/main/src /tmp/calls.pkl /tmp/gen.pkl
    python benchmarks/adhesion_fit.py --time /tmp/calls.pkl [--src /work/main/src] [--repeat 2]
    python benchmarks/adhesion_fit.py --results /tmp/calls.pkl --out /tmp/a.pkl
    python benchmarks/adhesion_fit.py --compare /tmp/a.pkl /tmp/b.pkl
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parents[1]


def capture(sweep: str, every: int, out: str, first: int = 0) -> None:
    """Pickle the top-level calls of fit_available_adhesion made by every ``every``-th point
    (or by the ``first`` points when given)."""
    import torquemod.analysis.friction as friction
    from torquemod.sweep import evaluate as ev
    from torquemod.sweep.evaluate import tasks
    from torquemod.sweep.spec import load_sweep

    real = friction.fit_available_adhesion
    calls: list = []
    depth = [0]

    def wrapped(*a, **k):
        if depth[0] == 0:
            calls.append((a, k))
        depth[0] += 1
        try:
            return real(*a, **k)
        finally:
            depth[0] -= 1

    friction.fit_available_adhesion = wrapped
    todo = tasks(load_sweep(sweep))
    todo = todo[:first] if first else todo[::every]
    with tempfile.TemporaryDirectory() as tmp:
        for task in todo:
            ev.evaluate_point(task, workdir=tmp, through_files=False)
    with open(out, "wb") as fh:
        pickle.dump(calls, fh)
    print(f"{len(calls)} calls from {len(todo)} points of {Path(sweep).name} -> {out}")


def _shape(u: np.ndarray, kind: int) -> np.ndarray:
    """k/k0 at utilisation u of a few saturating shapes (not the estimator's tables): the
    square root of 1 - u, an exponential approach, a hyperbola and a flat start with a knee
    (each 1 at u = 0 and 0 at u = 1)."""
    if kind == 0:
        return np.sqrt(1.0 - u)
    if kind == 1:
        return (np.exp(-3.0 * u) - np.exp(-3.0)) / (1.0 - np.exp(-3.0))
    if kind == 2:
        return (1.0 - u) / (1.0 + 2.0 * u)
    return np.where(u < 0.5, 1.0, 1.0 - ((u - 0.5) / 0.5) ** 2)


def generate(out: str, n_calls: int, seed: int = 0) -> None:
    """Pickle ``n_calls`` varied calls of fit_available_adhesion (module docstring)."""
    rng = np.random.default_rng(seed)
    calls = []
    for c in range(n_calls):
        n = int(rng.integers(4, 13))
        p_true = float(rng.uniform(0.1, 0.45))
        top = float(rng.choice([0.5, 0.7, 0.86, 0.95, 0.99]))
        u = np.sort(rng.uniform(0.02, top, n))
        coa = u * p_true
        k0 = float(rng.uniform(20.0, 400.0))
        noise = float(rng.choice([0.0, 0.01, 0.03, 0.1]))
        k = k0 * np.clip(_shape(u, c % 4), 1e-3, None) * (1.0 + noise * rng.normal(size=n))
        k_se = np.full(n, max(noise, 0.005)) * np.abs(k)
        kw: dict = {"probe": bool(rng.random() < 0.5)}
        if rng.random() < 0.5:
            kw["coa_se"] = 0.01 * coa * rng.uniform(0.5, 2.0, n)
        case = c % 10
        if case in (1, 2, 5, 6):  # a swing with C known
            kw["swing"] = rng.uniform(1e-4, 3e-3, n)
            kw["constant"] = float(rng.uniform(0.5, 10.0))
            if rng.random() < 0.5:
                kw["speed_m_s"] = float(rng.uniform(0.5, 30.0))
                kw["constant_rel_se"] = float(rng.choice([0.0, 0.05]))
        elif case == 3:  # a swing without C: k0 profiled (19 grids: without the probe)
            kw["swing"] = rng.uniform(1e-4, 3e-3, n)
            kw["constant"] = None
            kw["probe"] = False
        elif case in (4, 9):
            kw["ratio_bounds"] = (float(rng.uniform(0.3, 2.0)), float(rng.uniform(2.0, 7.0)))
            kw["knee"] = bool(rng.random() < 0.5)
            kw["other_laws"] = bool(rng.random() < 0.7)
            kw["scale_by_chi2"] = bool(rng.random() < 0.7)
        calls.append(((coa, k, k_se), kw))
    with open(out, "wb") as fh:
        pickle.dump(calls, fh)
    print(f"{len(calls)} generated calls -> {out}")


def load(path: str) -> list:
    """The captured calls ``[(args, kwargs), ...]``."""
    with open(path, "rb") as fh:
        return pickle.load(fh)


def time_calls(path: str, repeat: int) -> float:
    """CPU seconds per call, the median of ``repeat`` passes after a warm-up pass."""
    from torquemod.analysis.friction import fit_available_adhesion

    calls = load(path)
    for a, k in calls:
        fit_available_adhesion(*a, **k)
    per = []
    for _ in range(repeat):
        c0 = time.process_time()
        for a, k in calls:
            fit_available_adhesion(*a, **k)
        per.append((time.process_time() - c0) / len(calls))
    return float(np.median(per))


def results(path: str, out: str) -> None:
    """Pickle each call's fit fields and the kernel grids it evaluated."""
    import torquemod.analysis.friction as friction

    real = friction._coarse_to_fine
    grids: list = []

    def wrapped(*a, **k):
        got = real(*a, **k)
        grids.append((np.asarray(got[0]), [np.asarray(o) for o in got[1]]))
        return got

    friction._coarse_to_fine = wrapped
    fits = []
    for a, k in load(path):
        fit = friction.fit_available_adhesion(*a, **k)
        fits.append(None if fit is None else dataclasses.asdict(fit))
    with open(out, "wb") as fh:
        pickle.dump({"fits": fits, "grids": grids}, fh)
    print(f"{len(fits)} fits, {len(grids)} kernel grids -> {out}")


def _diff(a, b) -> float:
    """Largest absolute difference (NaN == NaN, inf == inf; a shape or type change: inf)."""
    if isinstance(a, (str, bool)) or a is None:
        return 0.0 if a == b else np.inf
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        return np.inf
    same = (a == b) | (np.isnan(a) & np.isnan(b))
    if same.all():
        return 0.0
    with np.errstate(invalid="ignore"):
        d = np.abs(a - b)[~same]
    return float(np.nanmax(np.where(np.isfinite(d), d, np.inf)))


def compare(path_a: str, path_b: str) -> None:
    """Print the largest difference of every fit field and kernel grid."""
    with open(path_a, "rb") as fh:
        ra = pickle.load(fh)
    with open(path_b, "rb") as fh:
        rb = pickle.load(fh)
    worst: dict[str, float] = {}
    if len(ra["fits"]) != len(rb["fits"]):
        print(f"different numbers of fits: {len(ra['fits'])} vs {len(rb['fits'])}")
        return
    for fa, fb in zip(ra["fits"], rb["fits"], strict=True):
        if (fa is None) != (fb is None):
            worst["fit is None"] = np.inf
            continue
        for key in fa or {}:
            worst[key] = max(worst.get(key, 0.0), _diff(fa[key], fb[key]))
    ga, gb = ra["grids"], rb["grids"]
    worst["kernel calls (count differs: inf)"] = 0.0 if len(ga) == len(gb) else np.inf
    for (ca, oa), (cb, ob) in zip(ga, gb, strict=False):
        worst["kernel: evaluated columns"] = max(worst.get("kernel: evaluated columns", 0.0),
                                                 _diff(ca, cb))
        for name, x, y in zip(("chi2", "amplitude", "mixing fraction"), oa, ob, strict=True):
            key = f"kernel: {name}"
            worst[key] = max(worst.get(key, 0.0), _diff(x, y))
    print(f"{len(ra['fits'])} fits, {len(ga)} kernel grids; largest difference per field "
          "(0: bit for bit):")
    for key, v in worst.items():
        print(f"  {key:>34s}: {v:.3g}")


def compare_src(other: str, paths: list[str], repeat: int, rounds: int) -> None:
    """Results and CPU per fit of this checkout against ``other`` (another checkout's src) on
    each calls file, in fresh processes of the same run."""
    srcs = {"other": other, "this": str(HERE / "src")}
    with tempfile.TemporaryDirectory() as tmp:
        for path in paths:
            outs = {}
            for label, src in srcs.items():
                outs[label] = str(Path(tmp) / f"{label}.pkl")
                subprocess.run([sys.executable, __file__, "--results", path, "--out",
                                outs[label]], env={**os.environ, "PYTHONPATH": src},
                               capture_output=True, text=True, check=True)
            print(f"{Path(path).name}: this checkout against {other}")
            compare(outs["other"], outs["this"])
    for path in paths:
        got: dict[str, list[float]] = {k: [] for k in srcs}
        for _ in range(rounds):
            for label, src in srcs.items():
                done = subprocess.run(
                    [sys.executable, __file__, "--time", path, "--repeat", str(repeat),
                     "--child"], env={**os.environ, "PYTHONPATH": src},
                    capture_output=True, text=True, check=True)
                got[label].append(float(done.stdout.split()[-1]))
        b, a = float(np.median(got["other"])), float(np.median(got["this"]))
        print(f"{Path(path).name}: {len(load(path))} calls, CPU per fit (median of {rounds} "
              f"alternated rounds): other {b:.4f} s, this {a:.4f} s -> x{b / a:.2f} "
              f"(load {os.getloadavg()[0]:.2f})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--capture")
    ap.add_argument("--every", type=int, default=5)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--generate")
    ap.add_argument("--n", type=int, default=300)
    ap.add_argument("--compare-src", nargs="+", metavar=("OTHER_SRC", "FILE"))
    ap.add_argument("--sweep", default=str(HERE / "examples" / "sweep_vtrack_conditions.toml"))
    ap.add_argument("--time")
    ap.add_argument("--src", default=None)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--results")
    ap.add_argument("--out")
    ap.add_argument("--compare", nargs=2)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.capture:
        capture(args.sweep, args.every, args.capture, args.first)
    elif args.generate:
        generate(args.generate, args.n)
    elif args.compare_src:
        if len(args.compare_src) < 2:
            ap.error("--compare-src OTHER/src FILE [FILE...]")
        compare_src(args.compare_src[0], args.compare_src[1:], args.repeat, args.rounds)
    elif args.results:
        results(args.results, args.out)
    elif args.compare:
        compare(*args.compare)
    elif args.time and args.child:
        print(f"{time_calls(args.time, args.repeat):.6f}")
    elif args.time:
        srcs = ({"before": args.src} if args.src else {}) | {"after": str(HERE / "src")}
        got: dict[str, list[float]] = {k: [] for k in srcs}
        n = len(load(args.time))
        for r in range(args.rounds):
            for label, src in srcs.items():
                load0 = os.getloadavg()[0]
                done = subprocess.run(
                    [sys.executable, __file__, "--time", args.time, "--repeat",
                     str(args.repeat), "--child"], env={**os.environ, "PYTHONPATH": src},
                    capture_output=True, text=True, check=True)
                cpu = float(done.stdout.split()[-1])
                got[label].append(cpu)
                print(f"round {r + 1} {label:>6s} ({src}): {cpu:.4f} CPU-s per fit over {n} "
                      f"calls, load {load0:.2f} -> {os.getloadavg()[0]:.2f}", flush=True)
        if "before" in got:
            b, a = float(np.median(got["before"])), float(np.median(got["after"]))
            print(f"median: before {b:.4f}, after {a:.4f} CPU-s per fit -> x{b / a:.2f}")
    else:
        ap.error("one of --capture, --generate, --time, --results, --compare, --compare-src")


if __name__ == "__main__":
    main()
