"""``torquemod simulate``: run the V-Track digital twin and write an experiment folder.

Public entry points (the CLI in :mod:`torquemod.cli` only parses arguments and calls these):

* :func:`default_config_text` -- the commented default TOML (package data
  ``torquemod/data/vtrack_default.toml``),
* :func:`load_config` -- default config, optionally overridden by a user TOML file,
* :func:`run_simulation` -- simulate the procedure and write ``experiment.toml``, one file per
  recording and ``truth.json`` (the simulated ground truth per step),
* :func:`simulate_batch` (from :mod:`torquemod.rig.batch`) -- the ground truth of many
  configurations (sweep points) at once, without sensors or files.

The torque steps run side by side on a pool of threads, one per CPU up to one per step (each
integrates a step and draws its truth, noise and files; step 1 starts while the other steps
are planned): every step starts from the steady state of the torque before it
(:mod:`torquemod.rig.steps`), which moves the simulated phases by < 1e-6 deg against running
the steps one after the other. Most of a step's work runs in compiled kernels that release
the GIL (integrator, truth sums, the theory's Newton solve, noise, sample times) and the
files' values are copied in by ``os.pwrite`` after h5py has closed them; what holds the GIL
(h5py's metadata through its low-level calls, the theory's set-up, the run's set-up) is
~12 % of a run's CPU (benchmarks/simulate.py prints the split and the projection to more
cores).
The sensor noise of each step comes from its own stream (an SFC64 child of the seed's, which
seeds the compiled splitmix64/ziggurat generator of :mod:`torquemod.rig.noise` per channel),
so a run is deterministic for its seed whatever the threads' timing. The settling before the
recorded revolutions is integrated at the longest stable RK4 step without output samples
(:func:`torquemod.rig.steps.integrate_step`).

``truth.json`` holds the run's speed-loop wobble (``speed_wobble``: configuration, realised
terms, reference RMS) and per step the steady state, the theory phases and what was simulated
(``simulated``: means, CoA, the phase with the wobble fitted out, the platform speed's RMS
variation), also per platform revolution (``simulated.cycles``).

Recordings of a step in which the wheel slips are *not* written; the step appears in
``truth.json`` with ``slipped = true`` and the procedure stops there (as the paper's test did).
"""

from __future__ import annotations

import copy
import itertools
import math
import sys
import tomllib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, replace
from importlib import resources
from pathlib import Path

import numba
import numpy as np

from . import __version__
from .checks import positive_number
from .contact.hertz import hertz_ellipse
from .contact.kalker import kalker_coefficients
from .contact.presets import polach_preset
from .data import Recording
from .errors import InputError
from .fsutil import atomic_dir
from .io import write_manifest, write_recording
from .jsonutil import dump_json
from .rig.batch import (  # noqa: F401 - BatchPoint, simulate_batch re-exported
    BatchPoint,
    default_workers,
    plan_run,
    simulate_batch,
)
from .rig.dynamics import OUT_COLUMNS, pack_parameters
from .rig.params import (
    ContactParams,
    DisturbanceParams,
    ModulationParams,
    ProcedureParams,
    RigParams,
    SensorParams,
    SimConfig,
)
from .rig.sensors import measure
from .rig.simrun import SimulatedRun
from .rig.steps import (  # MAX_LAMBDA_H, stiffest_rate: re-exported
    MAX_LAMBDA_H,
    integrate_step,
    stiffest_rate,
)
from .rig.truth import (  # noqa: F401 - sine_fit_phase_deg, wobble_free_phase_deg re-exported
    _step_truth,
    _wobble_truth,
    recorded_step_truth,
    sine_fit_phase_deg,
    wobble_free_phase_deg,
)
from .theory import creep_curve_peak
from .tomlcheck import below_nyquist, between, checked_value, unknown_keys

_POLACH_KEYS = ("mu0", "a_ratio", "b_s_m", "k_a", "k_s")
_COL = {name: i for i, name in enumerate(OUT_COLUMNS)}
_SUFFIX = {"csv": ".csv", "hdf5": ".h5"}


# --------------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------------

def default_config_text() -> str:
    """The default configuration (V-Track) as commented TOML text."""
    return (resources.files("torquemod") / "data" / "vtrack_default.toml").read_text("utf-8")


