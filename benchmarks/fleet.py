"""Fleet throughput on Dask: hours of recording processed per minute against workers.

Writes a synthetic fleet (``--runs`` experiments of 6 steps x ``--cycles`` one-revolution
HDF5 recordings at 16 670 Hz, and ``--train-runs`` train runs of the twin, ``--train-length-m``
each, MDF4), then for each worker count processes the whole fleet with
:func:`torquemod.fleet.run.run_fleet` on a ``LocalCluster`` of that many single-threaded worker
processes (``force``: nothing skipped) and prints

* the wall time of ``run_fleet`` and, of it, the seconds spent writing ``fleet_report.html``
  in the client (serial: matplotlib),
* hours of recording per minute of processing (wall time less the report; workers warmed up:
  imports and numba caches loaded before the clock starts), and the scaling efficiency
  against 1 worker (speed-up / workers),
* CPU seconds the workers spent (their own ``process_time``), hence the figure per core,
* peak RSS per worker (``ru_maxrss``),
* the number of Dask tasks the fleet ran.

``--long-revolutions N`` adds a rig run of one HDF5 file spanning N platform revolutions
(6.46 s each) without manifest cycles: the fleet cuts it into groups of revolutions
(``--revolutions-per-task``, default about a minute of recording each) instead of one task
for the whole file. ``--runs 0 --long-revolutions 40`` is a fleet of that file alone.

    python benchmarks/fleet.py 1 2 [--runs 8] [--cycles 3] [--train-runs 0]
                                   [--train-length-m 2000] [--long-revolutions 0]
                                   [--revolutions-per-task K] [--workdir DIR]

The script takes the machine as it finds it (``os.cpu_count()``) and runs unchanged on a
bigger one; worker counts above the cores measure oversubscription.
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path


def _worker_stats() -> dict:
    return {"maxrss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "cpu_s": time.process_time()}


def _warm_up() -> None:
    """Imports and the numba kernels' cache, once per worker, outside the timing."""
    import numpy as np

    import torquemod.ontrain.run
    import torquemod.processing.pipeline  # noqa: F401
    from torquemod.dsp import resampling

    resampling.resample(np.zeros((2, 5000)), 2, 625, method="two_stage", padtype="constant")


def write_fleet(root: Path, runs: int, cycles: int, train_runs: int = 0,
                train_length_m: float = 2000.0, long_revolutions: int = 0) -> float:
    """The fleet's folders; returns the recorded duration [s]."""
    import dataclasses
    import json

    import h5py

    from torquemod.testing import write_synthetic_experiment
    from torquemod.twins.train import load_train_config, run_train_simulation

    for k in range(runs):
        folder = root / f"run{k:03d}"
        if not (folder / "experiment.toml").exists():
            write_synthetic_experiment(folder, n_steps=6, n_cycles=cycles, fmt="hdf5", seed=k)
    if long_revolutions and not (root / "run_long" / "experiment.toml").exists():
        write_synthetic_experiment(root / "run_long", n_steps=1, n_cycles=long_revolutions,
                                   files_per_cycle=False, fmt="hdf5", seed=99)
    cfg = load_train_config()
    cfg = dataclasses.replace(cfg, track=dataclasses.replace(cfg.track,
                                                             length_m=train_length_m))
    for k in range(train_runs):
        folder = root / f"train{k:03d}"
        if not (folder / "run.toml").exists():
            run_train_simulation(cfg, folder, seed=k)
    seconds = sum(json.loads(p.read_text())["duration_s"]
                  for p in root.glob("train*/simulation.json"))
    for path in root.glob("run*/*.h5"):
        with h5py.File(path, "r") as fh:
            seconds += fh["torque_nm"].shape[0] / float(fh.attrs["sample_rate_hz"])
    return seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workers", type=int, nargs="+")
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--cycles", type=int, default=3)
    ap.add_argument("--train-runs", type=int, default=0)
    ap.add_argument("--train-length-m", type=float, default=2000.0)
    ap.add_argument("--long-revolutions", type=int, default=0)
    ap.add_argument("--revolutions-per-task", type=int, default=None)
    ap.add_argument("--workdir", default=None)
    args = ap.parse_args()

    from dask.distributed import Client, LocalCluster, get_task_stream

    from torquemod.fleet.run import run_fleet

    with tempfile.TemporaryDirectory(dir=args.workdir) as tmp:
        root = Path(args.workdir or tmp) / "fleet"
        seconds = write_fleet(root, args.runs, args.cycles, args.train_runs,
                              args.train_length_m, args.long_revolutions)
        extra = ({} if args.revolutions_per_task is None
                 else {"revolutions_per_task": args.revolutions_per_task})
        hours = seconds / 3600
        long_text = (f"a rig file of {args.long_revolutions} revolutions, "
                     if args.long_revolutions else "")
        print(f"cores visible: {os.cpu_count()}; load average {os.getloadavg()[0]:.1f}; "
              f"fleet: {args.runs} rig runs, {args.train_runs} train runs, "
              f"{long_text}"
              f"{hours * 60:.1f} min of recording")
        print(f"{'workers':>7s} {'wall s':>7s} {'report s':>8s} {'h/min':>7s} {'efficiency':>10s} "
              f"{'worker CPU s':>12s} {'h/min per CPU-core':>18s} {'peak RSS/worker':>15s} "
              f"{'tasks':>6s}")
        base = None
        for n in args.workers:
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=40)
            client = Client(cluster)
            try:
                client.run(_warm_up)
                before = client.run(_worker_stats)
                with get_task_stream(client) as tasks:
                    res = run_fleet([root], Path(tmp) / f"out{n}",
                                    scheduler=cluster.scheduler_address, force=True, **extra)
                after = client.run(_worker_stats)
            finally:
                client.close()
                cluster.close()
            if res.count("failed"):
                print(res.failures.to_string())
            cpu = sum(after[w]["cpu_s"] - before[w]["cpu_s"] for w in after)
            rss = max(a["maxrss_mib"] for a in after.values())
            rate = hours / ((res.wall_s - res.report_s) / 60)
            if n == 1:
                base = rate
            eff = f"{rate / (base * n):10.2f}" if base else f"{'-':>10s}"
            print(f"{n:7d} {res.wall_s:7.1f} {res.report_s:8.1f} {rate:7.2f} {eff} {cpu:12.1f} "
                  f"{hours / (cpu / 60):18.2f} {rss:12.0f} MiB {len(tasks.data):6d}",
                  flush=True)


if __name__ == "__main__":
    main()
