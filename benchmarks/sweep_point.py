"""Where a full-mode sweep point's CPU goes: the twin, the chain, the fits.

Evaluates the first ``--points`` points of a sweep (default: the example V-Track sweep,
``mode = "full"``) one after the other in this process, after one warm-up point, and charges
each point's CPU time to its stages (the innermost stage wins):

* ``twin``: ``torquemod.twins.vtrack.simulate.simulate_run`` (integration, sensors, truth; the
recordings
  stay in memory), or with ``--through-files`` ``run_simulation`` (HDF5 files);
* ``chain``: the processing chain on the recordings in memory, or with ``--through-files``
  ``torquemod.api.process`` (reading the files, the chain);
* ``fits``: ``torquemod.api.analyze`` (Polach fit with its profile interval, mu from the
  phase, the theory constant) and the sweep's own mu-from-phase fit (``_phase_mu``), with
  the Polach fit (``fit_polach``) and the available-adhesion fit
  (``fit_available_adhesion_from_phase``: analyze's and the sweep's) charged apart;
* ``rest``: the point's set-up, theory columns and table.

It prints each stage's CPU per point and its share, and the twin's CPU against the recorded
seconds it simulates (x real time per core).

``--wall`` instead times the whole sweep as a user runs it (``torquemod sweep SWEEP --out
TMP --workers 2``, a fresh process, its local Dask cluster included), alternating this
checkout with ``--src OTHER/src`` (e.g. the main branch) ``--repeat`` times, and prints
each wall time, the CPU of the command and its workers, and the ratio of the medians; with
``--rerun`` each finished sweep is run again in its folder (every point skipped: what a
sweep costs besides its points). ``--report DIR`` draws the report of a finished sweep
folder in this process and prints the CPU of its parts (imports, point summary,
figures, PNGs, page); with ``--as-worker`` after importing what a sweep's worker has
imported (``torquemod.sweep.workerpreload``: a larger heap, as where the figures are now
drawn). ``--worker`` evaluates ``--points`` points in this process, in a
worker of Dask's default local cluster and in a worker of torquemod's, and prints the CPU
of each (what the worker's settings cost a point).

The shares bound what a faster stage can give the sweep: a stage of share s made
infinitely fast speeds the sweep up by at most 1/(1 - s) (Amdahl).

    python benchmarks/sweep_point.py [--points 6] [--through-files]
                                     [--sweep examples/sweep_vtrack_conditions.toml]
    python benchmarks/sweep_point.py --wall [--src /work/main/src] [--repeat 1] [--rerun]
    python benchmarks/sweep_point.py --report OUT [--sweep SWEEP] [--as-worker]
    python benchmarks/sweep_point.py --worker [--points 6] [--repeat 1]
"""

from __future__ import annotations

import argparse
import functools
import inspect
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]


def _timed_sweep(sweep: str, out: Path, src: str, workers: int,
                 cache: str | None = None) -> tuple[float, float, int]:
    """(wall [s], CPU of the command and its workers [s], exit code) of one sweep
    (``cache``: its torquemod disk cache folder, XDG_CACHE_HOME)."""
    env = {**os.environ, "PYTHONPATH": src, **({"XDG_CACHE_HOME": cache} if cache else {})}
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "torquemod.cli", "sweep", sweep, "--out",
                           str(out), "--workers", str(workers), "--quiet"],
                          env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime), done.returncode


def sweep_wall(sweep: str, srcs: dict[str, str], repeat: int, workers: int,
               rerun: bool = False) -> None:
    """Wall and CPU seconds of ``torquemod sweep`` for each source tree, alternated.

    Each tree gets its own torquemod disk cache (XDG_CACHE_HOME in a temporary folder),
    filled before the first timed run by one point evaluated in a process of its own (which
    also compiles any kernel missing from numba's cache): the creep-law tables are keyed by
    their source, and two trees sharing one cache would each replace the other's tables
    and rebuild them in every run (seconds of CPU per worker)."""
    walls: dict[str, list[float]] = {k: [] for k in srcs}
    caches = {k: tempfile.mkdtemp(prefix=f"torquemod-bench-cache-{k}-") for k in srcs}
    warm = ("import sys; from torquemod.sweep.evaluate import evaluate_point, tasks; "
            "from torquemod.sweep.spec import load_sweep; "
            "evaluate_point(tasks(load_sweep(sys.argv[1]))[0])")
    for label, src in srcs.items():
        subprocess.run([sys.executable, "-c", warm, sweep],
                       env={**os.environ, "PYTHONPATH": src, "XDG_CACHE_HOME": caches[label]},
                       check=True)
    for r in range(repeat):
        for label, src in srcs.items():
            with tempfile.TemporaryDirectory() as tmp:
                load0 = os.getloadavg()[0]
                wall, cpu, code = _timed_sweep(sweep, Path(tmp) / "out", src, workers,
                                               caches[label])
                load1 = os.getloadavg()[0]
                again = (_timed_sweep(sweep, Path(tmp) / "out", src, workers, caches[label])
                         if rerun else None)
            walls[label].append(wall)
            print(f"round {r + 1} {label:>7s} ({src}): wall {wall:6.1f} s, CPU {cpu:6.1f} s "
                  f"(command and workers), exit {code}, load {load0:.2f} -> {load1:.2f}",
                  flush=True)
            if again is not None:
                print(f"        rerun, every point skipped: wall {again[0]:5.1f} s, CPU "
                      f"{again[1]:5.1f} s, exit {again[2]}, load {os.getloadavg()[0]:.2f}",
                      flush=True)
    for cache in caches.values():
        shutil.rmtree(cache, ignore_errors=True)
    med = {k: statistics.median(v) for k, v in walls.items()}
    if "before" in med:
        print(f"median wall: before {med['before']:.1f} s, after {med['after']:.1f} s -> "
              f"x{med['before'] / med['after']:.2f}")


