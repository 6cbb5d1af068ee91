"""One run of the fleet (a rig experiment or a train run): finding the manifests, naming and
partitioning the runs, the fingerprint that lets a rerun skip it, its plan, the work items of
its recordings and their assembly into the partitions and summary row
(:func:`plan_run`, :func:`work_item`, :func:`finish_run`; :func:`process_run` all in this
process). :mod:`torquemod.fleet.run` sends them to Dask.
"""

from __future__ import annotations

import datetime as _dt
import glob
import hashlib
import json
import shutil
import time
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from torquemod._util.blas import single_blas
from torquemod._util.fsutil import sha256_file
from torquemod._version import __version__
from torquemod.errors import InputError
from torquemod.fleet.tasks import _recording_items, may_split, one_line, part_item, scan_item
from torquemod.results import resume
from torquemod.results.writer import write_folder

if TYPE_CHECKING:
    from torquemod.io.config import ProcessingConfig
    from torquemod.io.experiment import Experiment
    from torquemod.io.run import Run
    from torquemod.ontrain.estimator import OnboardConfig

MANIFEST_NAME = "experiment.toml"
RUN_NAME = "run.toml"
TABLES = ("cycles", "steps", "track")
SUMMARY_COLUMNS = ["run", "kind", "status", "vehicle", "date", "manifest", "duration_s",
                   "n_rows", "n_steps", "n_cycles", "mu", "mu_stderr", "mu_lower_bound",
                   "mu_given_share", "low_adhesion_windows", "slip_windows", "seconds",
                   "message"]
#: summary fields a skipped run takes from its state file
_KEPT = SUMMARY_COLUMNS[3:-2]


def find_manifests(runs: Iterable[str | Path]) -> list[Path]:
    """Run manifests from paths, folders, glob patterns or list files.

    Parameters
    ----------
    runs : iterable of str or pathlib.Path
        Manifest files, folders (every ``experiment.toml`` and ``run.toml`` below them), glob
        patterns, or list files (``.txt``/``.lst``: one of the above a line, ``#``
        comments).

    Returns
    -------
    list of pathlib.Path
        Sorted, without duplicates.
    """
    return sorted(_spellings(runs))


def _spellings(runs: Iterable[str | Path]) -> dict[Path, str]:
    """{resolved manifest path: the path as found} (the first spelling: a folder's or a
    list file's path joined with what was found there, as the user wrote it). ``runs`` may
    also be a single path or pattern."""
    out: dict[Path, str] = {}
    for p in _found(_as_list(runs)):
        out.setdefault(p.resolve(), str(p))
    return out


def _as_list(runs: Iterable[str | Path] | str | Path) -> list[str | Path]:
    """``runs`` as a list: a single path or pattern is a list of one (not its characters)."""
    return [runs] if isinstance(runs, str | Path) else list(runs)


def _found(runs: Iterable[str | Path]) -> list[Path]:
    found: list[Path] = []
    for item in runs:
        text = str(item)
        path = Path(text)
        if path.is_dir():
            found += sorted([*path.rglob(MANIFEST_NAME), *path.rglob(RUN_NAME)])
        elif path.is_file() and path.suffix.lower() in (".txt", ".lst"):
            lines = [ln.split("#", 1)[0].strip() for ln in path.read_text().splitlines()]
            found += _found([path.parent / ln for ln in lines if ln])
        elif path.is_file():
            found.append(path)
        elif any(ch in text for ch in "*?["):
            found += _found(sorted(glob.glob(text, recursive=True)))
        else:
            raise InputError("no such run manifest, folder or list", path=path,
                             hint="give experiment.toml or run.toml files, folders holding "
                                  "them, a glob or a .txt list of them")
    return found


