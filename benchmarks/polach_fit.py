"""The Polach force fit (``torquemod.analysis.fit.fit_polach``, with its profile interval for
mu) replayed on recorded and generated calls: CPU per call of this checkout against another
(``--compare-src OTHER/src``, e.g. the main branch) measured in the same run, and the largest
differences between their results.

The calls:

* ``sweep``: the arguments of every ``fit_polach`` call ``torquemod.api.analyze`` makes while
  the first ``--sweep-points`` points of a sweep are evaluated (default: the example V-Track
  sweep, full mode; recorded in this process with this checkout's chain, which does not
  depend on the fit);
* ``generated``: ``--generated`` calls on synthetic creep points (4 to 16 steps up to 30-100 %
  of mu, CoA noise 0 to 1e-2, with or without standard errors, creepage swing, lateral CoA,
  stiffness; a few velocity-dependent), the curve written here from Polach's formula;
* ``--cases FILE``: more recorded calls (a pickle of ``[(args, kwargs), ...]``, e.g. the
  test suite's, recorded with ``--record-tests FILE``).

Each checkout replays every call once (the results) and then ``--rounds`` times (the CPU;
the generated calls only once, their CPU that of the first replay), in its own process, the
two alternated ``--repeat`` times; the CPU ratio is of the medians.
The results compared: mu, its 68 and 95 % intervals, mu_determined, the lower bound, the
fitted parameters and their standard errors, chi2, the profile (grid and delta chi2), the
covariance, residuals, the starts' costs and the warnings. Each field is reported as
identical (every bit, NaN and None alike) or by its largest relative difference.

    python benchmarks/polach_fit.py --compare-src /work/main/src [--sweep-points 6]
        [--generated 300] [--cases FILE] [--rounds 3] [--repeat 2]
    python benchmarks/polach_fit.py --record-tests FILE   # the tests' calls, for --cases
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parents[1]
FIELDS = ("mu", "mu_interval_95", "mu_interval_68", "mu_determined", "mu_lower_bound",
          "theta", "params", "stderr", "chi2", "reduced_chi2", "mu_estimate",
          "mu_stderr_estimate", "curve_peak_coa", "mu_profile", "covariance", "residuals",
          "weighted_residuals", "sigma", "starts", "warnings", "converged", "nfev")


def record_sweep(sweep: str, n: int) -> list:
    """The ``(args, kwargs)`` of analyze's ``fit_polach`` calls over ``n`` sweep points."""
    import torquemod.analysis.analyzer as analyzer
    from torquemod.sweep.evaluate import evaluate_point, tasks
    from torquemod.sweep.spec import load_sweep
    calls = []
    fn = analyzer.fit_polach

    @functools.wraps(fn)  # the analysis inspects fit_polach's signature
    def recorder(*a, **k):
        calls.append((a, k))
        return fn(*a, **k)
    analyzer.fit_polach = recorder
    try:
        for task in tasks(load_sweep(sweep))[:n]:
            evaluate_point(task)
    finally:
        analyzer.fit_polach = fn
    return calls


def _curve(xi, mu, ka, ks):
    """Polach's lumped curve ``mu*(2/pi)*(A*e/(1 + (A*e)^2) + arctan(S*e))``, e = |xi|/mu."""
    e = np.abs(xi) / mu
    return mu * 2.0 / np.pi * (ka * e / (1.0 + (ka * e) ** 2) + np.arctan(ks * e))