def report_alone(sweep: str, out: Path, as_worker: bool = False) -> None:
    """CPU of drawing a finished sweep's report in this process, by part (``as_worker``:
    after a sweep worker's imports)."""
    if as_worker:
        import torquemod.sweep.workerpreload  # noqa: F401
    c0 = time.process_time()
    marks = []

    def mark(label: str) -> None:
        marks.append((label, time.process_time()))

    import pandas as pd

    from torquemod.sweep import report as rep
    from torquemod.sweep.run import _hashable_params
    from torquemod.sweep.spec import load_sweep
    from torquemod.sweep.summary import point_summary
    spec = load_sweep(sweep)
    mark("imports, the sweep file")
    table = _hashable_params(pd.read_parquet(out / "sweep.parquet"), spec.swept)
    summary = point_summary(table, spec)

    def shared(fn) -> dict:  # an older checkout (--src) computes the summary itself
        return ({"summary": summary} if "summary" in inspect.signature(fn).parameters
                else {})
    rec = rep.recommend(table, spec, **shared(rep.recommend))
    mark("table, point summary, recommendation")
    if hasattr(rep, "figure_jobs"):  # each figure drawn and encoded by its job
        jobs = rep.figure_jobs(table, spec, rec, **shared(rep.figure_jobs))
        mark("the figures' jobs")
        pngs = [(job.stem, rep.draw_png(job), job.caption) for job in jobs]
        mark(f"{len(pngs)} figures drawn and encoded")
    else:  # an older checkout (--src): drawn, then encoded
        figs = rep.make_figures(table, spec, rec, **shared(rep.make_figures))
        mark(f"{len(figs)} figures drawn")
        pngs = [(stem, rep._png(fig), caption) for stem, fig, caption in figs]
        mark("their PNGs")
    rep.render(table, spec, rec, pngs, **shared(rep.render))
    mark("the page")
    load = os.getloadavg()[0]
    print(f"report of {out} ({len(table)} rows), load {load:.2f}:")
    last = c0
    for label, c in marks:
        print(f"  {label:>38s}: {c - last:5.2f} CPU-s")
        last = c
    print(f"  {'total':>38s}: {last - c0:5.2f} CPU-s")


def _points_cpu(sweep: str, n: int) -> tuple[float, float]:
    """(CPU of this process [s], wall [s]) of ``n`` points of ``sweep`` after one warm-up
    point (a Dask task: process-wide CPU, every thread of the worker counted)."""
    from torquemod.sweep.evaluate import evaluate_point, tasks
    from torquemod.sweep.spec import load_sweep
    todo = tasks(load_sweep(sweep))
    evaluate_point(todo[1])
    c0, t0 = time.process_time(), time.perf_counter()
    for task in todo[2:2 + n]:
        evaluate_point(task)
    return time.process_time() - c0, time.perf_counter() - t0