def manifest_kind(path: Path) -> str:
    """Whether a manifest is a train run or a rig experiment.

    By content (a ``[vehicle]`` table without ``[rig]`` is a run, as the readers decide), else
    by the file name (``run.toml``) when the file does not parse (its reader then names the
    problem).

    Parameters
    ----------
    path : pathlib.Path
        The manifest.

    Returns
    -------
    {"train", "rig"}
        The kind.
    """
    try:
        doc = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        doc = None
    if isinstance(doc, dict) and ("vehicle" in doc or "rig" in doc):
        return "train" if "vehicle" in doc and "rig" not in doc else "rig"
    return "train" if Path(path).name == RUN_NAME else "rig"


def _safe(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in text)


def run_names(manifests: list[Path]) -> list[str]:
    """A partition name per manifest.

    Its folder's name (``folder-stem`` for a manifest not named experiment.toml or run.toml),
    with a short hash of the full path when two manifests share a name.

    Parameters
    ----------
    manifests : list of pathlib.Path
        The manifests.

    Returns
    -------
    list of str
        One name each, unique.
    """
    base = [m.parent.name if m.name in (MANIFEST_NAME, RUN_NAME) or not m.parent.name
            else f"{m.parent.name}-{m.stem}" for m in manifests]
    out = []
    for m, b in zip(manifests, base, strict=True):
        safe = _safe(b or m.stem)
        if base.count(b) > 1:
            safe += "-" + hashlib.sha256(str(m).encode()).hexdigest()[:8]
        out.append(safe)
    return out


def partition_value(value: object, *, day: bool = False) -> str:
    """A hive partition value.

    Characters other than letters, digits and ``-_.`` are replaced by ``_`` (no ``/`` or
    ``=`` can enter the path).

    Parameters
    ----------
    value : object
        The label (vehicle, date).
    day : bool
        Give the ISO day of a date, a date-time or a text starting with an ISO date.
        Default False.

    Returns
    -------
    str
        The value; ``unknown`` for nothing.

    Examples
    --------
    >>> partition_value("ICE 4/12")
    'ICE_4_12'
    >>> partition_value("2024-05-01T10:00", day=True)
    '2024-05-01'
    >>> partition_value(None)
    'unknown'
    """
    if value is None or (isinstance(value, str) and not value.strip()):
        return "unknown"
    if day:
        if isinstance(value, _dt.datetime):
            return value.date().isoformat()
        if isinstance(value, _dt.date):
            return value.isoformat()
        try:
            return _dt.date.fromisoformat(str(value).strip()[:10]).isoformat()
        except ValueError:
            pass
    return _safe(str(value).strip())[:80]


def _file_digest(path: Path, known: dict) -> list:
    """``[size, mtime_ns, sha256]`` of a file; the digest in ``known[str(path)]`` is reused
    when size and modification time are unchanged (a rerun does not read every file again
    just to find it unchanged; the usual assumption of make and rsync)."""
    st = path.stat()
    old = known.get(str(path))
    if old and old[0] == st.st_size and old[1] == st.st_mtime_ns:
        return list(old)
    return [st.st_size, st.st_mtime_ns, sha256_file(path, chunk=1 << 22)]


@dataclass(frozen=True)
class Prepared:
    """A parsed manifest and its fingerprint.

    Attributes
    ----------
    kind : {"rig", "train"}
        The manifest's kind.
    source : Experiment or Run
        The parsed manifest.
    settings : ProcessingConfig or OnboardConfig
        The processing (rig) or ``[onboard]`` (train) settings.
    digest : str
        The fingerprint (SHA-256, hex).
    files : dict
        Each file to ``[size [B], mtime_ns [ns], sha256]``.
    vehicle : str
        The vehicle partition label.
    date : str
        The date partition label (ISO day).
    fresh : frozenset
        The files hashed anew (not taken from ``known``).
    """

    kind: str
    source: Experiment | Run
    settings: ProcessingConfig | OnboardConfig
    digest: str
    files: dict
    vehicle: str
    date: str
    fresh: frozenset = frozenset()  # files hashed now (not digests kept from the last run)
    parameters_digest: str | None = None
    """SHA-256 of the settings (the resume record says from it what changed on a redo)."""
    inputs_digest: str | None = None
    """SHA-256 over the files' SHA-256."""


