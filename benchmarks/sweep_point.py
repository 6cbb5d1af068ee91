"""Where a full-mode sweep point's CPU goes: the twin, the chain, the fits.

Evaluates the first ``--points`` points of a sweep (default: the example V-Track sweep,
``mode = "full"``) one after the other in this process, after one warm-up point, and charges
each point's CPU time to its stages (the innermost stage wins):

* ``twin``: ``torquemod.twins.vtrack.simulate.run_simulation`` (integration, sensors, truth, HDF5
files);
* ``chain``: ``torquemod.api.process`` (reading the files, the processing chain);
* ``fits``: ``torquemod.api.analyze`` (Polach fit with its profile interval, mu from the
  phase, the theory constant) and the sweep's own mu-from-phase fit (``_phase_mu``);
* ``rest``: the point's set-up, theory columns and table.

It prints each stage's CPU per point and its share, and the twin's CPU against the recorded
seconds it simulates (x real time per core). These shares bound what a faster stage can
give the sweep: a stage of share s made infinitely fast speeds the sweep up by at most
1/(1 - s) (Amdahl).

    python benchmarks/sweep_point.py [--points 6] [--sweep examples/sweep_vtrack_conditions.toml]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=6)
    ap.add_argument("--sweep", default=str(Path(__file__).resolve().parents[1] / "examples"
                                           / "sweep_vtrack_conditions.toml"))
    args = ap.parse_args()

    import torquemod.api as api
    import torquemod.twins.vtrack.simulate as sim
    from torquemod.sweep import evaluate as ev
    from torquemod.sweep.evaluate import tasks
    from torquemod.sweep.spec import load_sweep

    spec = load_sweep(args.sweep)
    todo = tasks(spec)[: args.points + 1]
    acc: dict[str, float] = {}
    recorded = [0.0]
    depth = [0]

    def charge(mod, name, label):
        fn = getattr(mod, name)

        def wrapped(*a, **k):
            depth[0] += 1
            c0 = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                depth[0] -= 1
                acc[label] = acc.get(label, 0.0) + time.process_time() - c0

        setattr(mod, name, wrapped)

    real_sim = sim.run_simulation

    def counted(config, *a, **k):
        truth = real_sim(config, *a, **k)
        p = config.procedure
        recorded[0] += sum(1 for s in truth["steps"] if not s.get("slipped")) * (
            p.cycles_per_step * config.rig.revolution_s)
        return truth

    sim.run_simulation = counted
    charge(sim, "run_simulation", "twin")
    charge(api, "process", "chain")
    charge(api, "analyze", "fits")
    charge(ev, "_phase_mu", "fits (sweep)")
    with tempfile.TemporaryDirectory() as tmp:
        ev.evaluate_point(todo[0], workdir=tmp)  # warm-up: kernels, caches
        acc.clear()
        recorded[0] = 0.0
        load0 = os.getloadavg()[0]
        c0, w0 = time.process_time(), time.perf_counter()
        for task in todo[1:]:
            ev.evaluate_point(task, workdir=tmp)
        total, wall = time.process_time() - c0, time.perf_counter() - w0
    n = len(todo) - 1
    print(f"{n} points of {Path(args.sweep).name} (mode {spec.mode}) in this process; load "
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
