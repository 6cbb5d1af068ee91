"""Running a sweep: batches of points as Dask tasks on worker processes (each point
evaluated and written on its own inside its batch), or the points in this process;
resumable point by point, every output written atomically::

    OUT/points/point=<id>/part-0.parquet   the rows of one finished point
    OUT/_state/<id>.json                   its resume record (torquemod.results.resume):
                                           fingerprint (parameters, seed, mode, base
                                           config, torquemod version), status, seconds
    OUT/provenance.json                    the provenance block: spec, inputs with SHA-256
    OUT/sweep.parquet                      every point's rows (metadata: version, sweep file)
    OUT/failures.csv                       one row per failed point: its one-line message
    OUT/sweep.json                         version, sweep spec, seeds, counts, wall time,
                                           the recommendation
    OUT/figures/*.png, OUT/report.html     (:mod:`torquemod.sweep.report`)

A rerun skips a point whose partition is in place and whose fingerprint is unchanged
(:func:`torquemod.results.resume.decide`; a redone point's message says what changed);
``force`` reruns every point. Each point's folder and the summary files are published by
:func:`torquemod.results.writer.write_folder`. A point that fails (bad parameter value,
wheel slipping at the first step, ...) becomes a row of failures.csv and the sweep goes on.
"""

from __future__ import annotations

import contextlib
import csv
import json
import shutil
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from torquemod._util.daskutil import CONNECT_TIMEOUT_S, check_cluster
from torquemod._util.fsutil import (
    environment_error,
    output_lock,
    removed_if_left_empty,
)
from torquemod._util.jsonutil import dump_json
from torquemod._version import __version__
from torquemod.errors import InputError, OutputError, TorquemodError
from torquemod.results import resume
from torquemod.results.writer import write_folder
from torquemod.sweep import finish
from torquemod.sweep.evaluate import PointTask, evaluate_point, tasks
from torquemod.sweep.schedule import plan_line, point_batches
from torquemod.sweep.spec import SweepSpec, load_sweep
from torquemod.sweep.state import (  # noqa: F401  (fingerprint: the sweep's API, here as before)
    digests,
    fingerprint,
    one_study,
    partition_path,
    study_key,
    sweep_provenance,
)

__all__ = ["SweepResult", "fingerprint", "plan_line", "point_batches", "run_point",
           "run_points", "run_sweep", "tasks"]

FAILURE_COLUMNS = ["point_id", "point_index", "seed", "params", "message"]


#: what the local cluster's workers have imported before their first point: they are forked
#: from a fork server that imported these (:func:`torquemod._util.daskutil.
#: start_worker_server`; ``torquemod sweep`` starts it before its own imports)
WORKER_MODULES = ("torquemod.sweep.workerpreload",)


