"""Many rig experiments and train runs at once on Dask: tasks per recording, in
worker processes.

:func:`run_fleet` sends the fleet to Dask worker processes (a ``LocalCluster`` of processes
sized to the machine, or an existing scheduler). Per run manifest, a task reads and
fingerprints it (:func:`plan_run`); a run to process becomes one task per recording
(:func:`work_item`: for a rig experiment, steps 1-5 and 8 of the chain on one recording file,
usually one cycle; for a train run, the on-board estimator on one axle), except that a long
rig file of many revolutions becomes a scan task and one task per group of revolutions
(:mod:`torquemod.fleet.tasks`, :mod:`torquemod.processing.revtasks`), and a task that
assembles them (:func:`finish_run`: for a rig, the alignment, phases, steps and creep-curve fit
of ``process_experiment`` and ``torquemod process``; for a train run, the axles' tracks of
``torquemod onboard``). Each worker runs one thread (the processes are the parallelism: the
GIL makes threads of this chain useless) and writes its tables as partitions of Parquet
datasets::

    OUT/cycles/vehicle=<v>/date=<d>/run=<run>/part-0.parquet          rig: per cycle
    OUT/steps/vehicle=<v>/date=<d>/run=<run>/part-0.parquet           rig: per step
    OUT/track/vehicle=<v>/date=<d>/run=<run>/axle=<n>/part-0.parquet  train: per window
    OUT/fleet_summary.csv     one row per run (:data:`SUMMARY_COLUMNS`)
    OUT/failures.csv          one row per failed run: the one-line message
    OUT/fleet_report.html     the summary, the failures and figures (torquemod.fleet.report)
    OUT/provenance.json       the provenance block: settings, manifests with SHA-256
    OUT/_state/<run>.json     the run's resume record (torquemod.results.resume)

The summary files are written together through :func:`torquemod.results.writer.write_folder`
(staged in OUT, moved in when all are written); each run's partitions replace the old ones
whole.

The ``track`` files hold exactly the 14 columns of ``torquemod onboard``'s ``track.parquet``;
the partition keys (hive layout) add ``vehicle``, ``date``, ``run`` (and ``axle``) when pandas,
Dask or DuckDB read ``OUT/track`` (or ``OUT/cycles``, ``OUT/steps``) as a dataset.
``vehicle`` is the free text ``[vehicle] vehicle`` of run.toml or ``[rig] vehicle`` of
experiment.toml; ``date`` the recordings' ``date`` (run.toml ``[[recording]]``, the earliest
when the axles differ) or ``[test] date`` of experiment.toml; the day of a TOML date or of an
ISO text, else the text; characters other than letters, digits, ``-_.`` become ``_``; absent
means ``unknown``.

A bad run never stops the fleet: its error, the same line ``torquemod process`` or
``torquemod onboard`` prints after ``torquemod: error:``, becomes a row of the failures table.
A rerun skips a run whose fingerprint (SHA-256 of the manifest and of every recording, the
processing or ``[onboard]`` settings, the torquemod version) is unchanged and whose partitions
are in place; a file whose size and modification time are unchanged keeps its recorded digest.
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from torquemod._util.daskutil import CONNECT_TIMEOUT_S, check_cluster
from torquemod.errors import InputError
from torquemod.fleet.plan import (  # noqa: F401  (the fleet's per-run API, here as before)
    MANIFEST_NAME,
    RUN_NAME,
    SUMMARY_COLUMNS,
    TABLES,
    Plan,
    Prepared,
    _as_list,
    _spellings,
    find_manifests,
    fingerprint,
    finish_run,
    manifest_kind,
    partition_value,
    plan_run,
    prepare,
    process_run,
    run_names,
    work_item,
)
from torquemod.fleet.tasks import may_split, one_line, part_item, scan_item
from torquemod.processing.provenance import provenance_block
from torquemod.results.writer import write_folder


def prune_empty(out: Path) -> None:
    """Tidy the fleet's datasets once no task writes.

    Removes the hidden leftovers of a partition write cut short (``.run=<run>.tmp``/``.old``,
    e.g. by a killed worker) and empty partition folders (a run that moved to another vehicle
    or date, or failed).

    Parameters
    ----------
    out : pathlib.Path
        The fleet's output folder.
    """
    for table in TABLES:
        root = out / table
        if not root.is_dir():
            continue
        for folder, dirs, _files in os.walk(root, topdown=False):
            for d in dirs:  # .run=<run>.tmp-XXXXXXXX (the writer's), .tmp/.old (earlier)
                if d.startswith(".") and (d.endswith((".tmp", ".old"))
                                          or ".tmp-" in d or ".old-" in d):
                    shutil.rmtree(Path(folder) / d, ignore_errors=True)
            if Path(folder) != root:
                try:
                    os.rmdir(folder)
                except OSError:
                    pass  # not empty


@dataclass(frozen=True)
class FleetResult:
    """What :func:`run_fleet` did.

    Attributes
    ----------
    out_dir : pathlib.Path
        The output folder.
    summary : pandas.DataFrame
        One row per run (:data:`SUMMARY_COLUMNS`).
    failures : pandas.DataFrame
        Its failed rows.
    dashboard : str or None
        The Dask dashboard's address; None when the cluster has none.
    wall_s : float
        Wall time [s].
    report : pathlib.Path or None
        The report; None when not written.
    report_s : float
        Time of ``wall_s`` spent writing the report [s]. Default 0.
    """

    out_dir: Path
    summary: pd.DataFrame
    failures: pd.DataFrame
    dashboard: str | None
    wall_s: float
    report: Path | None = None
    report_s: float = 0.0

    def count(self, status: str) -> int:
        return int((self.summary["status"] == status).sum())


def run_fleet(manifests: Iterable[str | Path], out_dir: str | Path, *,
              scheduler: str | None = None, n_workers: int | None = None,
              force: bool = False, progress: bool = False, fit: bool = True,
              report: bool = True, on_dashboard=None,
              revolutions_per_task: int | None = None,
              axle_chunk_s: float | None = None,
              connect_timeout_s: float = CONNECT_TIMEOUT_S) -> FleetResult:
    """Process many run manifests in parallel on Dask and write the fleet's outputs.

    Rig experiments and train runs; the outputs are the datasets, the summary, the failures
    and the report.

    Parameters
    ----------
    manifests : iterable of str or pathlib.Path
        As :func:`~torquemod.fleet.plan.find_manifests` takes them.
    out_dir : str or pathlib.Path
        The output folder (new, or one a fleet wrote).
    scheduler : str or None
        Address of an existing Dask scheduler (``tcp://host:8786``); None starts a
        ``LocalCluster`` and stops it at the end.
    n_workers : int or None
        Single-threaded worker processes of the local cluster; None: the CPU count.
    force : bool
        Reprocess unchanged runs. Default False.
    progress : bool
        Show a progress bar on stderr. Default False.
    fit : bool
        Fit the rig experiments' creep curves (mu in the summary). Default True.
    report : bool
        Write ``fleet_report.html``. Default True.
    on_dashboard : callable or None
        Called with the dashboard address when there is one.
    revolutions_per_task : int or None
        A rig recording spanning many revolutions becomes one task per that many revolutions
        (default: about :data:`torquemod.processing.revtasks.TASK_SECONDS` of recording each,
        and only for files that ``process`` streams, >= 256 MiB).
    axle_chunk_s : float or None
        A train axle recording with random row access (HDF5, MAT v7.3, MDF4, TDMS) longer
        than this [s] becomes one task per chunk (:mod:`torquemod.ontrain.chunks`; the track
        is ``onboard``'s); None: about :data:`torquemod.fleet.tasks.AXLE_TASK_S` (10 min).
    connect_timeout_s : float
        Time a scheduler has to answer [s]. Default :data:`CONNECT_TIMEOUT_S`.

    Returns
    -------
    FleetResult
        What was done.

    Raises
    ------
    InputError
        No manifests found, ``out_dir`` not a folder, a malformed ``scheduler`` address or
        ``n_workers`` < 1 (before anything is read), or a scheduler that does not answer
        within ``connect_timeout_s`` (before anything is written).
    """
    scheduler = check_cluster(scheduler, n_workers, connect_timeout_s)
    manifests = _as_list(manifests)  # read twice below (a generator would be used up)
    spelled = _spellings(manifests)
    paths = sorted(spelled)
    if not paths:
        raise InputError("no run manifests found (no experiment.toml or run.toml)",
                         path=", ".join(map(str, manifests)) or None,
                         hint="give experiment.toml or run.toml files, folders holding "
                              "them, a glob or a list file")
    out = Path(out_dir).resolve()
    if out.exists() and not out.is_dir():
        raise InputError("the fleet output is not a folder", path=out_dir,
                         hint="give --out a folder (new, or one a fleet wrote)")
    from torquemod._util.fsutil import output_lock, refuse_inputs
    refuse_inputs(out, paths)  # the datasets never go into a folder holding a manifest
    with output_lock(out):  # one fleet at a time writes OUT (a second one fails at once)
        return _run_locked(paths, spelled, out, scheduler=scheduler, n_workers=n_workers,
                           force=force, progress=progress, fit=fit, report=report,
                           on_dashboard=on_dashboard,
                           revolutions_per_task=revolutions_per_task,
                           axle_chunk_s=axle_chunk_s, connect_timeout_s=connect_timeout_s)


def _run_locked(paths: list[Path], spelled: dict, out: Path, *, scheduler, n_workers, force,
                progress, fit, report, on_dashboard, revolutions_per_task,
                axle_chunk_s, connect_timeout_s) -> FleetResult:
    from torquemod._util.daskutil import dask_client
    from torquemod._util.fsutil import removed_if_left_empty

    names = run_names(paths)
    t0 = time.perf_counter()
    links: list[str] = []

    def dashboard(link: str) -> None:
        links.append(link)
        if on_dashboard is not None:
            on_dashboard(link)

    with removed_if_left_empty(out), dask_client(
            scheduler, n_workers, dashboard, connect_timeout_s=connect_timeout_s) as client:
        out.mkdir(parents=True, exist_ok=True)  # once the cluster answers
        rows = run_tasks(client, paths, names, str(out), force, fit, progress,
                         revolutions_per_task, axle_chunk_s)
    prune_empty(out)
    for row in rows:  # the manifest named as `torquemod process PATH` names it
        given = spelled.get(Path(row["manifest"]))
        if row["status"] == "failed" and given and given != row["manifest"]:
            row["message"] = str(row["message"]).replace(row["manifest"], given)
    summary = pd.DataFrame(rows, columns=SUMMARY_COLUMNS).sort_values("run",
                                                                      ignore_index=True)
    counts = ["n_rows", "n_steps", "n_cycles", "low_adhesion_windows", "slip_windows"]
    summary[counts] = summary[counts].astype("Int64")  # integers with gaps, not floats
    failures = summary.loc[summary["status"] == "failed",
                           ["run", "kind", "manifest", "message"]].reset_index(drop=True)
    page, t_report = None, time.perf_counter()
    with write_folder(out, mode="into", provenance=fleet_provenance(
            paths, names, fit=fit, force=force, revolutions_per_task=revolutions_per_task,
            axle_chunk_s=axle_chunk_s)) as w:
        _write_csv(summary, w.path / "fleet_summary.csv")
        _write_csv(failures, w.path / "failures.csv")
        if report:
            from torquemod.fleet.report import write_fleet_report
            write_fleet_report(out, summary, failures, dest=w.path)
            page = out / "fleet_report.html"
    return FleetResult(out, summary, failures, links[0] if links else None,
                       time.perf_counter() - t0, page, time.perf_counter() - t_report)


def fleet_provenance(paths: list[Path], names: list[str], **parameters) -> dict:
    """The provenance block of a fleet's folder (kind ``"fleet"``).

    Parameters
    ----------
    paths : list of pathlib.Path
        The run manifests.
    names : list of str
        Their run names.
    **parameters
        The fleet's settings.

    Returns
    -------
    dict
        :func:`~torquemod.processing.provenance.provenance_block` of the settings and every
        manifest with its SHA-256 and run name (each run's recordings, with their SHA-256,
        are in its resume record ``_state/<run>.json``).
    """
    return provenance_block("fleet", parameters,
                            [{"file": p, "run": n} for p, n in zip(paths, names, strict=True)])


def _write_csv(df: pd.DataFrame, path: Path) -> None:
    df.to_csv(path, index=False)


def run_tasks(client, paths: list[Path], names: list[str], out: str, force: bool,
               fit: bool, progress: bool, revolutions_per_task: int | None = None,
               axle_chunk_s: float | None = None) -> list[dict]:
    """Run the fleet's task graph, grown as results arrive.

    Per run a :func:`~torquemod.fleet.plan.plan_run` task; for a run to process, per
    recording one :func:`~torquemod.fleet.plan.work_item` task, or for a rig recording that
    may be split a :func:`~torquemod.fleet.tasks.scan_item` task and then one
    :func:`~torquemod.fleet.tasks.part_item` task per group of revolutions; once every
    recording of the run has its tasks, a :func:`~torquemod.fleet.plan.finish_run` task on
    their results.

    Parameters
    ----------
    client : distributed.Client
        The Dask client.
    paths : list of pathlib.Path
        The manifests.
    names : list of str
        Their partition names.
    out : str
        The output folder.
    force : bool
        Reprocess unchanged runs.
    fit : bool
        Fit the rig experiments' creep curves.
    progress : bool
        Show a progress bar.
    revolutions_per_task : int or None
        As :func:`run_fleet`.
    axle_chunk_s : float or None
        As :func:`run_fleet` [s].

    Returns
    -------
    list of dict
        The summary rows; a task lost with its worker (killed, out of memory) becomes a
        failed row.
    """
    from dask.distributed import as_completed
    from tqdm import tqdm


    def key(kind: str, name: str) -> str:
        return f"torquemod-{kind}-{name}-{time.time_ns()}"

    runs = {}  # plan and finish futures -> (run, manifest)
    scans = {}  # scan futures -> (run, recording index)
    open_runs: dict[str, dict] = {}  # run -> plan, per recording its futures and layout
    for p, name in zip(paths, names, strict=True):
        runs[client.submit(plan_run, str(p), out, name, force, fit=fit,
                           revolutions_per_task=revolutions_per_task,
                           axle_chunk_s=axle_chunk_s, pure=False,
                           key=key("plan", name))] = (name, str(p))
    rows = []
    bar = tqdm(total=len(runs), desc="fleet", unit="run", disable=not progress)
    done = as_completed(list(runs))

    def whole(plan: Plan, name: str, i: int) -> tuple[list, None]:
        return [client.submit(work_item, plan, i, pure=False, key=key(f"item{i}", name))], None

    def finish_when_ready(name: str) -> None:
        st = open_runs[name]
        if st["waiting"]:
            return
        del open_runs[name]
        futs = [f for slot in st["slots"] for f in slot[0]]
        last = client.submit(finish_run, st["plan"], *futs,
                             layout=[slot[1] for slot in st["slots"]], pure=False,
                             key=key("finish", name))
        runs[last] = (name, st["manifest"])
        done.add(last)

    for fut in done:
        if fut in scans:
            name, i = scans.pop(fut)
            st = open_runs[name]
            try:
                kind, rplan, groups, scan_s, first = fut.result()
            except Exception:  # the worker died under the scan: one task for the file
                kind = "whole"
            if kind == "split":
                done_first = [] if first is None else [first]
                st["slots"][i] = (done_first + [
                    client.submit(part_item, st["plan"], i, rplan, a, b, pure=False,
                                  key=key(f"part{i}.{a}", name))
                    for a, b in groups[len(done_first):]], (rplan, len(groups), scan_s))
            else:
                st["slots"][i] = whole(st["plan"], name, i)
            st["waiting"] -= 1
            finish_when_ready(name)
            continue
        name, manifest = runs.pop(fut)  # nothing held once handled
        try:
            res = fut.result()
        except Exception as exc:  # the worker died under the task
            row = dict.fromkeys(SUMMARY_COLUMNS)
            row.update(run=name, manifest=manifest, kind=manifest_kind(Path(manifest)),
                       status="failed", message=one_line(exc))
            rows.append(row)
            bar.update()
            continue
        if isinstance(res, Plan):
            st = {"plan": res, "manifest": manifest, "slots": [], "waiting": 0}
            open_runs[name] = st
            for i in range(res.n_items):
                if may_split(res, i):
                    scan = client.submit(scan_item, res, i, pure=False,
                                         key=key(f"scan{i}", name))
                    scans[scan] = (name, i)
                    done.add(scan)
                    st["slots"].append(None)
                    st["waiting"] += 1
                else:
                    st["slots"].append(whole(res, name, i))
            finish_when_ready(name)
            continue
        rows.append(res)
        bar.update()
    bar.close()
    return rows
