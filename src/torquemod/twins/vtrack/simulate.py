"""``torquemod simulate``: run the V-Track digital twin and write an experiment folder.

Public entry points (the CLI in :mod:`torquemod.cli` only parses arguments and calls these):

* :func:`default_config_text` -- the commented default TOML (package data
  ``torquemod/data/vtrack_default.toml``),
* :func:`load_config` -- default config, optionally overridden by a user TOML file,
* :func:`run_simulation` -- simulate the procedure and write ``experiment.toml``, one file per
  recording and ``truth.json`` (the simulated ground truth per step),
* :func:`simulate_batch` (from :mod:`torquemod.twins.vtrack.rig.batch`) -- the ground truth of many
  configurations (sweep points) at once, without sensors or files.

The torque steps run side by side on a pool of threads, one per CPU up to one per step (each
integrates a step and draws its truth, noise and files; step 1 starts while the other steps
are planned): every step starts from the steady state of the torque before it
(:mod:`torquemod.twins.vtrack.rig.steps`), which moves the simulated phases by < 1e-6 deg against
running
the steps one after the other. Most of a step's work runs in compiled kernels that release
the GIL (integrator, truth sums, the theory's Newton solve, noise, sample times) and the
files' values are copied in by ``os.pwrite`` after h5py has closed them; what holds the GIL
(h5py's metadata through its low-level calls, the theory's set-up, the run's set-up) is
~12 % of a run's CPU (benchmarks/simulate.py prints the split and the projection to more
cores).
The sensor noise of each step comes from its own stream (an SFC64 child of the seed's, which
seeds the compiled splitmix64/ziggurat generator of :mod:`torquemod.twins.vtrack.rig.noise` per
channel),
so a run is deterministic for its seed whatever the threads' timing. The settling before the
recorded revolutions is integrated at the longest stable RK4 step without output samples
(:func:`torquemod.twins.vtrack.rig.steps.integrate_step`).

``truth.json`` holds the run's speed-loop wobble (``speed_wobble``: configuration, realised
terms, reference RMS) and per step the steady state, the theory phases and what was simulated
(``simulated``: means, CoA, the phase with the wobble fitted out, the platform speed's RMS
variation), also per platform revolution (``simulated.cycles``).

Recordings of a step in which the wheel slips are *not* written; the step appears in
``truth.json`` with ``slipped = true`` and the procedure stops there (as the paper's test did).
"""

from __future__ import annotations

import itertools
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict
from pathlib import Path

import numba
import numpy as np

from torquemod import __version__
from torquemod._util.fsutil import atomic_dir
from torquemod._util.jsonutil import dump_json
from torquemod.errors import InputError
from torquemod.io import write_manifest, write_recording
from torquemod.io.experiment import Recording
from torquemod.twins.vtrack.params import (  # noqa: F401 - MAX_LAMBDA_H, stiffest_rate re-exported
    MAX_LAMBDA_H,
    SimConfig,
    stiffest_rate,
)
from torquemod.twins.vtrack.rig.batch import (  # noqa: F401 - BatchPoint, simulate_batch re-exported
    BatchPoint,
    default_workers,
    plan_run,
    simulate_batch,
)
from torquemod.twins.vtrack.rig.dynamics import OUT_COLUMNS, pack_parameters
from torquemod.twins.vtrack.rig.sensors import measure
from torquemod.twins.vtrack.rig.simrun import SimulatedRun
from torquemod.twins.vtrack.rig.steps import integrate_step
from torquemod.twins.vtrack.rig.truth import recorded_step_truth, step_truth, wobble_truth
from torquemod.twins.vtrack.rig.truthphase import (  # noqa: F401 - re-exported
    sine_fit_phase_deg,
    wobble_free_phase_deg,
)
from torquemod.twins.vtrack.simconfig import (  # noqa: F401 - re-exported
    config_from_dict,
    default_config_text,
    load_config,
)
from torquemod.twins.vtrack.theory import creep_curve_peak

_COL = {name: i for i, name in enumerate(OUT_COLUMNS)}
_SUFFIX = {"csv": ".csv", "hdf5": ".h5"}


# --------------------------------------------------------------------------------------------
# Simulation
# --------------------------------------------------------------------------------------------