def _write_parquet(df: pd.DataFrame, path: Path, metadata: dict | None = None) -> None:
    """``df`` as Parquet at ``path`` (a file of a folder the results writer publishes),
    with ``metadata`` in the schema's key-value metadata."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(df, preserve_index=False)
    if metadata:
        table = table.replace_schema_metadata({**(table.schema.metadata or {}),
                                               **{k.encode(): v.encode()
                                                  for k, v in metadata.items()}})
    pq.write_table(table, path)


def _hashable_params(table: pd.DataFrame, keys) -> pd.DataFrame:
    """``table`` with list- or array-valued cells of the columns ``keys`` as JSON text
    (e.g. ``"[80.0, 90.0]"``); the table itself when there are none."""
    import numpy as np
    cols = [k for k in keys if k in table and table[k].map(
        lambda v: isinstance(v, list | tuple | np.ndarray)).any()]
    if not cols:
        return table
    view = table.copy()
    for k in cols:
        view[k] = view[k].map(lambda v: json.dumps(np.asarray(v).tolist())
                              if isinstance(v, list | tuple | np.ndarray) else v)
    return view


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    if isinstance(exc, TorquemodError):
        return text
    env = environment_error(exc)  # a full disk, a read-only folder: the system's
    if env is not None:
        reason = env.strerror or " ".join(str(env).split())
        return f"{env.filename}: {reason}" if env.filename else reason
    return f"internal error: {type(exc).__name__}: {text}"


def _decision(task: PointTask, out: Path, force: bool):
    """(the point's digests, :func:`~torquemod.results.resume.decide`'s decision, its
    record or None)."""
    digest, params_digest, inputs_digest = digests(task)
    old = resume.read_record(out, task.point_id)
    decision = resume.decide(old, digest, outputs_ok=partition_path(out, task.point_id).is_file(),
                             force=force, parameters_digest=params_digest,
                             inputs_digest=inputs_digest)
    return (digest, params_digest, inputs_digest), decision, old


def _unchanged(todo: list[PointTask], out: Path, force: bool) -> tuple[list[dict], list]:
    """The status rows of the points that a run would skip (decided here, as
    :func:`run_point` decides, so that no worker starts for them) and the points to run."""
    rows, run = [], []
    for task in todo:
        t0 = time.perf_counter()
        if force or not resume.record_path(out, task.point_id).is_file():
            run.append(task)  # runs whatever its digests (a new folder: none computed)
            continue
        try:
            _digests, decision, old = _decision(task, out, force)
        except Exception:  # run_point says what is wrong with the point
            run.append(task)
            continue
        if decision.redo:
            run.append(task)
        else:
            rows.append({"point_id": task.point_id, "point_index": task.index,
                         "seed": task.seed, "status": "skipped",
                         "n_rows": old.extra.get("n_rows", 0), "message": "",
                         "seconds": time.perf_counter() - t0})
    return rows, run


def run_point(task: PointTask, out_dir: str, force: bool = False) -> dict:
    """Evaluate one point into its partition (a Dask task; also usable alone). Never raises.

    Parameters
    ----------
    task : PointTask
        The point.
    out_dir : str
        The sweep's output folder.
    force : bool
        Rerun a point whose fingerprint is unchanged. Default False.

    Returns
    -------
    dict
        Status row: ``done``, ``skipped`` or ``failed`` with the message; rows written,
        seconds [s].
    """
    t0 = time.perf_counter()
    out = Path(out_dir)
    row = {"point_id": task.point_id, "point_index": task.index, "seed": task.seed,
           "status": "failed", "n_rows": 0, "message": ""}
    part = partition_path(out, task.point_id)
    try:
        (digest, params_digest, inputs_digest), decision, old = _decision(task, out, force)
        if not decision.redo:
            return {**row, "status": "skipped", "n_rows": old.extra.get("n_rows", 0),
                    "seconds": time.perf_counter() - t0}
        work = None
        if task.kind == "train":  # its run goes through a folder
            work = out / "_work"
            work.mkdir(parents=True, exist_ok=True)
        df = evaluate_point(task, workdir=work)
        with write_folder(part.parent, mode="replace") as w:
            _write_parquet(df, w.path / part.name)
        resume.write_record(out, resume.ResumeRecord(
            name=task.point_id, fingerprint=digest, parameters_digest=params_digest,
            inputs_digest=inputs_digest,
            outputs=(str(part.parent.relative_to(out)),),
            extra={"point_id": task.point_id, "params": task.params, "seed": task.seed,
                   "n_rows": len(df), "seconds": time.perf_counter() - t0}))
        row.update(status="done", n_rows=len(df), message=decision.message)
    except Exception as exc:  # a bad point never stops the sweep: it becomes a failure row
        row["message"] = _one_line(exc)
        if isinstance(exc, OutputError) or (not isinstance(exc, TorquemodError)
                                            and environment_error(exc) is not None):
            row["system"] = True  # the sweep stops (the next points would fail alike)
        shutil.rmtree(part.parent, ignore_errors=True)  # no stale rows of an earlier run
        resume.drop_record(out, task.point_id)
    row["seconds"] = time.perf_counter() - t0
    return row


@dataclass(frozen=True)
class SweepResult:
    """What :func:`run_sweep` did.

    Attributes
    ----------
    out_dir : pathlib.Path
        The output folder.
    table : pandas.DataFrame
        One row per point and step (a train sweep: per point and friction segment).
    status : pandas.DataFrame
        The status of each point.
    failures : pandas.DataFrame
        The failed points.
    recommendation : dict
        The recommendation (:func:`torquemod.sweep.summary.recommend`).
    report : pathlib.Path or None
        The report; None when not written.
    dashboard : str or None
        The Dask dashboard's address.
    wall_s : float
        Wall time [s].
    """

    out_dir: Path
    table: pd.DataFrame
    status: pd.DataFrame
    failures: pd.DataFrame
    recommendation: dict
    report: Path | None
    dashboard: str | None
    wall_s: float

    def count(self, status: str) -> int:
        return int((self.status["status"] == status).sum())


def _evaluate_all(todo: list[PointTask], out: Path, *, in_process: bool, scheduler,
                  n_workers, force: bool, progress: bool, on_dashboard, begin,
                  connect_timeout_s: float = CONNECT_TIMEOUT_S,
                  closing: list | None = None, tail=None, stack=None,
                  warm: bool = False, cluster=None,
                  frames: dict | None = None) -> tuple[list, str, object]:
    """Every point's status row, the dashboard's address and the local cluster's client
    (None without one) for drawing the report's figures (``begin()`` creates the output
    when the work can start).

    The points a run would skip are decided here; a local cluster starts only when some
    point is left to run. Its client is entered into ``stack`` (a ``contextlib.ExitStack``
    the caller closes after the report; the cluster then closes in a thread appended to
    ``closing``, joined by the caller). ``tail()`` runs in a thread once fewer batches are
    left than worker slots (a core the workers no longer use), and is waited for before
    this returns; ``warm`` then also gives each worker the drawing code's imports
    (:func:`~torquemod.sweep.finish.warm_workers`) to run once it has no point left.
    ``cluster``: the local cluster already starting (:class:`~torquemod._util.daskutil.
    EarlyCluster`), used when points are left to run. ``frames`` receives the partitions
    of the points a batch finished, read while the other batches run (for
    :func:`assemble`)."""
    from tqdm import tqdm
    rows, links = [], []
    if not in_process:
        rows, todo = _unchanged(todo, out, force)
        if not todo:
            begin()
            return rows, None, None
    if in_process:
        begin()
        bar = tqdm(total=len(todo), desc="sweep", unit="point", disable=not progress)
        for task in todo:
            rows.append(run_point(task, str(out), force))
            bar.update()
        bar.close()
        return rows, None, None
    from dask.distributed import as_completed

    from torquemod._util.daskutil import dask_client

    def dashboard(link: str) -> None:
        links.append(link)
        if on_dashboard is not None:
            on_dashboard(link)

    client = stack.enter_context(dask_client(
        scheduler, n_workers, dashboard, connect_timeout_s=connect_timeout_s,
        closing=closing, worker_modules=WORKER_MODULES, started=cluster))
    begin()  # once the cluster answers
    bar = tqdm(total=len(todo), desc="sweep", unit="point", disable=not progress)
    slots = sum(client.nthreads().values()) or 1
    since = time.time()
    futures = {client.submit(run_points, b, str(out), force, pure=False,
                             key=f"torquemod-sweep-{b[0].point_id}-{time.time_ns()}"): b
               for b in point_batches(todo, slots)}
    left, helper = len(futures), None
    try:
        for fut in as_completed(futures):
            try:
                done = fut.result()
            except Exception as exc:  # the worker died (memory, a kill): points failed
                done = _lost(futures[fut], out, _one_line(exc), since, force)
            rows.extend(done)
            if frames is not None:
                finish.read_parts(done, out, frames)
            bar.update(len(futures[fut]))
            left -= 1
            if tail is not None and helper is None and 0 < left < slots:
                if warm and scheduler is None:  # kept until the figures are drawn
                    stack.callback(list.clear, finish.warm_workers(client))
                helper = threading.Thread(target=tail, name="torquemod-sweep-tail",
                                          daemon=True)
                helper.start()
    finally:
        if helper is not None:
            helper.join()
    bar.close()
    return rows, (links[0] if links else None), (client if scheduler is None else None)


def run_points(batch: list[PointTask], out_dir: str, force: bool = False) -> list[dict]:
    """:func:`run_point` for each point of a batch, one after another (a Dask task).

    Each point's partition and state are written as soon as it is done, so an interrupted
    batch resumes point by point.

    Parameters
    ----------
    batch : list of PointTask
        The points.
    out_dir : str
        The sweep's output folder.
    force : bool
        Rerun unchanged points. Default False.

    Returns
    -------
    list of dict
        Their status rows.
    """
    return [run_point(t, out_dir, force) for t in batch]


def _lost(batch: list[PointTask], out: Path, why: str, since: float = 0.0,
          force: bool = False) -> list[dict]:
    """Status rows of a batch whose worker died: a point whose partition and state of its
    fingerprint are in place is done when its state was written at or after ``since`` [s,
    epoch] (by this run), skipped when older (unless ``force``, which wanted it rerun); the
    others failed."""
    rows = []
    for t in batch:
        row = {"point_id": t.point_id, "point_index": t.index, "seed": t.seed,
               "status": "failed", "n_rows": 0, "seconds": float("nan"),
               "message": f"worker lost: {why}"}
        rec = resume.read_record(out, t.point_id)
        try:
            written = resume.record_path(out, t.point_id).stat().st_mtime
        except OSError:
            written = 0.0
        if partition_path(out, t.point_id).is_file() and rec is not None \
                and rec.fingerprint == fingerprint(t):
            status = "done" if written >= since else None if force else "skipped"
            if status is not None:
                row.update(status=status, n_rows=int(rec.extra.get("n_rows", 0)), message="",
                           seconds=float(rec.extra.get("seconds", float("nan"))))
        rows.append(row)
    return rows


def assemble(out: Path, spec: SweepSpec, status: pd.DataFrame,
             frames: dict | None = None) -> pd.DataFrame:
    """The sweep table from the partitions of the points that are done.

    This spec's points only; stale partitions of an earlier spec are left alone.

    Parameters
    ----------
    out : pathlib.Path
        The output folder.
    spec : SweepSpec
        The sweep.
    status : pandas.DataFrame
        The points' status.
    frames : dict or None
        Partitions already read (point id -> table, as read here), e.g. while the
        other points ran. Default None.

    Returns
    -------
    pandas.DataFrame
        Sorted by point and step (train: segment); empty when no point is done.
    """
    order = {p.point_id: p.index for p in spec.points}
    ok = status.loc[status["status"].isin(["done", "skipped"]), "point_id"]
    read = frames or {}
    frames = [read[pid] if pid in read else pd.read_parquet(partition_path(out, pid))
              for pid in ok]
    if not frames:
        return pd.DataFrame()
    table = pd.concat(frames, ignore_index=True)
    table["point_index"] = table["point_id"].map(order)
    return table.sort_values(["point_index", "segment" if spec.kind == "train" else "step"],
                             ignore_index=True)


def run_sweep(sweep: SweepSpec | str | Path, out_dir: str | Path, *,
              in_process: bool = False, scheduler: str | None = None,
              n_workers: int | None = None, force: bool = False, progress: bool = False,
              report: bool = True, on_dashboard=None,
              connect_timeout_s: float = CONNECT_TIMEOUT_S, on_start=None,
              cluster=None) -> SweepResult:
    """Run a sweep into a results folder.

    Points run as Dask tasks: on the scheduler at ``scheduler``, else on a local cluster of
    single-threaded worker processes; ``in_process`` runs them one after another here instead
    (tests, small sweeps). Finished points with an unchanged fingerprint are skipped unless
    ``force``.

    Parameters
    ----------
    sweep : SweepSpec or str or pathlib.Path
        The sweep, or the path of ``SWEEP.toml``.
    out_dir : str or pathlib.Path
        The results folder.
    in_process : bool
        Run the points here, in sequence. Default False.
    scheduler : str or None
        Address of a Dask scheduler (``tcp://host:8786``). Default None.
    n_workers : int or None
        Local workers; None: the CPU count.
    force : bool
        Rerun unchanged points, and replace the points of another study. Default False.
    progress : bool
        Show a bar on stderr. Default False.
    report : bool
        Write the figures and report.html. Default True.
    on_dashboard : callable or None
        ``on_dashboard(link)`` receives the dashboard address.
    connect_timeout_s : float
        Time a scheduler has to answer [s]. Default :data:`CONNECT_TIMEOUT_S`.
    on_start : callable or None
        Called once the inputs and the output folder are checked, before the cluster starts
        (:func:`plan_line` says what is about to run).
    cluster : torquemod._util.daskutil.EarlyCluster or None
        A local cluster of ``n_workers`` already starting (the command starts it before
        its own imports when every point will run), used instead of a new one when points
        are left to run; else left to the caller to close. Default None.

    Returns
    -------
    SweepResult
        The table, the points' status, failures, recommendation and report.

    Raises
    ------
    InputError
        Before any work: no points, ``out_dir`` not a folder or holding the sweep file or its
        base; an ``out_dir`` holding the points of another study (a changed grid, ``[fixed]``
        value, mode, base, ``[steps]`` or ``[processing]``) unless ``force``; a malformed
        scheduler address, ``n_workers`` < 1; a scheduler that does not answer within
        ``connect_timeout_s``.
    """
    t0 = time.perf_counter()
    scheduler = None if in_process else check_cluster(scheduler, n_workers, connect_timeout_s)
    spec = sweep if isinstance(sweep, SweepSpec) else load_sweep(sweep)
    if not spec.points:
        raise InputError("the sweep has no points", path=spec.path,
                         hint="add a [grid] or [[point]] tables")
    out = Path(out_dir).absolute()
    if out.exists() and not out.is_dir():
        raise InputError("the sweep output is not a folder", path=out)
    for given in (spec.path, spec.base):  # the outputs never go beside the inputs
        if given is not None and (out == Path(given).resolve().parent
                                  or out in Path(given).resolve().parents
                                  or out.resolve() in Path(given).resolve().parents):
            raise InputError(f"the output folder holds the sweep's input {given}", path=out,
                             hint="choose an --out outside the folder of the sweep file and "
                                  "its base")
    closing: list = []  # the local cluster closing in a thread
    try:
        # one sweep at a time writes OUT (a second one fails at once); the cluster's client
        # stays open (``stack``) until the report's figures are drawn on its workers
        with output_lock(out), contextlib.ExitStack() as stack:
            return _run_locked(spec, out, t0, in_process=in_process, scheduler=scheduler,
                               n_workers=n_workers, force=force, progress=progress,
                               report=report, on_dashboard=on_dashboard,
                               connect_timeout_s=connect_timeout_s, on_start=on_start,
                               closing=closing, stack=stack,
                               cluster=None if in_process or scheduler else cluster)
    finally:
        for thread in closing:
            thread.join()


def _run_locked(spec: SweepSpec, out: Path, t0: float, *, in_process, scheduler, n_workers,
                force, progress, report, on_dashboard, connect_timeout_s,
                on_start, closing: list, stack, cluster) -> SweepResult:
    todo = tasks(spec)
    begin = one_study(out, spec, todo, force)
    if on_start is not None:
        on_start()
    parts: dict = {}  # the points' partitions, read as their batches finish
    with removed_if_left_empty(out):
        try:
            rows, link, client = _evaluate_all(
                todo, out, in_process=in_process, scheduler=scheduler, n_workers=n_workers,
                force=force, progress=progress, on_dashboard=on_dashboard, begin=begin,
                connect_timeout_s=connect_timeout_s, closing=closing, stack=stack,
                tail=(lambda: finish.import_report_modules(spec.kind,
                                                         drawing=scheduler is not None))
                if report else None, warm=report and spec.kind == "rig", cluster=cluster,
                frames=parts)
        finally:  # the twin's experiments, also of points cut short by an interrupt
            shutil.rmtree(out / "_work", ignore_errors=True)
    system = [r["message"] for r in rows if r.pop("system", False)]
    if system:  # the finished points stay: a rerun resumes once there is room
        raise OutputError(system[0] if system[0].startswith(str(out)) else
                          f"{out}: {system[0]}")
    status = pd.DataFrame(rows).sort_values("point_index", ignore_index=True)
    table = assemble(out, spec, status, frames=parts)
    params = {p.point_id: json.dumps(p.params, sort_keys=True, default=str)
              for p in spec.points}
    failed = status.loc[status["status"] == "failed"]
    failures = pd.DataFrame({"point_id": failed["point_id"],
                             "point_index": failed["point_index"], "seed": failed["seed"],
                             "params": failed["point_id"].map(params),
                             "message": failed["message"]}, columns=FAILURE_COLUMNS)
    meta = {"torquemod_version": __version__, "sweep_toml": spec.text,
            "sweep_spec": json.dumps(spec.to_dict(), default=str)}
    from torquemod.sweep.report import recommend, write_report
    from torquemod.sweep.summary import agreement, point_summary
    # the summaries group by the swept values: a list-valued one (procedure.dc_torques_nm)
    # comes back from Parquet as an array, which cannot be grouped; they see it as text
    table_view = _hashable_params(table, spec.swept)
    shared = {}  # the point summary, computed once for the recommendation and the report
    drawn = {}  # on a local cluster the report's figures are drawn on its workers
    if report and client is not None and spec.kind == "rig" and not table.empty:
        # those of the table alone start now, while the summary and the recommendation
        # are worked out here
        from torquemod.sweep.figurejobs import table_jobs
        drawn["draw"] = finish.draw_on(client)
        drawn["draw"].submit(table_jobs(table_view, spec))
    if spec.kind == "train":
        from torquemod.sweep.trainreport import recommend_train as recommend
        from torquemod.sweep.trainreport import write_train_report as write_report

        def agreement(_table):  # the large-signal theory is the rig's
            return None
    elif not table.empty:
        shared["summary"] = point_summary(table_view, spec)
    rec = recommend(table_view, spec, **shared) if not table.empty else {
        "setting": None, "reasoning": "no point finished"}
    report_path = None
    with write_folder(out, mode="into", provenance=sweep_provenance(spec)) as w:
        failures.to_csv(w.path / "failures.csv", index=False, quoting=csv.QUOTE_MINIMAL,
                        lineterminator="\n")
        if not table.empty:
            _write_parquet(table, w.path / "sweep.parquet", metadata=meta)
        else:
            w.drop("sweep.parquet")
        wall = time.perf_counter() - t0
        doc = {"generator": "torquemod sweep", "version": __version__, "spec": spec.to_dict(),
               "sweep_toml": spec.text, "seeds": list(spec.seeds),
               "points": {s: int((status["status"] == s).sum())
                          for s in ("done", "skipped", "failed")},
               "status": status.to_dict(orient="records"), "wall_s": wall,
               "recommendation": rec,
               "agreement": agreement(table_view) if not table.empty else None}
        if report and not table.empty:
            write_report(w.path, table_view, spec, rec, status=status, failures=failures,
                         wall_s=wall, **shared, **drawn)
            report_path = out / "report.html"
        (w.path / "sweep.json").write_text(dump_json(doc), encoding="utf-8")
    return SweepResult(out, table, status, failures, rec, report_path, link,
                       time.perf_counter() - t0)
