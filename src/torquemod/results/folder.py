"""The results folder: the one module that knows its layout (docs/format.md, "Results").

:func:`save` writes, once and atomically (the folder appears whole or not at all)::

    result.json       machine-readable state: experiment, parameters, per-cycle details,
                      warnings, the fit options (what :func:`load` rebuilds from)
    cycles.csv        per-cycle table (exact floats)
    steps.csv         per-step table, with the analysis columns when analysed
    traces.npz        signals for the figures, keys ``s{step}c{cycle}__{name}``
    provenance.json   for people: software, parameters, inputs with SHA-256, warnings
    fit.json          the analysis document (:meth:`Analysis.to_dict`), when analysed
    figures/, report.html   the report (:mod:`torquemod.report`), when analysed

:func:`load` is the only reader. It reads ``result.json``, the two tables and the traces,
checks them, and rebuilds the :class:`~torquemod.processing.pipeline.ProcessResult`; the
:class:`~torquemod.analysis.result.Analysis` is read back from ``fit.json``, the analysed
steps table and the values ``result.json`` keeps beside them
(:func:`~torquemod.analysis.result.saved_state`; the phase fit's tabulated curve is left out
and rebuilt from its law and parameters, :func:`_without_curve`), without fitting again.
When ``fit.json`` is missing, was written by another version or with other fit options, the
analysis is recomputed with the stored fit options (deterministic), with a warning.
``provenance.json`` and the report are outputs only. A missing or damaged file raises
:class:`InputError` naming it.
"""

from __future__ import annotations

import dataclasses
import json
import re
import warnings
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from torquemod._util.jsonutil import dump_json, write_json
from torquemod._version import __version__
from torquemod.analysis.analyzer import ADDED_STEP_COLUMNS, FitOptions, analyze
from torquemod.analysis.creeplaws import mixture_curve
from torquemod.analysis.result import from_saved, saved_state
from torquemod.errors import InputError, OptionError, OutputError, TorquemodError
from torquemod.io.config import ProcessingConfig
from torquemod.io.experiment import Experiment, RecordingEntry, Rig, TestSetup
from torquemod.processing.pipeline import CYCLE_COLUMNS, STEP_COLUMNS, ProcessResult
from torquemod.processing.provenance import provenance
from torquemod.report import write_report
from torquemod.results.writer import Writing, write_folder

if TYPE_CHECKING:
    from torquemod.analysis.result import Analysis

__all__ = ["STATE_FILE", "load", "save", "update"]

STATE_FILE = "result.json"
FORMAT = "torquemod-results"
FORMAT_VERSION = 1
_TRACE_KEY = re.compile(r"^s(\d+)c(\d+)__(\w+)$")
_BOOL = {"True": True, "False": False, "true": True, "false": False, "1": True, "0": False}


# --------------------------------------------------------------------------- writing

def save(result: ProcessResult, analysis: Analysis | None, folder, *, force: bool = False,
         inputs=(), command: list[str] | None = None, report: bool = True,
         report_options=None, export=()) -> Path:
    """Write a new results folder (see the module docstring) in one atomic step.

    Parameters
    ----------
    result : ProcessResult
        What :func:`torquemod.process` returned.
    analysis : Analysis or None
        What :func:`torquemod.analyze` returned; None writes no fit (``process --no-fit``).
    folder : str or os.PathLike
        The folder to create; an existing non-empty one is refused unless ``force``.
    force : bool, default False
        Replace an existing ``folder``.
    inputs : iterable of path
        The manifest and the recordings: files the folder must never replace or contain.
    command : list of str, optional
        The command line recorded in the provenance.
    report : bool, default True
        Also draw the figures and ``report.html``.
    report_options : dict, optional
        Passed to the report writer.
    export : iterable of {"mat", "parquet"}
        The cycles and steps tables also as MATLAB ``mat`` and/or ``parquet``
        (:mod:`torquemod.results.export`; CSV is always written); :func:`update` keeps
        them current.

    Returns
    -------
    pathlib.Path
        ``folder``.

    Raises
    ------
    OutputError
        ``folder`` is occupied (without ``force``), would replace an input, or cannot be
        written; nothing partial is left behind.
    """
    from torquemod.results.export import check_formats
    export = check_formats(export)
    if command is not None:
        result = dataclasses.replace(result, command=list(command))
    prov = provenance(result, command=result.command)
    with write_folder(folder, kind="results", provenance=prov, force=force,
                      refuse=inputs or ()) as w:
        _write_all(w, result, analysis, report=report, report_options=report_options,
                   export=export)
    return Path(folder)