@numba.njit(cache=True, nogil=True)
def _sample_times(t0_s, fs_hz, out):
    """``out[k] = t0_s + k/fs_hz`` [s]: :meth:`Recording.time_s`, value for value (the same
    two IEEE operations per sample), without the GIL."""
    for k in range(out.size):
        out[k] = t0_s + k / fs_hz


class _TwinRecording(Recording):
    """A :class:`Recording` whose sample times come from a compiled kernel that releases the
    GIL (the files of several steps are written side by side)."""

    def time_s(self) -> np.ndarray:
        out = np.empty(self.n_samples)
        _sample_times(float(self.t0_s), float(self.fs_hz), out)
        return out


def _step_pieces(plan, channels: dict, bounds: list[int], fs: float,
                 files_per_cycle: bool) -> list[tuple[dict, _TwinRecording]]:
    """A step's sensor ``channels`` (sample 0 at ``bounds[0]`` of the step) cut into one
    recording per revolution or one per step, each with its ``[[recording]]`` entry (the
    ``file`` without its suffix)."""
    dt = 1.0 / fs
    spans = (list(itertools.pairwise(bounds)) if files_per_cycle
             else [(bounds[0], bounds[-1])])
    pieces = []
    for j, (a, b) in enumerate(spans, start=1):
        sl = slice(a - bounds[0], b - bounds[0])
        rec = _TwinRecording({k: v[sl] for k, v in channels.items()}, fs_hz=fs,
                             t0_s=plan.t0_s + a * dt, source="torquemod simulate")
        entry = {"step": plan.index, "dc_torque_nm": plan.dc_nm,
                 "file": f"step{plan.index:02d}_cycle{j}" if files_per_cycle
                 else f"step{plan.index:02d}"}
        if files_per_cycle:
            entry["cycle"] = j
        pieces.append((entry, rec))
    return pieces


def _write_step(folder: Path, pieces: list[tuple[dict, Recording]], fmt: str) -> list[dict]:
    """Write a step's recordings (:func:`_step_pieces`) into ``folder``; return their
    ``[[recording]]`` entries with the files' names."""
    recs = []
    for entry, rec in pieces:
        file = entry["file"] + _SUFFIX[fmt]
        if fmt == "hdf5":  # the values copied in after h5py closes the file: no GIL held
            write_recording(folder / file, rec, fmt=fmt, write_time=True,
                            data_after_close=True)
        else:
            write_recording(folder / file, rec, fmt=fmt)
        recs.append({**entry, "file": file})
    return recs