def _parse(text: str, where: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:  # the message names line and column
        raise InputError(f"TOML syntax error: {exc}", path=where,
                         hint="fix the line named") from None


def _check_and_merge(default: dict, user: dict, where: str) -> dict:
    merged = copy.deepcopy(default)
    unknown_keys(user, default, "the configuration", where, takes="known sections:")
    for section, table in user.items():
        if not isinstance(table, dict):
            raise InputError(f"'{section}' must be a table", path=where)
        unknown_keys(table, default[section], "", where, prefix=f"{section}.",
                     takes=f"[{section}] takes")
        for key, value in table.items():
            ref = default[section][key]
            ok = (isinstance(value, bool) if isinstance(ref, bool)
                  else isinstance(value, str) if isinstance(ref, str)
                  else isinstance(value, list) if isinstance(ref, list)
                  else isinstance(value, int | float) and not isinstance(value, bool))
            if isinstance(ref, int) and not isinstance(ref, bool) and ok:
                ok = isinstance(value, int)
            if not ok:
                raise InputError(f"'{section}.{key}' has the wrong type ({value!r}); the "
                                 f"default is {ref!r}", path=where)
            if any(isinstance(v, float) and not math.isfinite(v)
                   for v in (value if isinstance(value, list) else [value])):
                raise InputError(f"'{section}.{key}' must be finite, got {value!r}",
                                 path=where, hint=f"the default is {ref!r}")
            merged[section][key] = value
    # a preset chosen by the user fills the Polach values it does not give itself
    if "preset" in user.get("contact", {}):
        vals = polach_preset(user["contact"]["preset"]).as_dict()
        for k in _POLACH_KEYS:
            merged["contact"][k] = user["contact"].get(k, vals[k])
    return merged


def _positive(doc: dict, section: str, key: str, where: str, *, allow_zero=False) -> float:
    return positive_number(doc[section][key], f"{section}.{key}", path=where,
                           allow_zero=allow_zero)


def _contact(doc: dict, rig: dict, where: str) -> ContactParams:
    c = doc["contact"]
    e_mod = _positive(doc, "contact", "youngs_modulus_pa", where)
    nu = checked_value(c["poisson_ratio"], float, "contact.poisson_ratio", where,
                       between(0.0, 0.5, lo_open=True, hi_open=True))
    a, b = float(c["semi_axis_a_m"]), float(c["semi_axis_b_m"])
    if a > 0 and b > 0:
        pass
    elif a == 0 and b == 0:
        rw_t = _positive(doc, "contact", "wheel_transverse_radius_m", where, allow_zero=True)
        rr_t = _positive(doc, "contact", "rail_transverse_radius_m", where, allow_zero=True)
        ky = (1.0 / rw_t if rw_t > 0 else 0.0) + (1.0 / rr_t if rr_t > 0 else 0.0)
        if ky <= 0:
            raise InputError("the contact needs a lateral curvature: give "
                             "rail_transverse_radius_m or wheel_transverse_radius_m > 0",
                             path=where)
        el = hertz_ellipse(float(rig["normal_load_n"]),
                           curvature_x_1_m=1.0 / float(rig["wheel_radius_m"]),
                           curvature_y_1_m=ky, youngs_modulus_pa=e_mod, poisson_ratio=nu)
        a, b = el.a_m, el.b_m
    else:
        raise InputError("give both contact.semi_axis_a_m and semi_axis_b_m (> 0) or neither",
                         path=where)
    kc = kalker_coefficients(a / b, nu)
    for k in _POLACH_KEYS:
        _positive(doc, "contact", k, where, allow_zero=(k == "b_s_m"))
    return ContactParams(mu0=float(c["mu0"]), a_ratio=float(c["a_ratio"]),
                         b_s_m=float(c["b_s_m"]), k_a=float(c["k_a"]), k_s=float(c["k_s"]),
                         shear_modulus_pa=e_mod / (2.0 * (1.0 + nu)), a_m=a, b_m=b,
                         c11=kc.c11, c22=kc.c22, lateral_creepage=float(c["lateral_creepage"]),
                         preset=str(c["preset"]))


def config_from_dict(doc: dict, *, where: str = "<config>") -> SimConfig:
    """Build a :class:`SimConfig` from a complete (merged) configuration dict."""
    r = doc["rig"]
    for key in r:
        _positive(doc, "rig", key, where)
    rig = RigParams(
        wheel_radius_m=float(r["wheel_radius_m"]), platform_radius_m=float(r["platform_radius_m"]),
        speed_m_s=float(r["speed_km_h"]) / 3.6, normal_load_n=float(r["normal_load_n"]),
        wheel_inertia_kg_m2=float(r["wheel_inertia_kg_m2"]),
        drive_inertia_kg_m2=float(r["drive_inertia_kg_m2"]),
        shaft_stiffness_nm_rad=float(r["shaft_stiffness_nm_rad"]),
        shaft_damping_nm_s_rad=float(r["shaft_damping_nm_s_rad"]),
        platform_inertia_kg_m2=float(r["platform_inertia_kg_m2"]),
        platform_kp_nm_s_rad=float(r["platform_kp_nm_s_rad"]),
        platform_ki_nm_rad=float(r["platform_ki_nm_rad"]),
        rolling_resistance_nm=float(r["rolling_resistance_nm"]),
        contact=_contact(doc, r, where))
    m = doc["modulation"]
    modulation = ModulationParams(
        amplitude_nm=_positive(doc, "modulation", "amplitude_nm", where, allow_zero=True),
        frequency_hz=_positive(doc, "modulation", "frequency_hz", where),
        frequency_offset=checked_value(m["frequency_offset"], float,
                                       "modulation.frequency_offset", where,
                                       between(-0.5, 0.5, lo_open=True, hi_open=True)),
        random_phase=bool(m["random_phase"]))
    d = dict(doc["disturbances"])
    dist = DisturbanceParams(**{k: (v if isinstance(v, bool | int) else
                                    tuple(float(x) for x in v) if isinstance(v, list)
                                    else float(v)) for k, v in d.items()})
    band = dist.speed_wobble_band_hz
    if len(band) != 2 or not 0 < band[0] <= band[1]:
        raise InputError(f"disturbances.speed_wobble_band_hz must be [low, high] with "
                         f"0 < low <= high, got {list(band)}", path=where)
    if (min(dist.speed_wobble_rms, dist.speed_wobble_rev1, dist.speed_wobble_rev2) < 0
            or dist.speed_wobble_components < 0):
        raise InputError("disturbances.speed_wobble_* amplitudes and components must be zero "
                         "or positive", path=where)
    for key in doc["sensors"]:
        _positive(doc, "sensors", key, where, allow_zero=(key != "sample_rate_hz"))
    sensors = SensorParams(**{k: float(v) for k, v in doc["sensors"].items()})
    below_nyquist(modulation.actual_frequency_hz, sensors.sample_rate_hz,
                  "modulation.frequency_hz", "sensors.sample_rate_hz", where)
    p = doc["procedure"]
    torques = p["dc_torques_nm"]
    if not torques or not all(isinstance(x, int | float) and not isinstance(x, bool)
                              and math.isfinite(x) for x in torques):
        raise InputError("'procedure.dc_torques_nm' must be a non-empty list of numbers",
                         path=where)
    if p["cycles_per_step"] < 1 or p["substeps"] < 1 or p["samples_per_step"] < 1:
        raise InputError("'procedure.cycles_per_step', 'substeps' and 'samples_per_step' must "
                         "be >= 1", path=where)
    procedure = ProcedureParams(dc_torques_nm=tuple(float(x) for x in torques),
                                cycles_per_step=int(p["cycles_per_step"]),
                                settle_s=_positive(doc, "procedure", "settle_s", where,
                                                   allow_zero=True),
                                ramp_s=_positive(doc, "procedure", "ramp_s", where,
                                                 allow_zero=True),
                                slip_creepage=_positive(doc, "procedure", "slip_creepage", where),
                                substeps=int(p["substeps"]),
                                samples_per_step=int(p["samples_per_step"]))
    procedure = _check_step(rig, sensors, procedure, where)
    return SimConfig(rig=rig, modulation=modulation, disturbances=dist, sensors=sensors,
                     procedure=procedure)


def _check_step(rig: RigParams, sensors: SensorParams, proc: ProcedureParams,
                where: str) -> ProcedureParams:
    """``proc`` with an RK4 step the rig's fastest mode allows (lambda*h <= MAX_LAMBDA_H):
    ``samples_per_step`` is halved (8, 4, 2, 1) while the step is too long -- a shorter step
    is only more accurate, so a stiffer rig or a lower sample rate just runs slower; refused
    when even one sample per step is too long (raise ``substeps``)."""
    lam = stiffest_rate(rig)
    sps = proc.samples_per_step
    while sps > 1 and lam * sps / (proc.substeps * sensors.sample_rate_hz) > MAX_LAMBDA_H:
        sps //= 2
    h = sps / (proc.substeps * sensors.sample_rate_hz)
    if lam * h > MAX_LAMBDA_H:
        raise InputError(f"integrator step {h:.3g} s too long for the rig's fastest mode "
                         f"(lambda*h = {lam * h:.2f} > {MAX_LAMBDA_H} with one sample per "
                         "step)", path=where, hint="raise procedure.substeps")
    return proc if sps == proc.samples_per_step else replace(proc, samples_per_step=sps)


def load_config(path: str | Path | None = None, *, overrides: dict | None = None) -> SimConfig:
    """The default configuration, overridden by the TOML file ``path`` (any subset of keys)
    and then by ``overrides`` (a dict of the same layout, for programs and tests).

    Unknown sections or keys and TOML syntax errors raise :class:`InputError` naming the key
    or the line.
    """
    default = _parse(default_config_text(), "vtrack_default.toml")
    merged = default
    where = "<default>"
    if path is not None:
        path = Path(path)
        where = str(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"cannot read the configuration ({exc})", path=path) from None
        merged = _check_and_merge(default, _parse(text, where), where)
    if overrides:
        merged = _check_and_merge(merged, overrides, "<overrides>")
    return config_from_dict(merged, where=where)


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
              large_signal: bool = True) -> dict | SimulatedRun:
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
        from .progress import WarmupBar

        bar = WarmupBar(total=len(torques), desc="simulate", unit="step", file=sys.stderr)
    else:
        bar = _NoProgress()

    def run(rp, plan, before):
        start = None if plan.y0 is not None else before.result()[2]
        out, n_done, slipped, y_end = integrate_step(config, params, rp.wobble, plan,
                                                     rp.n_step, start, rp.n_settle)
        bar.update(1)
        if slipped:
            return None, [], y_end, plan.t0_s + n_done * dt
        # (offering a step's truth to the pool while its thread draws the noise and writes
        # the files was tried in issue 12's fifth round: 2 cores, 30 alternations, median
        # 271 against 248 ms a run -- two threads wanting the GIL at once wait for each
        # other's switch interval)
        entry, bounds = recorded_step_truth(plan.index, plan.dc_nm, config, out, n_done,
                                            plan.t0_s, rp.wobble, rp.n_settle, large_signal)
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
        steps.append(_step_truth(slip_step, torques[slip_step - 1], config, None, True))
        steps[-1]["slip_time_s"] = slip_time
    bar.close()
    xi_peak, t_peak = creep_curve_peak(rig)
    truth = {
        "generator": "torquemod simulate", "version": __version__, "seed": seed,
        "format": fmt, "modulation_frequency_actual_hz": mod.actual_frequency_hz,
        "sample_rate_hz": fs, "slip_step": slip_step,
        "creep_curve_peak": {"creepage": xi_peak, "torque_nm": t_peak,
                             "coa": t_peak / (rig.wheel_radius_m * rig.normal_load_n)},
        "speed_wobble": _wobble_truth(config, wobble),
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
    """Simulate ``config`` and write the experiment folder ``out_dir``; return the truth dict.

    The folder is written into a temporary sibling and renamed into place at the end, so an
    interrupted run leaves no half-written experiment. An existing non-empty ``out_dir``
    raises :class:`~torquemod.errors.OutputError` unless ``force`` (then it is replaced).
    Deterministic for a given ``seed`` (and the same for any ``workers``: the threads that
    run the steps side by side, default the CPUs available, at most one per step; 1 runs
    them one after the other, e.g. inside a process pool that already fills the cores).
    """
    if fmt not in _SUFFIX:
        raise InputError(f"unknown output format '{fmt}'", hint="use csv or hdf5")
    out_dir = Path(out_dir)
    with atomic_dir(out_dir, force=force) as tmp:
        truth = _simulate(config, tmp, seed=seed, fmt=fmt, progress=progress,
                          files_per_cycle=files_per_cycle, workers=workers)
    return truth


def simulate_run(config: SimConfig, *, seed: int = 0, files_per_cycle: bool = True,
                 workers: int | None = None, large_signal: bool = True) -> SimulatedRun:
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

    Returns
    -------
    SimulatedRun
        The recordings, manifest tables and truth; ``write(folder)`` gives the folder
        :func:`run_simulation` writes, ``experiment()`` and ``recording(exp, entry)`` feed
        the processing chain without files.
    """
    return _simulate(config, None, seed=seed, fmt=None, progress=False,
                     files_per_cycle=files_per_cycle, workers=workers,
                     large_signal=large_signal)