def update(folder, result: ProcessResult, analysis: Analysis | None, *,
           command: list[str] | None = None, report: bool = True, report_options=None
           ) -> Path:
    """Rewrite an existing results folder with a new analysis or report, atomically.

    Readers see the old folder or the new one, never a mix.

    Parameters
    ----------
    folder : str or pathlib.Path
        The results folder (:func:`torquemod.save`).
    result : ProcessResult
        The processing result it holds.
    analysis : Analysis or None
        The new analysis; None: none.
    command : list of str or None
        The command for provenance.json; None keeps the processing command
        (``result.command``).
    report : bool
        Write the report. Default True.
    report_options : dict or None
        Options of the report. Default None.

    Returns
    -------
    pathlib.Path
        The folder.
    """
    from torquemod.results.export import EXPORT_FORMATS
    folder = Path(folder)
    # the exported copies of the tables the folder holds are rewritten with them
    export = [f for f, suffix in EXPORT_FORMATS.items()
              if f != "csv" and (folder / f"steps{suffix}").exists()]
    prov = provenance(result, command=command or result.command)
    with write_folder(folder, mode="update", provenance=prov) as w:
        _write_all(w, result, analysis, report=report, report_options=report_options,
                   export=export)
    return folder


def _write_all(w: Writing, result: ProcessResult, analysis: Analysis | None, *,
               report: bool, report_options, export=()) -> None:
    """Every file of the layout but provenance.json (the writer's) into the folder being
    assembled; a full disk or an unwritable target ends as one OutputError naming the
    folder."""
    tmp, final = w.path, w.target
    try:
        steps = analysis.steps if analysis is not None else result.steps
        result.cycles.to_csv(tmp / "cycles.csv", index=False, lineterminator="\n")
        steps.to_csv(tmp / "steps.csv", index=False, lineterminator="\n")
        if export:
            from torquemod.results.export import write_table
            for fmt in export:
                if fmt != "csv":  # written above
                    write_table(result.cycles, tmp / "cycles", fmt)
                    write_table(steps, tmp / "steps", fmt)
        write_json(tmp / STATE_FILE, _state(result, analysis))
        np.savez(tmp / "traces.npz", **{f"s{s}c{c}__{name}": x
                                        for (s, c), arrays in sorted(result.traces.items())
                                        for name, x in arrays.items()})
        if analysis is not None:
            doc = analysis.to_dict(results_dir=str(final))
            (tmp / "fit.json").write_text(dump_json(doc) + "\n", encoding="utf-8")
            if report:
                write_report(tmp, result, analysis, options=report_options,
                             provenance_doc=w.provenance)
    except TorquemodError:
        raise
    except OSError as exc:
        raise OutputError(f"{final}: cannot write the results "
                          f"({exc.strerror or exc}); nothing was changed") from None


def _state(result: ProcessResult, analysis: Analysis | None) -> dict:
    exp = result.experiment
    return {
        "format": FORMAT, "format_version": FORMAT_VERSION,
        "torquemod_version": result.torquemod_version, "created_utc": result.created_utc,
        "experiment": {
            "manifest_path": str(exp.manifest_path),
            "rig": dataclasses.asdict(exp.rig), "test": dataclasses.asdict(exp.test),
            "recordings": [{**dataclasses.asdict(e), "path": str(e.path)}
                           for e in exp.recordings],
            "channel_map": exp.channel_map, "extra": exp.extra},
        "config": result.config.to_dict(),
        "n_steps": len(result.steps), "n_cycles": len(result.cycles),
        "cycle_details": result.cycle_details, "warnings": result.warnings,
        "nan_actions": result.nan_actions, "timing_s": result.timing_s,
        "input_sha256": result.input_sha256, "command": result.command,
        "analysis": None if analysis is None else {
            "options": dataclasses.asdict(analysis.options),
            "created_utc": analysis.created_utc,
            "saved_with": __version__, "saved": _without_curve(saved_state(analysis))},
    }