def prepare(manifest: Path, known: dict | None = None, *, kind: str | None = None,
            fit: bool = True) -> Prepared:
    """Read a manifest and fingerprint it.

    The fingerprint is SHA-256 over the manifest's and each recording's SHA-256, the
    settings, the kind and the torquemod version.

    Parameters
    ----------
    manifest : pathlib.Path
        The manifest.
    known : dict or None
        ``files`` of an earlier call: a file whose size and mtime are unchanged is not hashed
        again. Default None.
    kind : {"rig", "train"} or None
        The kind; None: :func:`manifest_kind`.
    fit : bool
        Whether the rig's creep curve is fitted (part of the settings). Default True.

    Returns
    -------
    Prepared
        The manifest, its settings and fingerprint.

    Raises
    ------
    InputError
        The manifest or its settings are bad.
    """
    known = known or {}
    kind = kind or manifest_kind(manifest)
    if kind == "train":
        from torquemod.io.run import read_run
        from torquemod.ontrain import OnboardConfig
        src = read_run(manifest)
        settings = OnboardConfig.from_dict(src.extra.get("onboard"),
                                           source=str(src.manifest_path))
        params = settings.to_dict()
        dates = sorted(partition_value(e.date, day=True) for e in src.recordings if e.date)
        vehicle, date = src.vehicle.name, dates[0] if dates else None
    else:
        from torquemod.io import read_experiment
        src = read_experiment(manifest)
        settings = src.processing
        params = dict(settings.to_dict(), fit=fit)
        vehicle, date = src.rig.extra.get("vehicle"), src.test.extra.get("date")
    files = {str(Path(src.manifest_path)): _file_digest(Path(src.manifest_path), known)}
    for path in sorted({str(e.path) for e in src.recordings}):
        if Path(path).is_file():
            files[path] = _file_digest(Path(path), known)
    h = hashlib.sha256(kind.encode())
    for path, (_, _, digest) in sorted(files.items()):
        h.update(f"{path}\0{digest}\0".encode())
    h.update(json.dumps(params, sort_keys=True, default=str).encode())
    h.update(__version__.encode())
    fresh = frozenset(p for p, d in files.items() if known.get(p) != d)
    return Prepared(kind, src, settings, h.hexdigest(), files,
                    partition_value(vehicle), partition_value(date, day=True), fresh,
                    parameters_digest=resume.digest(params),
                    inputs_digest=resume.digest({p: d[2] for p, d in files.items()}))


def fingerprint(manifest: Path, known: dict | None = None) -> tuple[str, object, dict]:
    """The fingerprint of a manifest (:func:`prepare`).

    Parameters
    ----------
    manifest : pathlib.Path
        The manifest.
    known : dict or None
        ``files`` of an earlier call. Default None.

    Returns
    -------
    digest : str
        SHA-256, hex.
    source : Experiment or Run
        The parsed manifest.
    files : dict
        Each file to ``[size, mtime_ns, sha256]``.
    """
    p = prepare(Path(manifest), known)
    return p.digest, p.source, p.files


@dataclass(frozen=True)
class Plan:
    """A run to (re)process, split into items.

    The run's recordings (rig: one task per recording file, steps 1-5 and 8 of the chain;
    train: one task per axle), assembled by :func:`finish_run` (rig: alignment, phases, steps
    and the fit, exactly as ``process_experiment``; train: the axles' track tables).

    Attributes
    ----------
    prep : Prepared
        The manifest and its fingerprint.
    manifest : str
        The manifest's path.
    out_dir : str
        The fleet's output folder.
    run : str
        The run's partition name.
    row : dict
        The summary row so far.
    old_parts : tuple of str
        The partitions an earlier processing wrote (replaced).
    fit : bool
        Fit the rig's creep curve.
    seconds : float
        Time spent planning [s].
    revolutions_per_task : int or None
        Revolutions per task of a split rig recording.
    axle_chunk_s : float or None
        Length of the tasks of a split train axle [s].
    """

    prep: Prepared
    manifest: str
    out_dir: str
    run: str
    row: dict
    old_parts: tuple[str, ...]
    fit: bool
    seconds: float
    revolutions_per_task: int | None = None
    axle_chunk_s: float | None = None

    @property
    def n_items(self) -> int:
        return len(self.prep.source.recordings)