def worker_cost(sweep: str, n: int, repeat: int) -> None:
    """The same points in this process, on a worker of Dask's default local cluster and on
    a worker of torquemod's (``torquemod._util.daskutil.dask_client``), alternated."""
    import logging

    from dask.distributed import Client, LocalCluster

    from torquemod._util.daskutil import dask_client
    for r in range(repeat):
        load = os.getloadavg()[0]
        bare = _points_cpu(sweep, n)
        with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                          dashboard_address=None, silence_logs=logging.CRITICAL) as cluster, \
                Client(cluster) as client:
            default = client.submit(_points_cpu, sweep, n, pure=False).result()
        # Dask's nanny left its settings in this process's environment, where the next
        # workers would inherit them; a torquemod command starts one cluster from a clean one
        os.environ.pop("MALLOC_TRIM_THRESHOLD_", None)
        with dask_client(None, 1) as client:
            ours = client.submit(_points_cpu, sweep, n, pure=False).result()
        print(f"round {r + 1}, {n} points, load {load:.2f} -> {os.getloadavg()[0]:.2f}: "
              f"this process {bare[0]:.2f} CPU-s; Dask's default worker {default[0]:.2f} "
              f"(x{default[0] / bare[0]:.2f}); torquemod's worker {ours[0]:.2f} "
              f"(x{ours[0] / bare[0]:.2f})", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=6)
    ap.add_argument("--through-files", action="store_true",
                    help="the twin's experiment through an HDF5 folder, as before")
    ap.add_argument("--sweep", default=str(Path(__file__).resolve().parents[1] / "examples"
                                           / "sweep_vtrack_conditions.toml"))
    ap.add_argument("--wall", action="store_true",
                    help="time whole sweeps (a fresh torquemod sweep) instead")
    ap.add_argument("--src", default=None,
                    help="with --wall: another checkout's src to alternate with (before)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--rerun", action="store_true",
                    help="with --wall: run each finished sweep again (every point skipped)")
    ap.add_argument("--as-worker", action="store_true",
                    help="with --report: import what a sweep worker imports first")
    ap.add_argument("--report", type=Path, default=None, metavar="OUT",
                    help="draw the report of the finished sweep folder OUT, timed by part")
    ap.add_argument("--worker", action="store_true",
                    help="--points points in this process, on a default Dask worker and on "
                         "torquemod's local worker (CPU each)")
    args = ap.parse_args()
    if args.worker:
        worker_cost(args.sweep, args.points, args.repeat)
        return
    if args.report is not None:
        report_alone(args.sweep, args.report, args.as_worker)
        return
    if args.wall:
        srcs = ({"before": args.src} if args.src else {}) | {"after": str(HERE / "src")}
        sweep_wall(args.sweep, srcs, args.repeat, args.workers, args.rerun)
        return

    import torquemod.analysis.analyzer as analyzer
    import torquemod.analysis.phasefit as phasefit
    import torquemod.api as api
    import torquemod.twins.vtrack.simulate as sim
    from torquemod.sweep import evaluate as ev
    from torquemod.sweep.evaluate import tasks
    from torquemod.sweep.spec import load_sweep

    spec = load_sweep(args.sweep)
    todo = tasks(spec)[: args.points + 1]
    acc: dict[str, float] = {}
    recorded = [0.0]
    inner = [0.0]  # CPU of the charged calls inside the one running (innermost wins)

    def charge(mod, name, label):
        fn = getattr(mod, name)

        @functools.wraps(fn)  # the analysis inspects fit_polach's signature
        def wrapped(*a, **k):
            outer, inner[0] = inner[0], 0.0
            c0 = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                spent = time.process_time() - c0
                acc[label] = acc.get(label, 0.0) + spent - inner[0]
                inner[0] = outer + spent

        setattr(mod, name, wrapped)

    twin_name = "run_simulation" if args.through_files else "simulate_run"
    real_sim = getattr(sim, twin_name)

    def counted(config, *a, **k):
        got = real_sim(config, *a, **k)
        truth = got if isinstance(got, dict) else got.truth
        p = config.procedure
        recorded[0] += sum(1 for s in truth["steps"] if not s.get("slipped")) * (
            p.cycles_per_step * config.rig.revolution_s)
        return got

    setattr(sim, twin_name, counted)
    charge(sim, twin_name, "twin")
    charge(api, "process", "chain")
    charge(ev, "_process_in_memory", "chain")
    charge(api, "analyze", "fits")
    charge(ev, "_phase_mu", "fits (sweep)")
    # inside the fits: the Polach fit and the available-adhesion fit (analyze's and the
    # sweep's own, each then charged here instead of to its caller)
    charge(analyzer, "fit_polach", "  Polach fit")
    charge(phasefit, "fit_available_adhesion_from_phase", "  adhesion fit")
    with tempfile.TemporaryDirectory() as tmp:
        files = {"workdir": tmp, "through_files": args.through_files}
        ev.evaluate_point(todo[0], **files)  # warm-up: kernels, caches
        acc.clear()
        recorded[0] = 0.0
        load0 = os.getloadavg()[0]
        c0, w0 = time.process_time(), time.perf_counter()
        for task in todo[1:]:
            ev.evaluate_point(task, **files)
        total, wall = time.process_time() - c0, time.perf_counter() - w0
    n = len(todo) - 1
    how = "through HDF5 files" if args.through_files else "in memory"
    print(f"{n} points of {Path(args.sweep).name} (mode {spec.mode}, {how}) in this process; load "
          f"{load0:.2f} -> {os.getloadavg()[0]:.2f}; CPU {total:.2f} s, wall {wall:.2f} s")
    shares = {**acc, "rest": total - sum(acc.values())}
    for label, cpu in shares.items():
        print(f"{label:>14s}: {cpu / n:6.3f} CPU-s per point, {100 * cpu / total:5.1f} % "
              f"(made free: sweep x{1 / max(1e-9, 1 - cpu / total):.2f} at most)")
    print(f"twin: {recorded[0] / n:.1f} recorded s per point, "
          f"{recorded[0] / max(acc.get('twin', 0.0), 1e-9):.0f}x real time per core "
          "(recorded revolutions only; settling not counted)")


if __name__ == "__main__":
    main()