#: the relative tolerance within which the phase fit's curve rebuilt from its law and
#: parameters must equal the fitted one for result.json to leave it out (the rebuild mixes
#: the same two tabulated members with a mixing fraction recovered from the parameters:
#: a few ulp apart, ~4e-16 relative on the demo's fits)
CURVE_RTOL = 1e-12


def _without_curve(saved: dict) -> dict:
    """The saved state without the phase fit's tabulated curve ``best_s`` (2001 numbers)
    when :func:`~torquemod.analysis.creeplaws.mixture_curve` rebuilds it from the stored law
    and parameters within :data:`CURVE_RTOL` (``best_s_rebuilt`` says so); else as it is."""
    adhesion = (saved.get("phase_fit") or {}).get("adhesion")
    if not adhesion or "best_s" not in adhesion:
        return saved
    fitted = np.array([float(v) for v in adhesion["best_s"]])
    rebuilt = mixture_curve(adhesion["law"], adhesion["params"])
    if rebuilt is None or not np.allclose(rebuilt, fitted, rtol=CURVE_RTOL, atol=0.0,
                                          equal_nan=True):
        return saved
    adhesion = {k: v for k, v in adhesion.items() if k != "best_s"}
    adhesion["best_s_rebuilt"] = True
    return {**saved, "phase_fit": {**saved["phase_fit"], "adhesion": adhesion}}


def _with_curve(saved: dict) -> dict:
    """The saved state with the phase fit's curve rebuilt where :func:`_without_curve` left
    it out."""
    adhesion = (saved.get("phase_fit") or {}).get("adhesion")
    if not adhesion or not adhesion.get("best_s_rebuilt"):
        return saved
    curve = mixture_curve(adhesion["law"], adhesion["params"])
    if curve is None:
        raise ValueError("the phase fit's curve cannot be rebuilt from its law and parameters")
    adhesion = {k: v for k, v in adhesion.items() if k != "best_s_rebuilt"}
    adhesion["best_s"] = curve.tolist()
    return {**saved, "phase_fit": {**saved["phase_fit"], "adhesion": adhesion}}


# --------------------------------------------------------------------------- reading

def load(folder) -> tuple[ProcessResult, Analysis | None]:
    """Read a results folder written by :func:`save`.

    Parameters
    ----------
    folder : str or os.PathLike
        The results folder.

    Returns
    -------
    tuple of (ProcessResult, Analysis or None)
        The Analysis is None when the folder was saved without one (``process --no-fit``).

    Raises
    ------
    InputError
        The folder does not exist, is not a folder or is not a results folder.
    """
    folder = Path(folder)
    if not folder.exists():
        raise InputError("results folder does not exist", path=folder,
                         hint="give the --out folder of 'torquemod process'")
    if not folder.is_dir():
        raise InputError("not a folder", path=folder,
                         hint="give the --out folder of 'torquemod process'")
    state = _read_state(folder / STATE_FILE)
    path = folder / STATE_FILE
    try:
        exp = _experiment(state["experiment"])
        config = ProcessingConfig.from_dict(state["config"], source=str(path))
        n_steps, n_cycles = int(state["n_steps"]), int(state["n_cycles"])
        details = list(state["cycle_details"])
        fit_state = state.get("analysis")
        options = None if fit_state is None else _fit_options(fit_state["options"])
    except InputError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise InputError(f"damaged results state ({type(exc).__name__}: {exc})", path=path,
                         hint="process the experiment again") from None
    cycles = _read_table(folder / "cycles.csv", CYCLE_COLUMNS, n_cycles)
    doc = None if options is None else _saved_fit(folder, fit_state, options)
    steps = _read_table(folder / "steps.csv",
                        STEP_COLUMNS if doc is None else ANALYSED_STEP_COLUMNS, n_steps)
    analysed_steps, steps = steps, steps[STEP_COLUMNS].copy()
    traces = _read_traces(folder / "traces.npz")
    _check_consistent(cycles, steps, details, folder)
    result = ProcessResult(
        experiment=exp, config=config, cycles=cycles, steps=steps, cycle_details=details,
        traces=traces, warnings=list(state.get("warnings") or []),
        timing_s=dict(state.get("timing_s") or {}),
        nan_actions=list(state.get("nan_actions") or []),
        input_sha256=dict(state.get("input_sha256") or {}),
        created_utc=str(state.get("created_utc") or ""),
        torquemod_version=str(state.get("torquemod_version") or ""),
        command=state.get("command") if isinstance(state.get("command"), list) else None)
    if options is None:
        return result, None
    if doc is not None:
        try:
            return result, from_saved(doc, _with_curve(fit_state["saved"]), analysed_steps,
                                      options, name=result.name)
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InputError(f"damaged fit document ({type(exc).__name__}: {exc})",
                             path=folder / "fit.json",
                             hint="process the experiment again") from None
    try:
        analysis = analyze(result, options)
    except InputError as exc:  # tables that parse but cannot be analysed
        raise InputError(f"cannot be analysed: {exc}", path=folder,
                         hint="process the experiment again") from None
    analysis.created_utc = str(fit_state.get("created_utc") or analysis.created_utc)
    return result, analysis