def _failed(row: dict, exc: BaseException | str, out_dir: str, old_parts) -> dict:
    """The failure row; an earlier good run's partitions and state are removed (no stale
    results)."""
    row.update(status="failed", message=exc if isinstance(exc, str) else one_line(exc))
    _remove(Path(out_dir), old_parts)
    resume.drop_record(out_dir, row["run"])
    return row


def plan_run(manifest: str, out_dir: str, run: str, force: bool = False, *,
             fit: bool = True, revolutions_per_task: int | None = None,
             axle_chunk_s: float | None = None) -> dict | Plan:
    """Read and fingerprint one run manifest: its plan, or its summary row when done with.

    Never raises (a Dask task).

    Parameters
    ----------
    manifest : str
        The run manifest (experiment.toml or run.toml).
    out_dir : str
        The fleet's output folder.
    run : str
        The run's partition name (:func:`run_names`).
    force : bool
        Reprocess an unchanged run. Default False.
    fit : bool
        Fit the rig experiment's creep curve (mu in the summary). Default True.
    revolutions_per_task : int or None
        Revolutions per task of a split rig recording (:func:`~torquemod.fleet.tasks.scan_item`);
        None: about a minute of recording. Default None.
    axle_chunk_s : float or None
        Length of the tasks of a split train axle [s]; None:
        :data:`~torquemod.fleet.tasks.AXLE_TASK_S`. Default None.

    Returns
    -------
    Plan or dict
        The :class:`Plan`; or a summary row with ``status`` ``skipped`` (unchanged) or
        ``failed`` (the manifest is bad, with its message).
    """
    t0 = time.perf_counter()
    row = dict.fromkeys(SUMMARY_COLUMNS)
    row.update(run=run, manifest=str(manifest), kind=manifest_kind(Path(manifest)),
               vehicle="unknown", date="unknown", n_steps=0, n_cycles=0, n_rows=0,
               message="")
    old = resume.read_record(out_dir, run)
    old_extra = old.extra if old is not None else {}
    old_parts = (old.outputs if old is not None else ()) + tuple(f"{t}/run={run}"
                                                                   for t in TABLES)
    try:
        prep = prepare(Path(manifest), old_extra.get("files"), kind=row["kind"], fit=fit)
    except Exception as exc:
        return dict(_failed(row, exc, out_dir, old_parts), seconds=time.perf_counter() - t0)
    row.update(vehicle=prep.vehicle, date=prep.date)
    out = Path(out_dir)
    decision = resume.decide(
        old, prep.digest, force=force, parameters_digest=prep.parameters_digest,
        inputs_digest=prep.inputs_digest,
        outputs_ok=bool(old and old.outputs) and all((out / p).is_dir() for p in old.outputs))
    if not decision.redo:
        return {**row, **{k: (old_extra.get("row") or {}).get(k) for k in _KEPT},
                "status": "skipped", "seconds": time.perf_counter() - t0}
    row["message"] = decision.message  # a redo says what changed
    return Plan(prep, str(manifest), out_dir, run, row, old_parts, fit,
                time.perf_counter() - t0, revolutions_per_task, axle_chunk_s)


@single_blas
def work_item(plan: Plan, index: int) -> tuple:
    """Process recording ``index`` of a plan. Never raises (a Dask task).

    Parameters
    ----------
    plan : Plan
        The run.
    index : int
        The recording, in manifest order.

    Returns
    -------
    tuple
        ``("ok", result, seconds [s])`` or ``("error", one-line message, seconds [s])``.
    """
    t0 = time.perf_counter()
    prep = plan.prep
    entry = prep.source.recordings[index]
    try:
        if prep.kind == "train":
            from torquemod.ontrain.run import estimate_axle, track_table
            out = track_table(estimate_axle(prep.source, entry, prep.settings))
        else:
            from torquemod.processing.pipeline import load_and_process, resolve_config
            out = load_and_process(entry, prep.source, resolve_config(prep.source))
        return "ok", out, time.perf_counter() - t0
    except Exception as exc:
        return "error", one_line(exc), time.perf_counter() - t0


