"""Batch mode of the twin: many configurations (sweep points) advanced together, truth only.

:func:`simulate_batch` runs the procedure of every configuration without sensors or files
and returns per point what ``truth.json`` records per step (the simulated phase with the wobble
fitted out, means, CoA, theory; :mod:`torquemod.twins.vtrack.rig.truth`) -- what a sweep
compares. Every torque step of every point is one piece of work (each step starts from the
steady state of the torque before, :mod:`torquemod.twins.vtrack.rig.steps`); groups of
``lanes`` steps, of one point or of several, are integrated side by side in one compiled loop
over a structure of arrays (:mod:`torquemod.twins.vtrack.rig.lanes`), and the groups run on a
pool of threads: the compiled integrator releases the GIL, so they advance together on all
cores. The steps are dealt step by step across the points, and a step that starts (or
finishes integrating) after an earlier step of its point slipped is skipped: the point's
truth ends at its first slip.

For the same ``seed`` a point's steps are those of
:func:`torquemod.twins.vtrack.simulate.run_simulation`
(the same wobble, generator phases and integration), number for number.
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from torquemod.errors import InputError
from torquemod.twins.vtrack.params import SimConfig
from torquemod.twins.vtrack.rig.dynamics import pack_parameters, wobble_table
from torquemod.twins.vtrack.rig.steps import (
    StepJob,
    StepPlan,
    integrate_step,
    integrate_steps,
    plan_steps,
    steps_buffer_shape,
)
from torquemod.twins.vtrack.rig.truth import recorded_step_truth, step_truth, wobble_truth
from torquemod.twins.vtrack.theory import creep_curve_peak


@dataclass(frozen=True)
class BatchPoint:
    """The truth of one configuration of a batch.

    Attributes
    ----------
    seed : int
        The point's seed.
    steps : list of dict
        As ``truth.json``'s: one dict per step up to and including the first that slips.
    slip_step : int or None
        The step that slipped; None: none.
    slip_time_s : float or None
        When it slipped [s]; None without slip.
    speed_wobble : dict
        The run's speed-wobble record (:func:`~torquemod.twins.vtrack.rig.truth.wobble_truth`).
    creep_curve_peak : dict
        The creep curve's peak: ``creepage`` [-], ``torque_nm`` [N*m], ``coa`` [-].
    """

    seed: int
    steps: list[dict]
    slip_step: int | None
    slip_time_s: float | None
    speed_wobble: dict
    creep_curve_peak: dict

    def phases_deg(self) -> list[float]:
        """Simulated phase [deg] of each step that did not slip, in step order."""
        return [s["simulated"]["phase_deg"] for s in self.steps if not s["slipped"]]


#: what a step skipped after its point's first slip stands for (never read)
_SKIPPED = (None, None, None)


def default_workers() -> int:
    """Threads for the batch: the CPUs this process may use.

    Returns
    -------
    int
        At least 1.
    """
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class RunPlan:
    """What one run of a configuration draws from its seed and plans before integrating.

    Attributes
    ----------
    wobble : ndarray
        The speed loop's wobble rows (:func:`~torquemod.twins.vtrack.rig.wobble.wobble_table`).
    noise_seeds : list of numpy.random.SeedSequence
        The sensor-noise seeds, one per step.
    steps : list of StepPlan
        The steps (:func:`~torquemod.twins.vtrack.rig.steps.plan_steps`).
    n_settle : int
        Settling samples per step [-].
    n_step : int
        Samples integrated per step [-].
    """

    wobble: np.ndarray
    noise_seeds: list[np.random.SeedSequence]
    steps: list[StepPlan]
    n_settle: int
    n_step: int


def plan_run(config: SimConfig, seed: int,
             first: Callable[[RunPlan, StepPlan], None] | None = None) -> RunPlan:
    """The :class:`RunPlan` of ``config`` for ``seed`` (shared by
    :func:`torquemod.twins.vtrack.simulate.run_simulation` and :func:`simulate_batch`): the wobble
    drawn
    first, then the noise streams spawned (no draw), then one generator phase per step.
    ``first`` is called with the plan so far (no steps yet) and the first step's plan as
    soon as they are known (:func:`~torquemod.twins.vtrack.rig.steps.plan_steps`), so that the
    caller can
    start integrating step 1 while the other steps are planned.

    Parameters
    ----------
    config : SimConfig
        The twin's configuration.
    seed : int
        The run's seed.
    first : callable or None
        ``first(plan_so_far, first_step)``. Default None.

    Returns
    -------
    RunPlan
        The plan.
    """
    proc, fs = config.procedure, config.sensors.sample_rate_hz
    rng = np.random.default_rng(seed)
    wobble = wobble_table(config.disturbances, config.rig.platform_speed_rad_s, rng)
    noise_seeds = rng.bit_generator.seed_seq.spawn(1)[0].spawn(len(proc.dc_torques_nm))
    phases = [float(rng.uniform(0.0, 2.0 * np.pi)) if config.modulation.random_phase else 0.0
              for _ in proc.dc_torques_nm]
    n_settle = round(proc.settle_s * fs)
    n_rec = math.ceil((proc.cycles_per_step * config.rig.revolution_s * 1.01 + 0.1) * fs)
    hook = None
    if first is not None:
        head = RunPlan(wobble, noise_seeds, [], n_settle, n_settle + n_rec)

        def hook(plan: StepPlan) -> None:
            first(head, plan)
    return RunPlan(wobble, noise_seeds,
                   plan_steps(config, wobble, phases, n_settle + n_rec, hook),
                   n_settle, n_settle + n_rec)


#: torque steps integrated side by side in one compiled loop by :func:`simulate_batch`
#: (:mod:`torquemod.twins.vtrack.rig.lanes`). Measured on 16 default points (2 shared cores,
#: alternated): 2 lanes cost 3-4 % more CPU than 1, 4 lanes ~15 % more -- one RK4 step is
#: bound by its work, not by the latency of its chain of contact evaluations, so
#: interleaving scalar steps gains nothing (docs/performance.md)
DEFAULT_LANES = 1


def simulate_batch(configs: Sequence[SimConfig], *, seed: int | Sequence[int] = 0,
                   workers: int | None = None, large_signal: bool = True,
                   lanes: int | None = None) -> list[BatchPoint]:
    """Simulate every configuration of ``configs``
    (:class:`~torquemod.twins.vtrack.params.SimConfig`,
    e.g. from :func:`torquemod.twins.vtrack.simulate.load_config` with a point's overrides) and
    return
    their truth in the same order. ``seed``: one for all points or one per point (the speed
    loop's wobble and the generator phases are drawn from it as in ``run_simulation``).
    ``workers``: threads (default: the CPUs available). ``large_signal = False`` leaves
    each step's ``phase_large_signal_deg`` out (None) for a caller that solves the theory
    itself (a sweep's theory columns): ~7 ms less per step (the twin's step costs ~55 ms).

    Parameters
    ----------
    configs : sequence of SimConfig
        The configurations.
    seed : int or sequence of int
        One seed for all points or one per point. Default 0.
    workers : int or None
        Threads; None: the CPUs available.
    large_signal : bool
        Solve each step's large-signal theory phase. Default True.
    lanes : int or None
        Torque steps (of one point or of several) integrated together in one compiled
        loop (:func:`~torquemod.twins.vtrack.rig.steps.integrate_steps`); None:
        :data:`DEFAULT_LANES`. Every step's numbers are those of the step integrated alone.

    Returns
    -------
    list of BatchPoint
        In the order of ``configs``.

    Raises
    ------
    InputError
        A seed list of another length than ``configs``.
    """
    configs = list(configs)
    seeds = [int(seed)] * len(configs) if np.ndim(seed) == 0 else [int(s) for s in seed]
    if len(seeds) != len(configs):
        raise InputError(f"simulate_batch got {len(seeds)} seeds for {len(configs)} "
                         "configurations", hint="give one seed, or one per configuration")
    n_lanes = max(1, int(lanes or DEFAULT_LANES))
    points = [(config, plan_run(config, s), pack_parameters(config.rig, config.disturbances))
              for config, s in zip(configs, seeds, strict=True)]

    # the first step known to have slipped, per point: its later steps are never read (the
    # point's truth ends at its first slip), so a step that starts, or finishes integrating,
    # after an earlier step of its point slipped is skipped (the numbers of the steps that
    # are read do not depend on it)
    first_slip: dict[int, int] = {}
    lock = threading.Lock()

    def after_slip(point, plan) -> bool:
        return first_slip.get(id(point), plan.index) < plan.index

    def finish(point, plan, result):
        config, rp, _ = point
        out, n_done, slipped, y_end = result
        if slipped:
            with lock:
                first_slip[id(point)] = min(first_slip.get(id(point), plan.index), plan.index)
            return None, plan.t0_s + n_done * (1.0 / config.sensors.sample_rate_hz), y_end
        if after_slip(point, plan):
            return _SKIPPED
        entry, _ = recorded_step_truth(plan.index, plan.dc_nm, config, out, n_done, plan.t0_s,
                                       rp.wobble, rp.n_settle, large_signal)
        return entry, None, y_end

    local = threading.local()  # each thread's sample buffer, reused from group to group

    def run_group(group):
        todo = [q for q, (pt, plan) in enumerate(group) if not after_slip(pt, plan)]
        done = [_SKIPPED] * len(group)
        if not todo:
            return done
        jobs = [StepJob(pt[0], pt[2], pt[1].wobble, plan, pt[1].n_step, None, pt[1].n_settle)
                for pt, plan in (group[q] for q in todo)]
        shape = steps_buffer_shape(jobs)
        buf = getattr(local, "buf", None)
        if buf is None or buf.shape != shape:
            local.buf = buf = np.empty(shape)
        results = integrate_steps(jobs, buf)
        for q, res in zip(todo, results, strict=True):
            done[q] = finish(*group[q], res)
        return done

    def run_chained(point, plan, before):
        config, rp, params = point
        if after_slip(point, plan):
            return [_SKIPPED]
        start = before()[2]
        if start is None or after_slip(point, plan):
            return [_SKIPPED]
        res = integrate_step(config, params, rp.wobble, plan, rp.n_step, start, rp.n_settle)
        return [finish(point, plan, res)]

    results = []
    with ThreadPoolExecutor(max_workers=workers or default_workers()) as pool:
        # every step with its own start state goes to a group of lanes, step by step across
        # the points (a point's steps run apart in time, so that a slip is known before
        # the point's later steps start; steps of one index have the same length); a step
        # that starts where the one before ended is submitted after it, so that waiting for
        # it never blocks
        free = sorted(((pt, plan) for pt in points for plan in pt[1].steps
                       if plan.y0 is not None), key=lambda item: item[1].index)
        where = {}
        for g in range(0, len(free), n_lanes):
            group = free[g:g + n_lanes]
            fut = pool.submit(run_group, group)
            for q, (pt, plan) in enumerate(group):
                where[id(pt), plan.index] = (fut, q)

        def getter(key):
            fut, q = where[key]
            return lambda: fut.result()[q]

        for pt in points:
            for plan in pt[1].steps:
                if plan.y0 is None:
                    before = getter((id(pt), plan.index - 1))
                    where[id(pt), plan.index] = (pool.submit(run_chained, pt, plan, before), 0)
        try:
            for point, s in zip(points, seeds, strict=True):
                config, wobble = point[0], point[1].wobble
                steps, slip_step, slip_time = [], None, None
                for plan in point[1].steps:
                    entry, t_slip, _ = getter((id(point), plan.index))()
                    if entry is None:
                        slip_step, slip_time = plan.index, t_slip
                        entry = step_truth(plan.index, plan.dc_nm, config, None, True,
                                           large_signal=large_signal)
                        entry["slip_time_s"] = t_slip
                        steps.append(entry)
                        break
                    steps.append(entry)
                xi_peak, t_peak = creep_curve_peak(config.rig)
                rig = config.rig
                results.append(BatchPoint(
                    seed=s, steps=steps, slip_step=slip_step, slip_time_s=slip_time,
                    speed_wobble=wobble_truth(config, wobble),
                    creep_curve_peak={"creepage": xi_peak, "torque_nm": t_peak,
                                      "coa": t_peak / (rig.wheel_radius_m
                                                       * rig.normal_load_n)}))
        finally:
            for fut, _ in where.values():
                fut.cancel()
    return results