def generated(n: int, seed: int = 2026) -> list:
    """``n`` varied ``(args, kwargs)`` of synthetic creep curves."""
    rng = np.random.default_rng(seed)
    calls = []
    for i in range(n):
        mu = rng.uniform(0.08, 0.6)
        ka, ks = 10 ** rng.uniform(1.0, 3.0), 10 ** rng.uniform(0.3, 2.5)
        steps = int(rng.integers(4, 17))
        top = rng.choice([0.3, 0.5, 0.7, 0.85, 0.95, 1.0])  # of the curve's reach
        grid = np.geomspace(1e-5, 0.1, 4000)
        reach = _curve(grid, mu, ka, ks)
        target = np.linspace(0.1, top, steps) * reach.max()
        xi = np.interp(target, np.maximum.accumulate(reach), grid)
        noise = rng.choice([0.0, 1e-4, 1e-3, 3e-3, 1e-2])
        coa = _curve(xi, mu, ka, ks) + rng.normal(0.0, noise, steps)
        kw: dict = {}
        kind = i % 6
        if kind in (1, 2, 5):
            kw["coa_std"] = np.full(steps, max(noise, 1e-4)) * rng.uniform(0.5, 2.0, steps)
            kw["xi_std"] = xi * rng.uniform(0.0, 0.03, steps)
        if kind in (2, 3, 5):
            swing = np.linspace(3e-4, 5e-3, steps) * rng.uniform(0.5, 1.5)
            kw["creepage_swing"] = swing
        if kind in (3, 4):
            kw["lateral_coa"] = rng.uniform(0.0, 0.03, steps)
        if kind == 4:
            kw["stiffness"] = float(rng.uniform(50.0, 500.0))
        if i % 50 == 7 and steps >= 7:  # a few velocity-dependent fits (finite differences)
            kw["velocity_dependent"] = True
            kw["speeds_m_s"] = np.full(steps, rng.uniform(1.0, 5.0))
        if i % 25 == 3:
            xi = -xi  # braking
        calls.append(((xi, coa), kw))
    return calls


def _summary(fit) -> dict:
    """The compared fields of a PolachFit (plain values)."""
    out = {}
    for name in FIELDS:
        v = getattr(fit, name)
        if name == "starts":
            v = [(s["x0"], s["cost"]) for s in v]
        out[name] = v
    return out


def worker(cases: str, out: str, rounds: int) -> None:
    """Replay the calls in ``cases``: results once, then CPU over ``rounds`` replays."""
    from torquemod.analysis.fit import fit_polach
    from torquemod.errors import TorquemodError
    with open(cases, "rb") as fh:
        calls = pickle.load(fh)
    results = []
    c0 = time.process_time()
    for a, k in calls:
        try:
            results.append(_summary(fit_polach(*a, **k)))
        except TorquemodError as exc:
            results.append({"error": f"{type(exc).__name__}: {exc}"})
    cpu = time.process_time() - c0  # without extra rounds: the first replay's
    if rounds > 0:
        c0 = time.process_time()
        for _ in range(rounds):
            for a, k in calls:
                try:
                    fit_polach(*a, **k)
                except TorquemodError:
                    pass
        cpu = (time.process_time() - c0) / rounds
    with open(out, "wb") as fh:
        pickle.dump({"results": results, "cpu": cpu}, fh)


def _equal(a, b) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and a.tobytes() == b.tobytes()
    if isinstance(a, float) and isinstance(b, float):
        return (a == b and math.copysign(1, a) == math.copysign(1, b)) or (
            math.isnan(a) and math.isnan(b))
    return a == b