def _rig_tables(prep: Prepared, loaded: list, fit: bool) -> tuple[dict, dict]:
    """``torquemod process`` without its results folder, from the recordings' results:
    {table: {file: DataFrame}} and the summary fields (the fit's mu when ``fit``)."""
    from torquemod.processing.pipeline import process_experiment
    res = process_experiment(prep.source, workers=1,
                             loaded=list(zip(prep.source.recordings, loaded, strict=True)))
    info = {"n_steps": len(res.steps), "n_cycles": len(res.cycles), "n_rows": len(res.cycles),
            "duration_s": float(sum(d["n_samples"] / d["fs_hz"] for d in res.cycle_details))}
    if fit:
        from torquemod.analysis.analyzer import analyze
        ana = analyze(res)
        pf = ana.phase_fit
        from_phase = ana.mu is None and pf is not None and pf.mu_determined
        mu = ana.mu if ana.mu is not None else (pf.mu if from_phase else None)
        stderr = ana.mu_stderr if ana.mu is not None else (
            getattr(pf, "mu_stderr", None) if from_phase else None)
        info.update(mu=mu, mu_stderr=stderr, mu_lower_bound=ana.mu_lower_bound)
    return {"cycles": {"part-0.parquet": res.cycles},
            "steps": {"part-0.parquet": res.steps}}, info


def _train_tables(prep: Prepared, tracks: list) -> tuple[dict, dict]:
    """``torquemod onboard`` without its results folder: every axle's ``track.parquet``
    table (:func:`torquemod.ontrain.run.track_table`) and the summary fields."""
    run, config = prep.source, prep.settings
    axles = [e.axle for e in run.recordings]
    allrows = pd.concat(tracks, ignore_index=True)
    window_s = config.window_periods / run.modulation_frequency_hz
    given = allrows["mu"].notna()
    from torquemod.ontrain.alongtrack import run_mu_summary
    mu, bound = run_mu_summary(allrows)
    info = {"n_rows": len(allrows),
            "duration_s": max(float(t["time_s"].iloc[-1] - t["time_s"].iloc[0]) + window_s
                              for t in tracks),
            "mu": mu, "mu_lower_bound": bound,
            "mu_given_share": float(given.mean()),
            "low_adhesion_windows": int(allrows["low_adhesion"].sum()),
            "slip_windows": int(allrows["slip"].sum())}
    return {"track": {f"axle={a}/part-0.parquet": t
                      for a, t in sorted(zip(axles, tracks, strict=True))}}, info


