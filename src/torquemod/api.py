"""The library's face and the one orchestrator behind the CLI and the demo.

Stages, joined in memory (the rig)::

    exp = read_experiment("experiment.toml")   # Experiment; exp.processing: [processing]
    res = process(exp, phase_method="sinefit") # ProcessResult (tables, details, traces)
    ana = analyze(res)                         # Analysis (Polach fit, mu from the phase, ...)
    save(res, ana, "results/")                 # the results folder, atomically
    res, ana = load("results/")                # ... and back

and the train::

    run = read_run("run.toml")                 # Run: [vehicle], [test], recordings
    ob = onboard(run)                          # OnboardResult (track, along_track(), ...)
    ob.save("onboard/")                        # the results folder, atomically
    ob = load_onboard("onboard/")              # ... and back

:func:`run`, :func:`fit_folder` and :func:`report_folder` are what ``torquemod process``,
``fit`` and ``report`` do; they report their stages through an optional ``on_stage(text)``
callback and never print.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from torquemod import io as _io
from torquemod.errors import OutputError
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Experiment

if TYPE_CHECKING:  # imported when first used (_LAZY)
    from torquemod.analysis.analyzer import FitOptions, analyze
    from torquemod.analysis.result import Analysis
    from torquemod.processing.pipeline import ProcessResult, process_experiment, resolve_config
    from torquemod.results.folder import load, save, update

__all__ = ["RunOutcome", "analyze", "fit_folder", "fit_results_folder", "load", "load_onboard",
           "onboard", "process", "read_experiment", "read_run", "report_folder", "run", "save"]

Stage = Callable[[str], object] | None

#: Names this module offers from the heavier ones (scipy, matplotlib, pandas behind them),
#: imported when first used, so that a command prints its first stage line before it
#: waits for them.
_LAZY = {"analyze": "torquemod.analysis.analyzer", "FitOptions": "torquemod.analysis.analyzer",
         "Analysis": "torquemod.analysis.result", "load": "torquemod.results.folder",
         "save": "torquemod.results.folder", "update": "torquemod.results.folder",
         "ProcessResult": "torquemod.processing.pipeline",
         "process_experiment": "torquemod.processing.pipeline",
         "resolve_config": "torquemod.processing.pipeline"}


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


def _bind(*names: str) -> None:
    """The lazy ``names`` as globals of this module for the functions below (a name already
    set, e.g. by a test's monkeypatch, is kept)."""
    for name in names:
        if name not in globals():
            __getattr__(name)


def read_experiment(path) -> Experiment:
    """Read a rig experiment manifest.

    Parameters
    ----------
    path : str or os.PathLike
        ``experiment.toml`` or the folder that holds it.

    Returns
    -------
    Experiment
        The manifest and its recordings; ``exp.processing`` is its ``[processing]`` table as
        a :class:`~torquemod.io.config.ProcessingConfig` (SI units: Hz, s, m, N, kg m^2).

    Raises
    ------
    InputError
        The manifest, a recording it names or its ``[processing]`` table is missing or
        invalid (the message names the file and the key).
    """
    exp = _io.read_experiment(path)
    _ = exp.processing  # a bad [processing] table is reported here, naming the manifest
    return exp


def process(experiment, config: ProcessingConfig | None = None, *,
            phase_method: str | None = None, nan_policy: str | None = None,
            progress: bool = False, workers: int | None = None) -> ProcessResult:
    """Run the processing chain on a rig experiment: per cycle and per torque step, the
    creepage [-], coefficient of adhesion [-] and torque-to-speed phase lag [deg].

    The phase lag is the quantity of Eq. (1) of the V-Track torque-modulation paper
    (References): the wheel speed lags the modulated torque by ``phi = atan(C/k)``.

    Parameters
    ----------
    experiment : Experiment or path
        An :class:`Experiment` (:func:`read_experiment`) or its manifest's path.
    config : ProcessingConfig, optional
        Replaces the manifest's whole ``[processing]`` table.
    phase_method : {"paper", "sinefit"}, optional
        Applied over the table or ``config``: the paper's paired peaks and valleys
        (Eq. 2 of [1]_) or a least-squares sine fit (:mod:`torquemod.dsp.phase`).
    nan_policy : {"raise", "interpolate", "drop-cycle"}, optional
        What to do with missing samples; applied over the table or ``config``.
    progress : bool, default False
        Show a progress bar on stderr.
    workers : int, optional
        Processes for the per-recording work; default from the configuration.

    Returns
    -------
    ProcessResult
        The cycles and steps tables, per-recording details and traces.

    Raises
    ------
    InputError
        Bad manifest, recording or option (one line naming the file and key).

    Notes
    -----
    The CLI's ``--phase-method``/``--nan-policy`` apply the same overrides, so the library
    and ``torquemod process`` give the same result.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
    _bind("resolve_config", "process_experiment")
    exp = experiment if isinstance(experiment, Experiment) else read_experiment(experiment)
    cfg = resolve_config(exp, config, phase_method=phase_method, nan_policy=nan_policy)
    return process_experiment(exp, config=cfg, progress=progress, workers=workers)


def read_run(path):
    """Read a train run manifest.

    Parameters
    ----------
    path : str or os.PathLike
        ``run.toml`` or the folder that holds it.

    Returns
    -------
    Run
        The ``[vehicle]`` and ``[test]`` tables (SI units) and the recordings, one per axle.

    Raises
    ------
    InputError
        The manifest, a recording or its ``[onboard]`` table (checked now) is invalid.
    """
    from torquemod.io.run import read_run as _read_run
    from torquemod.ontrain.onboardconfig import OnboardConfig
    run = _read_run(path)
    OnboardConfig.from_dict(run.extra.get("onboard"), source=str(run.manifest_path))
    return run


def onboard(run, *, axle: int | None = None, config=None, **options):
    """The friction along a train run: one axle through the on-board estimator.

    Parameters
    ----------
    run : Run or path
        A :class:`~torquemod.io.run.Run` (:func:`read_run`) or its manifest's path.
    axle : int, optional
        Which ``[[recording]] axle``; may be left out when the run records one axle.
    config : OnboardConfig or dict, optional
        The estimator's settings; default the run's ``[onboard]`` table.
    **options
        Single settings over either (the keys of ``[onboard]``, e.g. ``hop_s=0.5``).

    Returns
    -------
    OnboardResult
        The axle's track (``to_frame()``, ``along_track()``), ``report()``, ``plot_*``,
        ``save(folder)`` (what ``torquemod onboard`` writes).
    """
    from torquemod.errors import InputError
    from torquemod.io.run import Run
    from torquemod.ontrain.onboardconfig import OnboardConfig
    from torquemod.ontrain.run import estimate_axle
    run = run if isinstance(run, Run) else read_run(run)
    if config is None:
        cfg = OnboardConfig.from_dict(run.extra.get("onboard"), source=str(run.manifest_path))
    elif isinstance(config, dict):
        cfg = OnboardConfig.from_dict(config, source="onboard(config=...)")
    elif isinstance(config, OnboardConfig):
        cfg = config
    else:
        raise InputError(f"config must be an OnboardConfig or a dict, got "
                         f"{type(config).__name__}")
    if options:  # checked as given here, not blamed on the manifest
        cfg = OnboardConfig.from_dict({**cfg.to_dict(), **options},
                                      source="onboard(**options)")
    axles = [e.axle for e in run.recordings]
    if axle is None:
        if len(axles) > 1:
            raise InputError(f"{run.manifest_path}: the run records axles {axles}",
                             hint="choose one with axle=")
        entry = run.recordings[0]
    else:
        entry = next((e for e in run.recordings if e.axle == axle), None)
        if entry is None:
            raise InputError(f"{run.manifest_path}: no axle {axle!r}; the run records axles "
                             f"{axles}")
    return estimate_axle(run, entry, cfg)


def load_onboard(folder, axle: int | None = None):
    """Read an on-board results folder back.

    Parameters
    ----------
    folder : str or os.PathLike
        What :meth:`OnboardResult.save` or ``torquemod onboard`` wrote.
    axle : int, optional
        Which axle; the first in the folder when None.

    Returns
    -------
    OnboardResult
        The axle's friction track, as :func:`onboard` returned it.

    Raises
    ------
    InputError
        The folder is not an on-board results folder or holds no such axle.
    """
    from torquemod.ontrain.load import load_onboard as _load
    return _load(folder, axle)


@dataclass
class RunOutcome:
    """What :func:`run` did.

    Attributes
    ----------
    result : ProcessResult
        The processing result.
    analysis : Analysis or None
        Its analysis; None with ``fit=False``.
    folder : pathlib.Path
        The results folder.
    report : pathlib.Path or None
        The report; None without one.
    stage_s : dict of str to float
        Wall time of each stage [s].
    """

    result: ProcessResult
    analysis: Analysis | None
    folder: Path
    report: Path | None
    stage_s: dict


def _inputs(exp: Experiment) -> list[Path]:
    return [Path(exp.manifest_path), *(Path(e.path) for e in exp.recordings)]


def _refuse_inputs(out, inputs) -> None:
    """Refuse, before any work, an output folder that is or holds one of the inputs (with
    --force it would be replaced, inputs and all)."""
    target = Path(out).resolve()
    for path in inputs:
        p = Path(path).resolve()
        if p == target or target in p.parents:
            raise OutputError(f"{out}: the results folder would replace the experiment's own "
                              f"file {path}; choose another --out")


def run(experiment, out, *, config: ProcessingConfig | None = None,
        phase_method: str | None = None, nan_policy: str | None = None, fit: bool = True,
        fit_options=None, report_options=None, force: bool = False, progress: bool = False,
        command: list[str] | None = None, on_stage: Stage = None, export=()) -> RunOutcome:
    """Process, analyse and save a rig experiment: what ``torquemod process`` does.

    Parameters
    ----------
    experiment : Experiment or path
        As for :func:`process`.
    out : str or os.PathLike
        The results folder to write (atomically; refused if it is or holds an input).
    config, phase_method, nan_policy
        As for :func:`process`.
    fit : bool, default True
        Also fit the creep curve (:func:`analyze`) and write the figures and report.
    fit_options : FitOptions or dict, optional
        Passed to :func:`analyze`.
    report_options : dict, optional
        Passed to the report writer.
    force : bool, default False
        Replace an existing ``out``.
    progress : bool, default False
        Show a progress bar on stderr.
    command : list of str, optional
        The command line recorded in the folder's provenance.
    on_stage : callable, optional
        Called with one line of text at each stage; nothing is printed otherwise.
    export : iterable of {"mat", "parquet"}
        The cycles and steps tables also in these formats.

    Returns
    -------
    RunOutcome
        The result, the analysis, the folder, the report path and the wall time of each
        stage [s].

    Raises
    ------
    InputError
        Bad input or export format (before any work is done).
    OutputError
        ``out`` is occupied (without ``force``) or would replace an input.
    """
    from torquemod.results.export import check_formats
    export = check_formats(export)  # a bad format is refused before the work
    say = on_stage or (lambda _text: None)
    t0 = time.perf_counter()
    exp = experiment if isinstance(experiment, Experiment) else read_experiment(experiment)
    from torquemod._util.fsutil import check_output_dir, output_lock
    _refuse_inputs(out, _inputs(exp))
    with output_lock(out):  # one run at a time writes --out (save re-enters this lock)
        check_output_dir(out, force=force)  # refuse an occupied --out before any work
        say(f"processing {len(exp.recordings)} recordings (the first run compiles the numba "
            "decimation filter, a few seconds; later runs reuse the compiled cache) ...")
        res = process(exp, config, phase_method=phase_method, nan_policy=nan_policy,
                      progress=progress)
        # the analysis, the layout and the report (matplotlib) are imported once the
        # recordings are done, so that their memory does not add to the processing's peak
        _bind("analyze", "save")
        t1 = time.perf_counter()
        ana = None
        if fit:
            say("fitting the creep curve and mu from the phase ...")
            ana = analyze(res, fit_options)
        t2 = time.perf_counter()
        if fit:
            say("writing the results folder with figures and report.html ...")
        folder = save(res, ana, out, force=force, inputs=_inputs(exp), command=command,
                      report=fit, report_options=report_options, export=export)
    t3 = time.perf_counter()
    return RunOutcome(res, ana, Path(folder), Path(folder) / "report.html" if fit else None,
                      {"process": t1 - t0, "fit": t2 - t1, "write": t3 - t2, "total": t3 - t0})


def fit_folder(folder, options: FitOptions | dict | None = None, *, report_options=None,
               on_stage: Stage = None
               ) -> tuple[ProcessResult, Analysis]:
    """Refit a results folder in place: what ``torquemod fit`` does.

    Parameters
    ----------
    folder : str or os.PathLike
        A results folder written by :func:`run` or :func:`save`.
    options : FitOptions or dict, optional
        Passed to :func:`analyze`.
    report_options : dict, optional
        Passed to the report writer.
    on_stage : callable, optional
        Called with one line of text at each stage.

    Returns
    -------
    tuple of (ProcessResult, Analysis)
        The loaded result and its new analysis; ``fit.json``, ``steps.csv``, the figures
        and ``report.html`` are rewritten atomically.
    """
    from torquemod._util.fsutil import output_lock
    say = on_stage or (lambda _text: None)
    _bind("load", "analyze", "update")
    with output_lock(folder):  # one run at a time updates the folder (update re-enters)
        res, _ = load(folder)
        say("fitting the creep curve and mu from the phase ...")
        ana = analyze(res, options)
        say("rewriting fit.json, steps.csv, the figures and report.html ...")
        update(folder, res, ana, report_options=report_options)
    return res, ana


def report_folder(folder, *, report_options=None, on_stage: Stage = None) -> Path:
    """Redraw the figures and ``report.html`` of a results folder: ``torquemod report``.

    Parameters
    ----------
    folder : str or os.PathLike
        A results folder; one saved without an analysis is analysed with the default
        options first.
    report_options : dict, optional
        Passed to the report writer.
    on_stage : callable, optional
        Called with one line of text at each stage.

    Returns
    -------
    pathlib.Path
        The path of ``report.html``.
    """
    from torquemod._util.fsutil import output_lock
    say = on_stage or (lambda _text: None)
    _bind("load", "analyze", "update")
    with output_lock(folder):  # one run at a time updates the folder (update re-enters)
        res, ana = load(folder)
        if ana is None:
            say("fitting the creep curve (the folder holds no fit yet) ...")
            ana = analyze(res)
        say("drawing the figures and writing report.html ...")
        update(folder, res, ana, report_options=report_options)
    return Path(folder) / "report.html"


def fit_results_folder(results_dir, *, options=None) -> dict:
    """Refit a results folder (:func:`fit_folder`) and summarise the fit.

    Parameters
    ----------
    results_dir : str or os.PathLike
        A results folder.
    options : FitOptions or dict, optional
        Passed to :func:`analyze`.

    Returns
    -------
    dict
        :meth:`Analysis.summary` plus the ``fit_json`` and ``steps_csv`` paths (str).
    """
    _, ana = fit_folder(results_dir, options)
    folder = Path(results_dir)
    return {**ana.summary(), "fit_json": str(folder / "fit.json"),
            "steps_csv": str(folder / "steps.csv")}
