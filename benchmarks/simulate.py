"""Throughput of the V-Track digital twin: simulated seconds per wall-clock second.

Run: ``python benchmarks/simulate.py [--repeat N] [--cores N] [--points N]``. Prints

* the warm-up: the first calls of the compiled kernels (numba compilation, or loading them
  from numba's on-disk cache once compiled), timed on their own and excluded below;
* the integrator alone: the default procedure's rig time, settling included, at 16 670 Hz,
  with the configured step (``procedure.samples_per_step`` samples per RK4 step), in this
  one thread;
* a complete ``run_simulation`` of the default experiment writing HDF5, then CSV: recorded
  seconds (7 columns -- time and 6 channels -- at 16 670 Hz) per wall-clock second of the
  whole call (integration, sensors, ground truth, files). Targets: issue 3 >= 100x real
  time for HDF5 on one core; issue 12 >= 1000x;
* the batch mode: ``--points`` (default 16) sweep points of the default experiment (mu0
  from 0.22 to 0.30, modulation at 2 and 3 Hz) as points per second and as recorded seconds
  per CPU-second (x real time per core): ``simulate_batch`` of all points at once (also
  without the large-signal theory column, and with two torque steps side by side in each
  compiled loop instead of the default one, rig/lanes.py), the same one point at a
  time, ``simulate_run``
  (recordings in memory, what a sweep point runs) and ``run_simulation`` (HDF5) one at a
  time, and the ratio batch / one at a time (``--batch-only``: this part alone);
* the CPU split of one run (``run_simulation`` HDF5 on one worker thread): per phase of a
  step its CPU and the part of it outside the compiled kernels that release the GIL (the
  "serial" part: h5py, the theory's Python, the run's set-up), and from it an Amdahl
  PROJECTION to 2-16 cores (a projection, not a measurement: serial part never overlapped /
  fully overlapped, and never below the longest single step);
* threads 1 vs 2: ``run_simulation`` on 1 and on 2 worker threads, alternated, and the serial
  share Amdahl's law infers from the two (``2*T2/T1 - 1``);
* a fresh process: ``torquemod simulate --format hdf5`` as a user starts it (imports and
  loading the compiled kernels included).

``--with-sensors [--points 6] [--repeat 3]`` instead: the twin as a full-mode sweep point runs
it (``simulate_run(workers=1, large_signal=False, statistics=False)`` on the example sweep's
first points, their settling and DC torques as the sweep sets them) against
``simulate_batch`` (truth only, no sensors) in the same run, as x real time per core, and the
run's CPU per point split into integrator, sensors, truth, planning and the rest. Run it with
another checkout's src on ``PYTHONPATH`` for a before/after pair (a checkout without the
``statistics`` flag runs its whole truth).

``run_simulation`` and ``simulate_batch`` run the torque steps side by side, one thread per
CPU and at most one per step (each step starts from the steady state of the torque before,
rig/steps.py). ``--cores N`` pins the process to N CPUs (Linux ``sched_setaffinity``) to show
the one-core figure. ``--repeat`` runs each measurement N times and prints every figure and
the best; the machine's other load shows as spread between repeats. Every timed run starts
with the theory's memos cleared (:func:`cold_theory`), as a fresh process would.

Later figures are in docs/performance.md ("The twin in a sweep", "The twin's integrator,
faster": the RK4 step of 12 samples and the normal load without its exact fall-back, batch
519-538x -> 778-782x real time per core, 570-579x -> 889-898x without the large-signal
theory; "The twin toward 1000x": the platform loop taken exactly, the sensors in fewer
passes, skipped steps after a slip: batch 749-789x -> 821-863x, 854-880x -> 865-944x
without the large-signal theory; "The twin's recorded step": 16 samples instead of 12, from
the measured discretisation error, batch 836-868x -> 919-969x, 921-951x -> 1064-1102x
without the theory; "The twin's batch past 1000x": the large-signal theory's Newton steps
by the Jacobian's Schur complement and its operators per rig, the truth's fit sums and
moments in one vectorised sweep, batch 909-975x -> 1060-1107x, 1101-1172x without the
theory). ``--samples-per-step N`` runs the batch at another recorded step.

Measured, fifth round of issue 12 (the same 2-core VM, load average 0.1-1.2 from other
agents; "before" = commit 472e5c0 from an exported copy, before and after alternated in 3
rounds with the final code; x real time is the best of 3 in-process runs after a warm-up;
the CPU split is the best run's):

=========================================  ======================  ======================
                                           before (472e5c0)        after
=========================================  ======================  ======================
run_simulation HDF5, 2 cores               367-387x                452-591x
run_simulation HDF5, 1 core                257-289x                296-320x
integrator (six steps, one thread)         605-846x                649-840x (code as before)
CPU of one run (s, one worker thread)      0.411-0.520             0.354-0.480
  best run of both sessions: integrator / 0.162/0.062/0.045/      0.171/0.063/0.031/
  noise / truth statistics / large-signal 0.030/0.066/0.011       0.025/0.051/0.012
  theory / HDF5 / set-up
serial (GIL-held) CPU of one run           0.082-0.111 s (19-22 %) 0.049-0.067 s (14-15 %)
  of which HDF5 files / large-signal       40-45 / 12-13 ms        20-23 / 4-5 ms
  theory's Python
fresh process (CLI, HDF5), 6 alternations  1.71-2.39 s (median     1.65-1.81 s (median
                                           1.95), CPU 2.19-2.58 s  1.80), CPU 2.10-2.30 s
=========================================  ======================  ======================

An earlier session (3 alternations, with the truth offered to the pool, since removed, see
below) measured before 492-554x / after 402-564x on 2 cores and 273-297x / 309-330x on one:
on this machine the 2-core figure moves with the other agents' load more than with these
changes; the CPU and serial figures are the steadier comparison.

Projection from the best after-run's split (0.305 s GIL-free, 0.049 s serial, longest step
0.066 s; Amdahl, serial part never overlapped .. fully overlapped): 2 cores 577-657x, 4 cores
928-1314x, 8 cores 1335-1765x, 16 cores 1709-1765x (before: 520-617x, 791-1234x, 1069-1651x,
1298-1651x). 1000x on 2 cores (0.116 s wall, ~0.23 s of CPU for everything) stays out of
reach: the integrator alone is ~0.17 s of CPU.

What changed in the fifth round (against a fresh compile of 472e5c0 the recorded files
are the same bit for bit, truth.json's large-signal phases move by <= 2.8e-14 deg and
everything else in it is the same; against a checkout whose numba cache held the other
Polach kernel, every value moves by ~1e-13 relative, see the item on numba's cache):

* HDF5: a new file of the flat layout is created by h5py's low-level calls with property
  lists made once per process -- the same bytes as h5py's File path (tested byte for byte),
  ~0.7 ms of GIL-held metadata a file instead of ~2.5 ms (18 files: 65 -> 14 ms CPU
  measured alone);
* the large-signal theory's Newton loop (residual, finite-difference Jacobian, solve,
  backtracking) compiled without the GIL (theory_kernels.py; ~11 -> ~4 ms of Python a run;
  agrees with the Python loop to 1e-14 deg, tested);
* the truth's sums: the fit basis's time columns turn by one precomputed small rotation,
  the fit's normal equations take four rows per load and store of each sum, the moments
  sum in local variables (truth of a step 10.3 -> 6.6 ms; the same additions in the same
  order, tested bit for bit against plain Python);
* the ziggurat's common case inside the channel's loop (add_normal 1.27 -> 1.11 ms per
  323 000 numbers, the same numbers);
* step 1 starts integrating while the other steps are planned (~6 ms off the critical
  path; on 2 cores not measurable: 40 alternations, medians 259 and 256 ms);
* ``torquemod._version`` is a plain string (pyproject reads it as a dynamic version) instead
  of importlib.metadata (~35 ms of each start-up);
* the integrator's fast-math Polach kernel has its own numba cache entry: it shared one with
  polach.creep_force_kernel (numba keys its cache by file, name and types, not by compile
  options), so which of the two a process loaded depended on the cache's history and the
  twin's values moved by ~1e-13 between checkouts (fx 1.1e-13 N); now always the fast-math
  kernel, as a fresh compile gave;
* after the alternations above: the dense Newton solve eliminates two pivots per pass
  over the rows, the same operations in the same order (bit for bit, tested; 4.8 -> 3.1 ms
  at 256 unknowns); the large-signal theory of a run 24.7 -> 18.7 ms of CPU (one split,
  0.354 s in all), tqdm imported only when the progress bar is shown, one HDF5 dataspace
  per file.

Tried and not kept: offering a step's truth to the pool while its thread writes the files
(2 cores, 30 alternations: median 271 against 248 ms a run -- two threads wanting the GIL
at once wait for each other's switch interval); submitting the steps by falling DC torque
(no measurable difference); one fused pass for all six noisy channels (15.2 against 10.8 ms
a step: the channels' generators interleaved lose more than the shared reads of the
integrator's rows save -- with each draw a call; written out per channel, as
``sensors._measure_kernel`` now does, the one pass is ~10-20 % faster than the channel
passes, docs/performance.md "The twin as a sweep point runs it"); the encoder kernel in
blocks of 256 or with a countdown (no gain; again later: the small rotations of a block of
512 computed first in a vector loop, 1.81 against 1.33 ms for 215 000 samples).
Not done: a shorter settling (4 s a step, 17 ms of the integrator's ~165 ms; it would move
every recorded value, since the recordings' start times follow it).

A fresh ``torquemod simulate`` (~1.6-1.8 s) is mostly fixed costs: importing numba (~0.2
s), scipy.optimize with scipy.special (~0.25 s; brentq and minimize_scalar are on the
twin's path), the io package (~0.1 s, of which pyarrow, scipy.io and the parquet writer
~65 ms that an HDF5 run does not use: io/__init__ imports every format), numba's first
cached kernel initialising its CPU target (~0.18 s), loading ~10 cached kernels (5-20 ms
each) and the run itself.

Measured, fourth round of issue 12 (2-core AMD EPYC VM shared with up to 8 other agents,
load average 0.8-4.0 during the runs; "before" = commit a2b9601 run from an exported copy,
before and after alternated so that both see the same load; x real time is the best of 3-5
in-process runs after a warm-up, ranges over 6-7 alternations, the quieter ones in brackets):

=========================================  ======================  ======================
                                           before (a2b9601)        after
=========================================  ======================  ======================
run_simulation HDF5, 2 cores               142-375x (239-375x)     197-539x (394-539x)
run_simulation HDF5, 1 core                152-232x (217-232x)     186-292x (276-292x)
integrator (six steps, one thread)         480-566x                621-836x
CPU of one run (s, whole process)          0.49-0.69               0.39-0.60
  integrator / noise / truth / theory /    0.27/0.07/0.07/0.05/    0.17/0.07/0.05/0.03/
  HDF5 / set-up (one thread, best run)     0.09/0.02               0.07/0.01
serial (GIL-held) CPU of one run           --                      0.073-0.089 s (18-21 %)
2 cores / 1 core (quieter rounds)          1.46-1.64               1.85-1.88
threads 1 -> 2 (serial share, Amdahl)      --                      1.70-1.84 (0.09-0.18)
batch, 4 points at once                    4.7 points/s            7.5 points/s
fresh process (CLI, HDF5)                  --                      2.5-3.0 s: 39-47x
=========================================  ======================  ======================

Projection from the measured split (0.318 s GIL-free, 0.073 s serial, longest step 0.073 s;
Amdahl with the serial part never overlapped .. fully overlapped): 2 cores 501-594x, 4 cores
761-1189x, 8 cores 1029-1588x, 16 cores 1249-1588x. 1000x needs about 8 free cores; with 7
torque steps (6 recorded, the last slips) nothing gains beyond 7 threads, and the longest
step (~0.073 s of CPU, about a sixth of each phase above) caps a run at ~1600x. Where the
serial 0.073 s goes: h5py's metadata of 18 files x 7 datasets (~42 ms: opening, 10
attributes and 7 dataset headers per file; h5py's lock serialises it across threads even
where the GIL is released), the large-signal theory's Newton loop in Python (~12 ms), the
run's set-up before the threads start and truth.json (~11 ms), the rest ~8 ms. A CLI run
is dominated by starting Python and importing the package (1.8-2.4 s: ``import torquemod``
loads the processing chain, scipy.signal and the report modules before the twin), not by the
simulation.

What changed in the fourth round: the truth's fit sums (normal equations of the whole step
and each revolution, the speed reference) in one compiled kernel without the GIL instead of
numpy gathers and BLAS products (phases move <= 2.1e-9 deg by summation order; every other
truth value and every recorded value unchanged); the HDF5 values copied into
early-allocated contiguous datasets by ``os.pwrite`` after h5py has closed the file (the same
float64 values, bit for bit), the files' sample times from a compiled kernel (bit for bit);
the theory's dense Newton solve releases the GIL, its creep-curve peak and operating points
are remembered per rig (a run asked for the same point three times, the peak ~20 times); the
step threads are no longer capped at 4; ``samples_per_step = 8`` by default (RK4 at
``lambda*h = 1.6``; still fourth order, difference ratios 16.05; the default experiment's
phases move by <= 1.6e-5 deg per step and 3.3e-5 deg per revolution, the recorded channels by
<= 4.5e-6 of their range: Fx 0.0033 N, torque 3.3e-4 N*m, wheel speed 3.4e-6 rad/s).

History: second round (commit ad67fc9 -> its successor, best of 3, load 1.9-3.1): HDF5 2
cores 149-318x -> 337-366x, 1 core 184-189x -> 220-225x, integrator 468x -> 532x, CPU of one
run 0.64 -> 0.53 s; the settling at the longest stable RK4 step without output samples, the
compiled splitmix64 + ziggurat noise (noise values per seed changed then), the truth's moments
in two passes, the encoder kernel without the GIL. First round, on a quieter machine:
integrator 405-419x -> 504-526x, HDF5 2 cores 142-202x -> 265-318x, 1 core 126-146x ->
161-182x, CSV 63-67x -> 132-139x, batch of 4 points 2.3 -> 4.3 points/s.

Why the integrator cannot give 1000x on 2 cores: the default procedure takes ~330 000 RK4
steps (settling at 10 samples per step, recording at 8), ~0.5 us each with their output
samples (the four Polach evaluations form a dependency chain of ~51 ns latency each, measured
in the second round, plus the normal-load disturbances and the wobble), i.e. ~0.17 CPU-s,
while 1000x on 2 cores allows 0.23 CPU-s for everything (noise, truth, theory, files ~0.22
CPU-s more). Not taken: interleaving two torque steps in one integrator loop (their chains are
independent) could hide most of the latency but needs a kernel rewritten across lanes.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import types
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

import torquemod.io.hdf5 as _hdf5
import torquemod.twins.vtrack.rig.noise as _noise
import torquemod.twins.vtrack.rig.sensors as _sensors
import torquemod.twins.vtrack.rig.steps as _steps
import torquemod.twins.vtrack.rig.truth as _truth
import torquemod.twins.vtrack.rig.truthphase as _truthphase
import torquemod.twins.vtrack.simulate as _simulate
import torquemod.twins.vtrack.theory as _theory
from torquemod.twins.vtrack.rig.batch import plan_run
from torquemod.twins.vtrack.rig.dynamics import OUT_COLUMNS, initial_state, pack_parameters
from torquemod.twins.vtrack.rig.lanes import integrate
from torquemod.twins.vtrack.rig.sensors import measure
from torquemod.twins.vtrack.rig.steps import integrate_step
from torquemod.twins.vtrack.simulate import (
    load_config,
    run_simulation,
    simulate_batch,
    simulate_run,
    sine_fit_phase_deg,
)
from torquemod.twins.vtrack.theory import operating_point

#: the example sweep whose points ``--with-sensors`` runs
_SWEEP = Path(__file__).resolve().parents[1] / "examples" / "sweep_vtrack_conditions.toml"


def cold_theory() -> None:
    """Forget the theory's remembered creep-curve peaks, operating points, large-signal
    results, FFT of the identity and collocation operators, so that every timed run
    computes them as a fresh process does (theory.py memoises them per rig)."""
    for name in ("_creep_curve_peak_memo", "_operating_point_memo", "_large_signal_memo",
                 "_eye_spectrum", "_operators_memo"):  # (an older checkout lacks some)
        if hasattr(_theory, name):
            getattr(_theory, name).cache_clear()


def warm_up(config) -> float:
    """Wall seconds of the first call of every compiled kernel the simulation uses (numba
    compiles them on the very first run, later runs load them from numba's cache)."""
    rig, proc = config.rig, config.procedure
    fs = config.sensors.sample_rate_hz
    t0 = time.perf_counter()
    p = pack_parameters(rig, config.disturbances)
    op = operating_point(proc.dc_torques_nm[0], rig)
    y = initial_state(rig, creepage=op.creepage, dc_torque_nm=op.dc_torque_nm,
                      contact_fx_n=op.fx_n)
    out = np.empty((200, len(OUT_COLUMNS)))
    integrate(y, 0.0, 200, 1 / fs, proc.substeps, p, 0.0, 0.0, 0.0, 0.5, 8.0, 12.6, 0.0, 0.0,
              proc.slip_creepage, out, proc.samples_per_step)
    measure(out, disturbances=config.disturbances, sensors=config.sensors,
            rng=np.random.default_rng(0))
    sine_fit_phase_deg(out[:, 0], out[:, 1], fs, 100.0)
    return time.perf_counter() - t0


def first_run(config) -> float:
    """Wall seconds of a one-step, one-revolution run_simulation (lazy imports, file layer)."""
    short = load_config(overrides={"procedure": {"dc_torques_nm": [22.84], "cycles_per_step": 1,
                                                 "settle_s": 0.1}})
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        run_simulation(short, Path(tmp) / "exp", fmt="hdf5", progress=False)
    return time.perf_counter() - t0


def integrator_throughput(config, coarse_settling: bool = True) -> tuple[float, float]:
    """(simulated seconds, wall seconds) of the integrator over the first six steps of the
    default procedure, settling included, one after the other in this thread, as the twin
    integrates them (:func:`integrate_step`; ``coarse_settling``: the settling at the longest
    stable step, else at the recorded step as before issue 12's second round)."""
    rp = plan_run(config, 0)
    p = pack_parameters(config.rig, config.disturbances)
    fs = config.sensors.sample_rate_hz
    t_sim, t0 = 0.0, time.perf_counter()
    for plan in rp.steps[:6]:
        _out, n, _slipped, _y = integrate_step(config, p, rp.wobble, plan, rp.n_step, None,
                                               rp.n_settle if coarse_settling else 0)
        t_sim += n / fs
    return t_sim, time.perf_counter() - t0


def batch_configs(n_points: int, samples_per_step: int = 0) -> list:
    """``n_points`` sweep points of the default experiment: friction (mu0) and modulation
    frequency varied together. ``samples_per_step`` > 0: that recorded step, set after the
    configuration's step guard (a measurement aid: a step the guard would shorten)."""
    mus = np.linspace(0.22, 0.30, n_points)
    configs = [load_config(overrides={"contact": {"mu0": float(mu)},
                                      "modulation": {"frequency_hz": 2.0 + (k % 2)}})
               for k, mu in enumerate(mus)]
    if samples_per_step > 0:
        configs = [replace(c, procedure=replace(c.procedure, samples_per_step=samples_per_step))
                   for c in configs]
    return configs


def _recorded_s(configs, points) -> float:
    """Recorded seconds [s] of a batch's results: the revolutions of its unslipped steps."""
    total = 0.0
    for c, p in zip(configs, points, strict=True):
        steps = p.steps if hasattr(p, "steps") else p.truth["steps"]
        total += sum(1 for s in steps if not s["slipped"]) * (
            c.procedure.cycles_per_step * c.rig.revolution_s)
    return total


def batch_throughput(configs, repeat: int) -> None:
    """Points per second and recorded seconds per CPU-second (x real time per core):
    :func:`simulate_batch` of all points at once, the same one point at a time, and
    ``simulate_run`` (recordings in memory, as a sweep point) and ``run_simulation`` (HDF5
    files) one point at a time. CPU is the process's (every thread's) over the call."""
    runs = {"simulate_batch (all points at once)": lambda: simulate_batch(configs, seed=0),
            "simulate_batch (all at once, large_signal=False)":
                lambda: simulate_batch(configs, seed=0, large_signal=False),
            "simulate_batch (all at once, two lanes)":
                lambda: simulate_batch(configs, seed=0, lanes=2),
            "simulate_batch (one point at a time)":
                lambda: [simulate_batch([c], seed=0)[0] for c in configs],
            "simulate_run, in memory (one point at a time)":  # each run dropped when done
                lambda: [types.SimpleNamespace(steps=simulate_run(c, seed=0).truth["steps"])
                         for c in configs]}

    def files():
        truths = []
        for c in configs:
            with tempfile.TemporaryDirectory() as tmp:
                truths.append(types.SimpleNamespace(steps=run_simulation(
                    c, Path(tmp) / "exp", seed=0, fmt="hdf5", progress=False)["steps"]))
        return truths
    runs["run_simulation hdf5 (one point at a time)"] = files
    per_core = {}
    for label, fn in runs.items():
        walls, cpus = [], []
        for _ in range(repeat):
            cold_theory()
            c0, t0 = time.process_time(), time.perf_counter()
            points = fn()
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
        best, cpu = min(walls), min(cpus)
        rec = _recorded_s(configs, points)
        per_core[label] = rec / cpu
        extra = f"  (runs: {', '.join(f'{w:.2f} s' for w in walls)})" if repeat > 1 else ""
        print(f"batch: {label}: {len(configs)} points in {best:.2f} s -> "
              f"{len(configs) / best:.2f} points/s; {rec:.0f} recorded s in {cpu:.2f} CPU-s "
              f"-> {rec / cpu:.0f}x real time per core{extra}")
    one = per_core["simulate_batch (one point at a time)"]
    print(f"batch: all {len(configs)} at once / one at a time, recorded s per CPU-s: "
          f"x{per_core['simulate_batch (all points at once)'] / one:.2f}")


def sweep_point_configs(n_points: int, sweep: Path = _SWEEP) -> list[tuple]:
    """``(config, seed)`` of the first ``n_points`` points of ``sweep`` as its full mode
    gives them to the twin (:func:`torquemod.sweep.evaluate.evaluate_point`: the point's
    overrides, DC torques as fractions of its peak, its settling time)."""
    from torquemod.sweep.evaluate import _theory_steps, point_config, settle_time_s, tasks
    from torquemod.sweep.spec import load_sweep
    out = []
    for task in tasks(load_sweep(sweep))[:n_points]:
        config, t_peak = point_config(task)
        settle = settle_time_s(config, _theory_steps(config, t_peak))
        out.append((replace(config, procedure=replace(config.procedure, settle_s=settle)),
                    task.seed))
    return out


#: what :func:`with_sensors` charges a sweep point's ``simulate_run`` to (module, function,
#: label); the rest is the run's set-up and packaging
_RUN_PHASES = ((_simulate, "integrate_step", "integrator"),
               (_simulate, "measure", "sensors"),
               (_simulate, "recorded_step_truth", "truth"),
               (_simulate, "plan_run", "plan (wobble, start states)"))


def with_sensors(n_points: int, repeat: int) -> None:
    """The twin as a sweep point runs it against the batch twin, in the same run: the first
    ``n_points`` points of the example sweep through ``simulate_run(workers=1,
    large_signal=False, statistics=False)`` (recordings with their sensors, the truth the
    sweep reads; what a full-mode point runs) and through
    ``simulate_batch(large_signal=False)`` (truth only, no sensors), alternated ``repeat``
    times; recorded seconds per CPU-second (x real time per core, best round of each) and
    the ``simulate_run`` CPU per point split by phase (thread CPU of the calls, best round)."""
    import inspect
    import threading
    # the sweep's call (a checkout without the flag: its whole truth)
    lean = ({"statistics": False} if "statistics" in inspect.signature(simulate_run).parameters
            else {})
    pts = sweep_point_configs(n_points + 1)
    simulate_run(pts[0][0], seed=pts[0][1], workers=1, large_signal=False, **lean)  # warm-up
    simulate_batch([pts[0][0]], seed=pts[0][1], large_signal=False)
    pts = pts[1:]
    acc: dict[str, float] = {}
    lock = threading.Lock()
    saved = {}
    for mod, name, label in _RUN_PHASES:
        fn = saved[(mod, name)] = getattr(mod, name)

        def wrapped(*a, _fn=fn, _label=label, **k):
            c0 = time.thread_time()
            try:
                return _fn(*a, **k)
            finally:
                with lock:
                    acc[_label] = acc.get(_label, 0.0) + time.thread_time() - c0
        setattr(mod, name, wrapped)
    runs, batch, splits = [], [], []
    try:
        for _ in range(repeat):
            acc.clear()
            c0 = time.process_time()
            rec = 0.0
            for config, seed in pts:
                run = simulate_run(config, seed=seed, workers=1, large_signal=False, **lean)
                rec += sum(r.n_samples / r.fs_hz for r in run.recordings)
                del run
            runs.append((time.process_time() - c0, rec))
            splits.append(dict(acc))
            c0 = time.process_time()
            for config, seed in pts:  # one point at a time, as a sweep's task
                simulate_batch([config], seed=seed, large_signal=False)
            batch.append(time.process_time() - c0)
    finally:
        for (mod, name), fn in saved.items():
            setattr(mod, name, fn)
    best = min(range(repeat), key=lambda i: runs[i][0])
    cpu, rec = runs[best]
    n = len(pts)
    print(f"with sensors: {n} points of {_SWEEP.name}, {rec / n:.1f} recorded s per point; "
          f"load {os.getloadavg()[0]:.2f}")
    print(f"  simulate_run (sensors, truth; workers=1, large_signal=False"
          f"{', statistics=False' if lean else ''}, as a sweep point): "
          f"{cpu / n * 1e3:.1f} ms CPU per point -> {rec / cpu:.0f}x real time per core "
          f"(rounds: {', '.join(f'{c / n * 1e3:.1f}' for c, _ in runs)} ms)")
    print(f"  simulate_batch (truth only, one point at a time): {min(batch) / n * 1e3:.1f} ms "
          f"CPU per point -> {rec / min(batch):.0f}x real time per core")
    print(f"  simulate_run / simulate_batch CPU: x{cpu / min(batch):.2f}")
    split = splits[best]
    for label, c in sorted(split.items(), key=lambda kv: -kv[1]):
        print(f"    {label:>28s}: {c / n * 1e3:6.1f} ms per point ({100 * c / cpu:4.1f} %)")
    rest = cpu - sum(split.values())
    print(f"    {'set-up, packaging, rest':>28s}: {rest / n * 1e3:6.1f} ms per point "
          f"({100 * rest / cpu:4.1f} %)")


#: the phases of a step as the twin runs them (module, function name, label); nested calls
#: are charged to the innermost phase
_PHASES = ((_simulate, "integrate_step", "integrator"),
           (_simulate, "recorded_step_truth", "truth: steady state, small-signal theory"),
           (_truth, "_large_signal", "truth: large-signal theory"),
           (_truth, "_spans_truth", "truth: simulated statistics and phase"),
           (_simulate, "measure", "sensor noise"),
           (_simulate, "_write_step", "HDF5 files"))
#: the compiled kernels (numba, nogil=True) and system calls that run without the GIL
_GIL_FREE = ((_steps, "integrate"), (_truth, "_fit_sums"), (_truth, "_partition_moments"),
             (_truth, "_span_moments"), (_truthphase, "_sine_fit_sums"),
             (_sensors, "_encoder_kernel"), (_sensors, "_measure_kernel"),
             (_noise, "_add_normal"), (_theory, "newton_periodic"),
             (_simulate, "_sample_times"), (_hdf5.os, "pwrite"))


@dataclass
class CpuSplit:
    """CPU seconds of one run (``run_simulation`` on one worker thread): per phase
    ``phases[label] = (cpu_s, gil_free_cpu_s)``; ``total_s`` the process's CPU over the run,
    ``step_max_s`` the CPU of its longest step (integration to files)."""

    phases: dict
    total_s: float
    step_max_s: float

    @property
    def parallel_s(self) -> float:
        """CPU inside GIL-free kernels and system calls [s]."""
        return sum(free for _cpu, free in self.phases.values())

    @property
    def serial_s(self) -> float:
        """CPU with the GIL held (or not known to be without it) [s]."""
        return self.total_s - self.parallel_s


def cpu_split(config, seed: int = 0) -> CpuSplit:
    """Run ``run_simulation`` (HDF5) on one worker thread with every phase of a step
    (:data:`_PHASES`) and every GIL-free kernel (:data:`_GIL_FREE`, each checked to be
    compiled with ``nogil``) wrapped by a thread-CPU clock; the wrappers are removed after.
    What is not inside a GIL-free kernel counts as serial (holding the GIL, or h5py's lock):
    conservative, numpy's own loops release the GIL too."""
    stack, acc, steps = [], {}, []

    def phase(fn, label):
        def wrapped(*a, **k):
            stack.append([label, time.thread_time(), 0.0, 0.0])  # label, start, inner, free
            try:
                return fn(*a, **k)
            finally:
                lab, t0, inner, free = stack.pop()
                cpu = time.thread_time() - t0
                tot = acc.setdefault(lab, [0.0, 0.0])
                tot[0] += cpu - inner
                tot[1] += free
                if stack:
                    stack[-1][2] += cpu
                if label == "integrator":
                    steps.append([t0, None])
                elif label == "HDF5 files":
                    steps[-1][1] = time.thread_time()
        return wrapped

    def gil_free(fn):
        def wrapped(*a, **k):
            t0 = time.thread_time()
            try:
                return fn(*a, **k)
            finally:
                if stack:
                    stack[-1][3] += time.thread_time() - t0
        return wrapped

    saved = []
    for mod, name in _GIL_FREE:
        fn = getattr(mod, name)
        if hasattr(fn, "targetoptions") and not fn.targetoptions.get("nogil"):
            raise RuntimeError(f"{name} is not compiled with nogil=True")
        saved.append((mod, name, fn))
        setattr(mod, name, gil_free(fn))
    for mod, name, label in _PHASES:
        fn = getattr(mod, name)
        saved.append((mod, name, fn))
        setattr(mod, name, phase(fn, label))
    try:
        with tempfile.TemporaryDirectory() as tmp:
            cold_theory()
            c0 = time.process_time()
            run_simulation(config, Path(tmp) / "exp", seed=seed, fmt="hdf5", progress=False,
                           workers=1)
            total = time.process_time() - c0
    finally:
        for mod, name, fn in reversed(saved):
            setattr(mod, name, fn)
    phases = {label: tuple(acc.get(label, (0.0, 0.0))) for _m, _n, label in _PHASES}
    inside = sum(cpu for cpu, _free in phases.values())
    phases["run set-up, truth.json, manifest"] = (max(total - inside, 0.0), 0.0)
    step_max = max((b - a for a, b in steps if b is not None), default=0.0)
    return CpuSplit(phases, total, step_max)


def print_split(split: CpuSplit, rec_s: float) -> None:
    """The CPU split of one run and the Amdahl projection from it."""
    print(f"CPU of one run (one worker thread): {split.total_s:.3f} s, of which GIL-free "
          f"{split.parallel_s:.3f} s and serial (GIL held) {split.serial_s:.3f} s "
          f"({100 * split.serial_s / split.total_s:.0f} %); longest step "
          f"{split.step_max_s:.3f} s")
    for label, (cpu, free) in split.phases.items():
        print(f"  {label:42s} {1e3 * cpu:6.1f} ms CPU, {1e3 * (cpu - free):6.1f} ms serial")
    print(f"PROJECTION (Amdahl, from the measured {split.parallel_s:.3f} s parallel and "
          f"{split.serial_s:.3f} s serial CPU; the longest step {split.step_max_s:.3f} s "
          "bounds any core count; not measured):")
    for n in (1, 2, 4, 8, 16):
        amdahl = max(split.serial_s + split.parallel_s / n, split.step_max_s)
        best = max(split.serial_s, split.total_s / n, split.step_max_s)
        print(f"  {n:2d} cores: {rec_s / amdahl:5.0f} x real time (serial part never "
              f"overlapped) to {rec_s / best:5.0f} x (serial part fully overlapped)")


def threads_speedup(config, repeat: int, rec_s: float) -> None:
    """Wall seconds of ``run_simulation`` (HDF5) on 1 and on 2 worker threads, alternated,
    and the serial share Amdahl's law infers from them: ``s = 2*T2/T1 - 1``."""
    if len(os.sched_getaffinity(0)) < 2:
        print("threads 1 vs 2: needs 2 CPUs")
        return
    walls = {1: [], 2: []}
    for _ in range(repeat):
        for w in (1, 2):
            with tempfile.TemporaryDirectory() as tmp:
                cold_theory()
                t0 = time.perf_counter()
                run_simulation(config, Path(tmp) / "exp", seed=0, fmt="hdf5", progress=False,
                               workers=w)
                walls[w].append(time.perf_counter() - t0)
    t1, t2 = min(walls[1]), min(walls[2])
    print(f"threads 1 vs 2 (HDF5, best of {repeat}): {rec_s / t1:.0f} x and {rec_s / t2:.0f} x "
          f"real time -> speed-up {t1 / t2:.2f}, serial share (Amdahl) {2 * t2 / t1 - 1:.2f}")


def fresh_process(repeat: int, rec_s: float) -> None:
    """Wall seconds of ``torquemod simulate --format hdf5`` in a new process (what a user
    starting the CLI waits for: imports, loading the compiled kernels, the run), and of the
    bare ``import torquemod.twins.vtrack.simulate`` in a new process."""
    cli = Path(sys.executable).with_name("torquemod")
    if not cli.exists():
        print("fresh process: no torquemod console script next to this Python")
        return
    walls, imports = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeat):
            t0 = time.perf_counter()
            subprocess.run([str(cli), "simulate", "--out", str(Path(tmp) / "exp"), "--format",
                            "hdf5", "--force", "--quiet"], check=True, capture_output=True)
            walls.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", "import torquemod.twins.vtrack.simulate"],
                           check=True)
            imports.append(time.perf_counter() - t0)
    print(f"fresh process: torquemod simulate --format hdf5 {min(walls):.2f} s wall -> "
          f"{rec_s / min(walls):.0f} x real time, of which starting Python and importing "
          f"torquemod.twins.vtrack.simulate {min(imports):.2f} s")