def _saved_fit(folder: Path, fit_state: dict, options: FitOptions) -> dict | None:
    """The ``fit.json`` document when this version wrote it with these fit options, else
    None with a warning that the analysis is computed again from the steps."""
    path = folder / "fit.json"
    why = None
    if not isinstance(fit_state.get("saved"), dict) or \
            fit_state.get("saved_with") != __version__:
        why = (f"result.json was written by torquemod {fit_state.get('saved_with')}"
               if fit_state.get("saved_with") else "an earlier results format")
    else:
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            why = "it is missing"
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise InputError(f"cannot read ({exc})", path=path,
                             hint="process the experiment again") from None
        else:
            if not isinstance(doc, dict) or doc.get("torquemod_version") != __version__:
                why = "it was written by another torquemod version"
            elif doc.get("fit_options") != json.loads(dump_json(dataclasses.asdict(options))):
                why = "its fit options differ from result.json's"
            else:
                return doc
    warnings.warn(f"{path}: not read back ({why}); the analysis is computed again from "
                  "steps.csv with the stored fit options", UserWarning, stacklevel=3)
    return None


def _read_state(path: Path) -> dict:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        if (path.parent / "onboard.json").exists():
            raise InputError("an on-board (train) results folder, not a rig one", path=path,
                             hint="read it with tm.load_onboard(folder)") from None
        raise InputError("not a torquemod results folder: result.json is missing", path=path,
                         hint="give a folder written by tm.save or 'torquemod process' "
                         "(process the experiment again to make one)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read ({getattr(exc, 'strerror', None) or exc})",
                         path=path) from None
    try:
        state = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"damaged: not valid JSON ({exc})", path=path,
                         hint="process the experiment again") from None
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise InputError("not a torquemod results state file", path=path,
                         hint="process the experiment again")
    if state.get("format_version") != FORMAT_VERSION:
        raise InputError(f"results format version {state.get('format_version')!r}; this "
                         f"torquemod reads version {FORMAT_VERSION}", path=path,
                         hint="process the experiment again with this version")
    return state


def _number(value, key: str) -> float:
    """A finite number of the state file (bool and text refused)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or \
            not np.isfinite(value):
        raise ValueError(f"'{key}' is {value!r}, not a finite number")
    return float(value)


def _experiment(doc: dict) -> Experiment:
    rig, test = dict(doc["rig"]), dict(doc["test"])
    for key in ("wheel_radius_m", "platform_radius_m"):
        rig[key] = _number(rig[key], f"rig.{key}")
    for key in ("normal_load_n", "modulation_frequency_hz", "modulation_amplitude_nm"):
        test[key] = _number(test[key], f"test.{key}")
    extra = dict(rig.get("extra") or {})
    for key in ("wheel_inertia_kg_m2", "contact_stiffness"):
        if extra.get(key) is not None:
            extra[key] = _number(extra[key], f"rig.{key}")
    rig["extra"] = extra
    recs = tuple(RecordingEntry(**{**r, "path": Path(r["path"])}) for r in doc["recordings"])
    return Experiment(manifest_path=Path(doc["manifest_path"]), rig=Rig(**rig),
                      test=TestSetup(**test), recordings=recs,
                      channel_map=dict(doc.get("channel_map") or {}),
                      extra=dict(doc.get("extra") or {}))


def _fit_options(doc) -> FitOptions:
    """The stored fit options, each of its default's type (a bad one is reported with the
    file's name by the caller)."""
    try:
        opts = FitOptions.coerce(doc)
    except OptionError as exc:
        raise ValueError(str(exc)) from None
    for f in dataclasses.fields(FitOptions):
        value, default = getattr(opts, f.name), f.default
        if isinstance(default, bool):
            ok = isinstance(value, bool)
        elif isinstance(default, int | float) or default is None:
            ok = (value is None and default is None) or (
                isinstance(value, int | float) and not isinstance(value, bool)
                and np.isfinite(value))
        else:
            ok = isinstance(value, type(default))
        if not ok:
            raise ValueError(f"fit option '{f.name}' is {value!r}")
    return opts