class _NoProgress:
    """A progress bar that shows nothing (``progress=False``)."""

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def _simulate(config: SimConfig, folder: Path | None, *, seed: int, fmt: str | None,
              progress: bool, files_per_cycle: bool, workers: int | None = None,
              large_signal: bool = True, statistics: bool = True) -> dict | SimulatedRun:
    """The run: each step's recordings written into ``folder`` as soon as the step is
    done (returns the truth), or kept in memory when ``folder`` is None (returns the
    :class:`SimulatedRun`)."""
    rig, mod, proc = config.rig, config.modulation, config.procedure
    fs = config.sensors.sample_rate_hz
    dt = 1.0 / fs
    params = pack_parameters(rig, config.disturbances)
    torques = proc.dc_torques_nm
    # one wobble for the whole run: the rig's speed loop runs on across the steps (redrawn
    # per step, the reference would jump by up to ~1 % of the speed at every step change);
    # the sensor noise has one stream per step (children of the seed's), so that the steps
    # can be finished in any order and the run stays deterministic; every step starts from
    # the steady state of the torque before (rig/steps.py), so that they run side by side:
    # each worker integrates a step and finishes it (truth, noise, files)
    if progress:  # tqdm imported only when shown (~7 ms of a quiet process's start)
        from torquemod._util.progress import WarmupBar

        bar = WarmupBar(total=len(torques), desc="simulate", unit="step", file=sys.stderr)
    else:
        bar = _NoProgress()

    # the first step known to have slipped: the run ends there, so a later step that starts,
    # or finishes integrating, after it is skipped (never read; its files never written)
    first_slip = [len(torques) + 1]
    skipped = (None, [], None, None)

    def run(rp, plan, before):
        start = None if plan.y0 is not None else before.result()[2]
        if first_slip[0] < plan.index or (plan.y0 is None and start is None):
            bar.update(1)
            return skipped
        out, n_done, slipped, y_end = integrate_step(config, params, rp.wobble, plan,
                                                     rp.n_step, start, rp.n_settle)
        bar.update(1)
        if slipped:
            first_slip[0] = min(first_slip[0], plan.index)
            return None, [], y_end, plan.t0_s + n_done * dt
        if first_slip[0] < plan.index:
            return skipped
        # (offering a step's truth to the pool while its thread draws the noise and writes
        # the files was tried in an earlier version: 2 cores, 30 alternations, median
        # 271 against 248 ms a run -- two threads wanting the GIL at once wait for each
        # other's switch interval)
        entry, bounds = recorded_step_truth(plan.index, plan.dc_nm, config, out, n_done,
                                            plan.t0_s, rp.wobble, rp.n_settle, large_signal,
                                            statistics)
        noise_rng = np.random.Generator(np.random.SFC64(rp.noise_seeds[plan.index - 1]))
        channels = measure(out[bounds[0]:bounds[-1]], disturbances=config.disturbances,
                           sensors=config.sensors, rng=noise_rng)
        pieces = _step_pieces(plan, channels, bounds, fs, files_per_cycle)
        if folder is not None:
            return entry, _write_step(folder, pieces, fmt), y_end, None
        return entry, pieces, y_end, None

    steps, recordings = [], []
    slip_step = slip_time = None
    # threads that integrate and finish steps at once (the compiled integrator, noise and
    # truth kernels and the files' data writes release the GIL): the CPUs this process may
    # use, at most one per step
    pool = ThreadPoolExecutor(max_workers=workers or min(len(torques), default_workers()))
    futures = []
    with pool:
        # step 1 starts integrating as soon as its plan is known, while the others are
        # planned (their operating points and the speed loop's reference angle, ~6 ms)
        rp = plan_run(config, seed,
                      first=lambda head, plan: futures.append(pool.submit(run, head, plan,
                                                                          None)))
        wobble, plans = rp.wobble, rp.steps
        for plan in plans[1:]:  # in step order: a step waiting for the one before never blocks
            futures.append(pool.submit(run, rp, plan, futures[-1]))
        try:
            for plan, fut in zip(plans, futures, strict=True):
                entry, recs, _y, t_slip = fut.result()
                if entry is None:
                    slip_step, slip_time = plan.index, t_slip
                    break
                steps.append(entry)
                recordings.extend(recs)
        finally:
            for fut in futures:  # the steps after a slip are not needed
                fut.cancel()
    if slip_step is not None and folder is not None:
        # files of steps after the slip that ran anyway are not part of the experiment
        for fut in futures[slip_step:]:
            if not fut.cancelled() and fut.exception() is None:
                for rec in fut.result()[1]:
                    (folder / rec["file"]).unlink(missing_ok=True)
    if slip_step is not None:
        steps.append(step_truth(slip_step, torques[slip_step - 1], config, None, True))
        steps[-1]["slip_time_s"] = slip_time
    bar.close()
    xi_peak, t_peak = creep_curve_peak(rig)
    truth = {
        "generator": "torquemod simulate", "version": __version__, "seed": seed,
        "format": fmt, "modulation_frequency_actual_hz": mod.actual_frequency_hz,
        "sample_rate_hz": fs, "slip_step": slip_step,
        "creep_curve_peak": {"creepage": xi_peak, "torque_nm": t_peak,
                             "coa": t_peak / (rig.wheel_radius_m * rig.normal_load_n)},
        "speed_wobble": wobble_truth(config, wobble),
        "steps": steps, "parameters": asdict(config),
    }
    manifest_rig = {"wheel_radius_m": rig.wheel_radius_m,
                    "platform_radius_m": rig.platform_radius_m,
                    # inertia between the torque sensor and the contact: sets the theory
                    # constant
                    "wheel_inertia_kg_m2": rig.wheel_inertia_kg_m2}
    test = {"normal_load_n": rig.normal_load_n, "modulation_frequency_hz": mod.frequency_hz,
            "modulation_amplitude_nm": mod.amplitude_nm}
    extra = {"simulation": {"generator": "torquemod simulate", "version": __version__,
                            "seed": seed, "slip_step": slip_step or 0, "truth": "truth.json"}}
    if folder is None:
        return SimulatedRun(truth, manifest_rig, test, extra,
                            tuple(e for e, _ in recordings), tuple(r for _, r in recordings))
    write_manifest(folder / "experiment.toml", rig=manifest_rig, test=test,
                   recordings=recordings, extra=extra)
    (folder / "truth.json").write_text(dump_json(truth), encoding="utf-8")
    return truth