def _report(label: str, sim_s: float, walls: list[float], what: str) -> None:
    runs = ", ".join(f"{w:.2f} s" for w in walls)
    best = min(walls)
    print(f"{label}: {sim_s:.1f} s {what} in {best:.2f} s wall -> {sim_s / best:.0f} x real "
          f"time" + (f"  (runs: {runs})" if len(walls) > 1 else ""))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=1, help="runs per measurement (best shown)")
    ap.add_argument("--points", type=int, default=16,
                    help="sweep points of the batch measurement (0: skip it)")
    ap.add_argument("--cores", type=int, default=0,
                    help="pin the process to this many CPUs (0: leave as it is)")
    ap.add_argument("--batch-only", action="store_true",
                    help="only the batch measurement (after the warm-up)")
    ap.add_argument("--samples-per-step", type=int, default=0,
                    help="batch: this recorded step instead of the configured one, set past "
                         "the step guard (0: as configured)")
    ap.add_argument("--with-sensors", action="store_true",
                    help="only the twin as a sweep point runs it (simulate_run with sensors) "
                         "against simulate_batch (truth only), on the example sweep's points")
    args = ap.parse_args()
    if args.cores > 0:
        os.sched_setaffinity(0, set(sorted(os.sched_getaffinity(0))[:args.cores]))
    print(f"CPUs available to this process: {len(os.sched_getaffinity(0))}")
    config = load_config()
    proc = config.procedure
    print(f"warm-up: kernels (numba compile or cache load) {warm_up(config):.2f} s, then a "
          f"short first run_simulation {first_run(config):.2f} s -- not counted below")
    print(f"step: {proc.samples_per_step} sample(s) per {proc.substeps} RK4 step(s) at "
          f"{config.sensors.sample_rate_hz:g} Hz")
    if args.with_sensors:
        with_sensors(args.points if args.points > 0 else 6, max(args.repeat, 1))
        return
    if args.batch_only:
        batch_throughput(batch_configs(args.points, args.samples_per_step), args.repeat)
        return
    for coarse in (False, True):
        walls = []
        for _ in range(args.repeat):
            sim_s, wall = integrator_throughput(config, coarse)
            walls.append(wall)
        _report("integrator" + (", coarse settling" if coarse else ", settling at the "
                                "recorded step"), sim_s, walls, "of rig time (settling included)")
    for fmt in ("hdf5", "csv"):
        walls = []
        for _ in range(args.repeat):
            with tempfile.TemporaryDirectory() as tmp:
                cold_theory()
                t0 = time.perf_counter()
                truth = run_simulation(config, Path(tmp) / "exp", seed=0, fmt=fmt,
                                       progress=False)
                walls.append(time.perf_counter() - t0)
        n_rec = sum(1 for s in truth["steps"] if not s["slipped"])
        rec_s = n_rec * proc.cycles_per_step * config.rig.revolution_s
        _report(f"run_simulation ({fmt})", rec_s, walls,
                f"recorded (7 columns at {config.sensors.sample_rate_hz:g} Hz)")
    splits = [cpu_split(config) for _ in range(args.repeat)]
    print_split(min(splits, key=lambda sp: sp.total_s), rec_s)
    threads_speedup(config, args.repeat, rec_s)
    fresh_process(args.repeat, rec_s)
    if args.points > 0:
        batch_throughput(batch_configs(args.points), args.repeat)


if __name__ == "__main__":
    main()