@single_blas
def finish_run(plan: Plan, *items: tuple, layout: list | None = None) -> dict:
    """Assemble a run from its items and write its partitions and state.

    The first failed item, in manifest order, fails the run with its message (the one the
    sequential command meets first). Never raises (a Dask task).

    Parameters
    ----------
    plan : Plan
        The run.
    *items : tuple
        The items' results (:func:`work_item`, :func:`~torquemod.fleet.tasks.part_item`), in
        manifest order.
    layout : list or None
        The parts of split recordings. Default None.

    Returns
    -------
    dict
        The run's summary row (:data:`SUMMARY_COLUMNS`).
    """
    t0 = time.perf_counter()
    row = dict(plan.row)
    seconds = plan.seconds
    parts: list[str] = []  # written by this task: removed again if the run fails after all
    try:
        items = tuple(_recording_items(plan, items, layout))
        seconds += sum(it[2] for it in items)
        errors = [it[1] for it in items if it[0] != "ok"]
        if errors:
            raise _ItemError(errors[0])
        results = [it[1] for it in items]
        prep = plan.prep
        tables, info = (_train_tables(prep, results) if prep.kind == "train"
                        else _rig_tables(prep, results, plan.fit))
        out = Path(plan.out_dir)
        where = f"vehicle={prep.vehicle}/date={prep.date}/run={plan.run}"
        for table, files in tables.items():
            parts.append(f"{table}/{where}")
            _write_partition(files, out / table / where)
        _remove(out, [p for p in plan.old_parts if p not in parts])
        row.update(info, status="processed")
        resume.write_record(plan.out_dir, resume.ResumeRecord(
            name=plan.run, fingerprint=prep.digest, outputs=tuple(parts),
            parameters_digest=prep.parameters_digest, inputs_digest=prep.inputs_digest,
            extra={"manifest": plan.manifest, "partitions": parts, "files": prep.files,
                   "row": {k: row[k] for k in _KEPT}}))
    except _ItemError as exc:
        _failed(row, str(exc), plan.out_dir, plan.old_parts)
    except Exception as exc:  # a bad run (or a bug) is reported; the fleet goes on
        _failed(row, exc, plan.out_dir, (*plan.old_parts, *parts))
    row["seconds"] = seconds + time.perf_counter() - t0
    return row


class _ItemError(Exception):
    """An item's failure, carried to :func:`finish_run` as its one-line message."""


def process_run(manifest: str, out_dir: str, run: str, force: bool = False, *,
                fit: bool = True, revolutions_per_task: int | None = None,
                axle_chunk_s: float | None = None) -> dict:
    """Process one run manifest (rig or train) into its partitions in this process.

    What :func:`~torquemod.fleet.run.run_fleet` does with tasks, in sequence. Never raises.

    Parameters
    ----------
    manifest : str
        The run manifest (experiment.toml or run.toml).
    out_dir : str
        The fleet's output folder.
    run : str
        The run's partition name (:func:`run_names`).
    force : bool
        Reprocess an unchanged run. Default False.
    fit : bool
        Fit the rig experiment's creep curve (mu in the summary). Default True.
    revolutions_per_task : int or None
        Revolutions per task of a split rig recording (:func:`~torquemod.fleet.tasks.scan_item`);
        None: about a minute of recording. Default None.
    axle_chunk_s : float or None
        Length of the tasks of a split train axle [s]; None:
        :data:`~torquemod.fleet.tasks.AXLE_TASK_S`. Default None.

    Returns
    -------
    dict
        The summary row: ``status`` processed, skipped or failed (:data:`SUMMARY_COLUMNS`).
    """
    plan = plan_run(manifest, out_dir, run, force, fit=fit,
                    revolutions_per_task=revolutions_per_task, axle_chunk_s=axle_chunk_s)
    if isinstance(plan, dict):
        return plan
    items, layout = [], []
    for i in range(plan.n_items):
        kind, rplan, groups, scan_s, first = (scan_item(plan, i) if may_split(plan, i)
                                              else ("whole", None, None, 0.0, None))
        if kind == "split":
            items += [first] if first is not None else []
            items += [part_item(plan, i, rplan, a, b)
                      for a, b in groups[0 if first is None else 1:]]
            layout.append((rplan, len(groups), scan_s))
        else:
            items.append(work_item(plan, i))
            layout.append(None)
    return finish_run(plan, *items, layout=layout)


def _write_partition(files: dict, folder: Path) -> None:
    """``files`` ({relative path: DataFrame}) as the folder ``folder``, replacing it whole
    through the results writer (mode ``"replace"``: written beside it under a hidden name,
    which dataset readers skip, then renamed), so a reader never sees half a partition."""
    with write_folder(folder, mode="replace") as w:
        for rel, df in files.items():
            (w.path / rel).parent.mkdir(parents=True, exist_ok=True)
            df.to_parquet(w.path / rel, index=False)


def _remove(out: Path, rels: Iterable[str]) -> None:
    for rel in rels:
        shutil.rmtree(out / rel, ignore_errors=True)