def run_simulation(config: SimConfig, out_dir: Path, *, seed: int = 0, fmt: str = "csv",
                   progress: bool = True, files_per_cycle: bool = True,
                   force: bool = False, workers: int | None = None) -> dict:
    """Simulate ``config`` and write the experiment folder ``out_dir``.

    The folder is written into a temporary sibling and renamed into place at the end, so an
    interrupted run leaves no half-written experiment.

    Parameters
    ----------
    config : SimConfig
        The rig, the contact and the test programme (SI units; :func:`load_config`).
    out_dir : str or os.PathLike
        The experiment folder to write (``experiment.toml`` and the recordings).
    seed : int, default 0
        Seed of the noise; the run is deterministic for a given seed, for any ``workers``.
    fmt : {"csv", "hdf5"}, default "csv"
        Recording format.
    progress : bool, default True
        Show a progress bar on stderr.
    files_per_cycle : bool, default True
        One recording per modulation cycle rather than one per step.
    force : bool, default False
        Replace an existing non-empty ``out_dir``.
    workers : int, optional
        Threads that run the steps side by side; default the CPUs available, at most one
        per step; 1 runs them one after the other (e.g. inside a process pool).

    Returns
    -------
    dict
        The simulation's truth, also written as ``truth.json``: per-step truth
        (``steps``), the creep curve's peak (creepage [-], torque [N*m], CoA [-]), the
        actual modulation frequency [Hz], the sample rate [Hz], the slip step (or None),
        the speed wobble and the parameters.

    Raises
    ------
    InputError
        Unknown ``fmt``.
    OutputError
        ``out_dir`` exists and is not empty (without ``force``).
    """
    if fmt not in _SUFFIX:
        raise InputError(f"unknown output format '{fmt}'", hint="use csv or hdf5")
    out_dir = Path(out_dir)
    with atomic_dir(out_dir, force=force) as tmp:
        truth = _simulate(config, tmp, seed=seed, fmt=fmt, progress=progress,
                          files_per_cycle=files_per_cycle, workers=workers)
    return truth


def simulate_run(config: SimConfig, *, seed: int = 0, files_per_cycle: bool = True,
                 workers: int | None = None, large_signal: bool = True,
                 statistics: bool = True) -> SimulatedRun:
    """Simulate ``config`` as :func:`run_simulation` does and keep the experiment in memory.

    Parameters
    ----------
    config : SimConfig
        The twin's configuration (:func:`load_config`).
    seed : int
        The run's seed: the same seed gives the same recordings and truth as
        :func:`run_simulation` (value for value).
    files_per_cycle : bool
        One recording per platform revolution (else one per torque step).
    workers : int, optional
        Threads that run the torque steps side by side (default: the CPUs available).
    large_signal : bool
        False leaves each step's large-signal theory phase out of the truth (None), for a
        caller that solves the theory itself (a sweep's theory columns; ~7 ms a step).
    statistics : bool
        False keeps of what each step simulated only its phase (``simulated`` holds
        ``phase_deg`` alone, the same value): no means, CoA, variations or per-revolution
        entries, for a caller that reads only the phase (a sweep's rows; ~1 ms a step).

    Returns
    -------
    SimulatedRun
        The recordings, manifest tables and truth; ``write(folder)`` gives the folder
        :func:`run_simulation` writes, ``experiment()`` and ``recording(exp, entry)`` feed
        the processing chain without files.
    """
    return _simulate(config, None, seed=seed, fmt=None, progress=False,
                     files_per_cycle=files_per_cycle, workers=workers,
                     large_signal=large_signal, statistics=statistics)