def _check_consistent(cycles: pd.DataFrame, steps: pd.DataFrame, details: list,
                      folder: Path) -> None:
    """The tables and the per-cycle details describe the same steps and cycles."""
    if set(cycles["step"]) != set(steps["step"]) or len(details) != len(cycles):
        raise InputError("damaged results: steps.csv, cycles.csv and result.json do not "
                         "describe the same steps and cycles", path=folder,
                         hint="process the experiment again")


def _read_table(path: Path, columns: list[str], n_rows: int) -> pd.DataFrame:
    """A table of the layout with its columns checked and typed; rows must all be there."""
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except FileNotFoundError:
        raise InputError("missing from the results folder", path=path,
                         hint="process the experiment again") from None
    except (OSError, UnicodeDecodeError, pd.errors.ParserError,
            pd.errors.EmptyDataError) as exc:
        raise InputError(f"damaged table ({str(exc).strip().splitlines()[0]})", path=path,
                         hint="process the experiment again") from None
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise InputError(f"damaged table: column(s) {missing} missing", path=path,
                         hint="process the experiment again")
    if len(df) != n_rows:
        raise InputError(f"damaged table: {len(df)} rows where {n_rows} were written",
                         path=path, hint="process the experiment again")
    out = {}
    for col in columns:
        values = df[col].str.strip()
        if col == "coa_source":
            out[col] = values.to_numpy(dtype=object)
        elif col == "slip":
            bad = ~values.isin(list(_BOOL))
            if bad.any():
                raise InputError(f"damaged table: column 'slip' holds "
                                 f"{values[bad].iloc[0]!r} in row {int(np.flatnonzero(bad)[0]) + 2}"
                                 " (True or False expected)", path=path,
                                 hint="process the experiment again")
            out[col] = values.map(_BOOL).astype(bool).to_numpy()
        else:
            num = pd.to_numeric(values.replace({"": "nan"}), errors="coerce")
            bad = num.isna() & ~values.str.lower().isin(["", "nan"])
            if bad.any():
                row = int(np.flatnonzero(bad)[0]) + 2
                raise InputError(f"damaged table: column '{col}' holds {values[bad].iloc[0]!r} "
                                 f"in line {row} (a number expected)", path=path,
                                 hint="process the experiment again")
            out[col] = num.to_numpy()
    table = pd.DataFrame(out, columns=columns)
    for col in ("step", "cycle", "n_cycles"):
        if col in table:
            values = table[col].to_numpy(float)
            if not np.all(np.isfinite(values) & (values == np.round(values))):
                raise InputError(f"damaged table: column '{col}' is not a whole number",
                                 path=path, hint="process the experiment again")
            table[col] = table[col].astype(int)
    return table


def _read_traces(path: Path) -> dict[tuple[int, int], dict[str, np.ndarray]]:
    traces: dict[tuple[int, int], dict[str, np.ndarray]] = {}
    try:
        with np.load(path, allow_pickle=False) as npz:
            for key in npz.files:
                m = _TRACE_KEY.match(key)
                if m is None:
                    raise InputError(f"damaged: unexpected entry {key!r}", path=path,
                                     hint="process the experiment again")
                traces.setdefault((int(m[1]), int(m[2])), {})[m[3]] = npz[key]
    except FileNotFoundError:
        raise InputError("missing from the results folder", path=path,
                         hint="process the experiment again") from None
    except InputError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise InputError(f"damaged signal traces ({exc})", path=path,
                         hint="process the experiment again") from None
    return traces


#: Column order of steps.csv after the analysis (for documentation and tests).
ANALYSED_STEP_COLUMNS = [*STEP_COLUMNS, *ADDED_STEP_COLUMNS]