def _rel(a, b) -> float:
    """Largest relative difference of two values (inf when their structure differs)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return math.inf
        return max((_rel(a[k], b[k]) for k in a), default=0.0)
    if isinstance(a, list | tuple | np.ndarray) and isinstance(b, list | tuple | np.ndarray):
        if len(a) != len(b):
            return math.inf
        return max((_rel(x, y) for x, y in zip(a, b, strict=True)), default=0.0)
    if a is None or b is None or isinstance(a, str | bool) or isinstance(b, str | bool):
        return 0.0 if a == b else math.inf
    a, b = float(a), float(b)
    if a == b or (math.isnan(a) and math.isnan(b)):
        return 0.0
    return abs(a - b) / max(abs(a), abs(b))


def _run(src: str, cases: str, rounds: int) -> dict:
    with tempfile.NamedTemporaryFile(suffix=".pkl", delete=False) as fh:
        out = fh.name
    try:
        subprocess.run([sys.executable, __file__, "--worker", cases, out,
                        "--rounds", str(rounds)],
                       env={**os.environ, "PYTHONPATH": src}, check=True)
        with open(out, "rb") as fh:
            return pickle.load(fh)
    finally:
        os.unlink(out)


def compare(groups: dict[str, list], other: str, rounds: int, repeat: int) -> None:
    srcs = {"this": str(HERE / "src"), "other": other}
    with tempfile.TemporaryDirectory() as tmp:
        files = {}
        for name, calls in groups.items():
            files[name] = os.path.join(tmp, f"{name}.pkl")
            with open(files[name], "wb") as fh:
                pickle.dump(calls, fh)
        cpu = {(g, s): [] for g in groups for s in srcs}
        res = {}
        load0 = os.getloadavg()[0]
        for _ in range(repeat):
            for g in groups:
                for s in ("other", "this"):
                    got = _run(srcs[s], files[g], 0 if g == "generated" else rounds)
                    cpu[g, s].append(got["cpu"] / max(len(groups[g]), 1))
                    res[g, s] = got["results"]
        load1 = os.getloadavg()[0]
    print(f"this = {srcs['this']}, other = {other}; load {load0:.2f} -> {load1:.2f}; "
          f"{rounds} rounds x {repeat} alternations")
    for g, calls in groups.items():
        a = statistics.median(cpu[g, "this"])
        b = statistics.median(cpu[g, "other"])
        print(f"{g:>10s}: {len(calls):4d} calls, CPU per call this {a * 1e3:7.2f} ms, other "
              f"{b * 1e3:7.2f} ms, this/other {a / b:.3f} (each run: this "
              + ", ".join(f"{v * 1e3:.2f}" for v in cpu[g, "this"]) + "; other "
              + ", ".join(f"{v * 1e3:.2f}" for v in cpu[g, "other"]) + " ms)")
        ra, rb = res[g, "this"], res[g, "other"]
        same = sum(_equal(x, y) for x, y in zip(ra, rb, strict=True))
        print(f"{'':>10s}  results identical in every compared field: {same}/{len(calls)}")
        errors = sum("error" in x for x in ra)
        if errors:
            print(f"{'':>10s}  calls raising (both compared): {errors}")
        for f in FIELDS:
            pairs = [(x.get(f), y.get(f)) for x, y in zip(ra, rb, strict=True)
                     if "error" not in x and "error" not in y]
            n_eq = sum(_equal(x, y) for x, y in pairs)
            if n_eq < len(pairs):
                worst = max(_rel(x, y) for x, y in pairs)
                print(f"{'':>10s}  {f:>20s}: identical in {n_eq}/{len(pairs)}, largest "
                      f"relative difference {worst:.3g}")


def record_tests(out: str) -> None:
    """Run the fit tests with ``fit_polach`` recorded; pickle its calls to ``out``."""
    plugin = Path(tempfile.mkdtemp()) / "polach_recorder.py"
    plugin.write_text(
        "import functools, pickle, atexit\n"
        "import torquemod.analysis.fit as fit\n"
        "CALLS = []\n"
        "_fn = fit.fit_polach\n"
        "@functools.wraps(_fn)\n"
        "def fit_polach(*a, **k):\n"
        "    CALLS.append((a, k))\n"
        "    return _fn(*a, **k)\n"
        "fit.fit_polach = fit_polach\n"
        f"atexit.register(lambda: pickle.dump(CALLS, open({out!r}, 'wb')))\n")
    env = {**os.environ, "PYTHONPATH": f"{HERE / 'src'}{os.pathsep}{plugin.parent}"}
    tests = sorted(str(p) for p in (HERE / "tests" / "analysis").glob("test_fit*.py"))
    tests += [str(HERE / "tests" / "analysis" / "test_polach_jacobian.py")]
    subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "polach_recorder",
                    "-p", "no:cacheprovider", *tests], env=env, cwd=HERE, check=False)
    with open(out, "rb") as fh:
        print(f"{len(pickle.load(fh))} calls recorded to {out}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--compare-src", default=None, help="the other checkout's src")
    ap.add_argument("--sweep", default=str(HERE / "examples" / "sweep_vtrack_conditions.toml"))
    ap.add_argument("--sweep-points", type=int, default=6)
    ap.add_argument("--generated", type=int, default=300)
    ap.add_argument("--cases", action="append", default=[], help="a pickle of recorded calls")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--record-tests", default=None, metavar="FILE")
    ap.add_argument("--worker", nargs=2, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(*args.worker, args.rounds)
        return
    if args.record_tests:
        record_tests(args.record_tests)
        return
    if not args.compare_src:
        ap.error("--compare-src OTHER/src is needed (e.g. /work/main/src)")
    groups = {}
    if args.sweep_points > 0:
        groups["sweep"] = record_sweep(args.sweep, args.sweep_points)
    if args.generated > 0:
        groups["generated"] = generated(args.generated)
    for i, path in enumerate(args.cases):
        with open(path, "rb") as fh:
            groups[f"cases{i + 1}" if len(args.cases) > 1 else "cases"] = pickle.load(fh)
    compare(groups, args.compare_src, args.rounds, args.repeat)


if __name__ == "__main__":
    main()
