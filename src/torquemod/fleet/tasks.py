"""The fleet's Dask task graph (:func:`run_tasks`, for :func:`torquemod.fleet.run.run_fleet`) and
the tasks of a rig recording spanning many revolutions (issue 11): a cheap scan, one task per
group of revolutions, and their merge in the run's assembly
(:func:`torquemod.fleet.run.finish_run`). The work itself is :mod:`torquemod.process.revtasks`."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

from torquemod._util.blas import single_blas

if TYPE_CHECKING:
    from torquemod.fleet.run import Plan


#: seconds of a train axle's recording per task (the windows it measures) by default
AXLE_TASK_S = 600.0
#: by default a train recording is scanned for chunks only from this size [bytes] (16 MiB:
#: ~10 min of torque, wheel speed and time at 1 kHz in float64)
AXLE_SCAN_MIN_BYTES = 16 * 2**20


def _fresh_sha256(plan: Plan, index: int) -> str | None:
    """The recording's SHA-256 when the plan computed it just now (not kept from the last
    run's state by size and modification time): then no task reads the file to hash it."""
    path = str(plan.prep.source.recordings[index].path)
    return plan.prep.files[path][2] if path in plan.prep.fresh else None


def _one_line(exc: BaseException) -> str:
    from torquemod.fleet.run import one_line
    return one_line(exc)


def _axle_api():
    """:mod:`torquemod.ontrain.run` when it can measure an axle in chunks, else None."""
    from torquemod.ontrain import run as onboard_run
    names = ("plan_axle_chunks", "measure_axle_chunk", "assemble_axle")
    return onboard_run if all(hasattr(onboard_run, n) for n in names) else None


def may_split(plan: Plan, index: int) -> bool:
    """Whether recording ``index`` may be cut into several tasks (a rig recording without
    a manifest cycle, NaN policy ``raise``: groups of revolutions; a train axle: chunks of
    ``axle_chunk_s``, default :data:`AXLE_TASK_S` and only files of
    :data:`AXLE_SCAN_MIN_BYTES` or more): then :func:`scan_item` decides."""
    if plan.prep.kind == "train":
        if _axle_api() is None:
            return False
        if plan.axle_chunk_s is not None:
            return True
        try:  # by default no scan task for a recording far shorter than two chunks
            size = plan.prep.source.recordings[index].path.stat().st_size
        except OSError:
            return False
        return size >= AXLE_SCAN_MIN_BYTES
    entry = plan.prep.source.recordings[index]
    return entry.cycle is None and plan.prep.settings.nan_policy == "raise"


@single_blas
def scan_item(plan: Plan, index: int) -> tuple:
    """Recording ``index`` of a plan, cheaply: ``("split", RevolutionPlan or None, groups,
    seconds, first)`` when it becomes one task per group (rig: of revolutions,
    ``plan.revolutions_per_task`` each, default about a minute of recording,
    :mod:`torquemod.process.revtasks`; ``first`` the first group's item when the scan computed it,
    else None; train: chunks of the axle), else ``("whole", None, None, seconds, None)``:
    one :func:`work_item` (also when the scan meets an error: the one task then gives the
    error ``process`` gives). Never raises (a Dask task)."""
    t0 = time.perf_counter()
    prep = plan.prep
    if prep.kind == "train":  # a train axle: the on-board estimator's chunks
        try:
            chunks = _axle_api().plan_axle_chunks(prep.source, prep.source.recordings[index],
                                                  prep.settings,
                                                  chunk_s=plan.axle_chunk_s or AXLE_TASK_S)
        except Exception:
            chunks = []
        if len(chunks) < 2:
            return "whole", None, None, time.perf_counter() - t0, None
        return "split", None, [tuple(c) for c in chunks], time.perf_counter() - t0, None
    try:
        from torquemod.process.pipeline import resolve_config
        from torquemod.process.revtasks import scan_revolutions
        got = scan_revolutions(prep.source.recordings[index], prep.source,
                               resolve_config(prep.source),
                               revolutions_per_task=plan.revolutions_per_task,
                               sha256=_fresh_sha256(plan, index))
    except Exception:
        got = None
    if got is None:
        return "whole", None, None, time.perf_counter() - t0, None
    rplan, first = got
    seconds = time.perf_counter() - t0
    return ("split", rplan, rplan.groups(plan.revolutions_per_task), seconds,
            None if first is None else ("ok", first, 0.0))


@single_blas
def part_item(plan: Plan, index: int, rplan, first: int, stop: int) -> tuple:
    """Revolutions ``first:stop`` of recording ``index`` (:func:`scan_item`'s plan):
    ``("ok", RevolutionPart, seconds)`` or ``("error", one-line message, seconds)``. Never
    raises (a Dask task)."""
    t0 = time.perf_counter()
    prep = plan.prep
    try:
        if prep.kind == "train":
            out = _axle_api().measure_axle_chunk(prep.source, prep.source.recordings[index],
                                                 prep.settings, first, stop)
            return "ok", out, time.perf_counter() - t0
        from torquemod.process.pipeline import resolve_config
        from torquemod.process.revtasks import process_revolutions
        out = process_revolutions(prep.source.recordings[index], prep.source,
                                  resolve_config(prep.source), rplan, first, stop,
                                  sha256=_fresh_sha256(plan, index) if first == 0 else None)
        return "ok", out, time.perf_counter() - t0
    except Exception as exc:
        return "error", _one_line(exc), time.perf_counter() - t0


def _recording_items(plan: Plan, items: tuple, layout: list | None) -> list[tuple]:
    """One item per recording: ``layout`` (per recording None for one :func:`work_item`,
    or ``(RevolutionPlan or None, number of parts, scan seconds)``) says which items are
    the parts of a split recording; they are merged (rig: :func:`merge_revolutions`; train:
    ``assemble_axle`` and the track table). The first failed part, in order, is the
    recording's error: the one the sequential read meets first."""
    if layout is None:
        return list(items)
    out, pos = [], 0
    for index, lay in enumerate(layout):
        if lay is None:
            out.append(items[pos])
            pos += 1
            continue
        rplan, n, scan_s = lay
        parts, pos = items[pos:pos + n], pos + n
        secs = scan_s + sum(p[2] for p in parts)
        bad = [p[1] for p in parts if p[0] != "ok"]
        if bad:
            out.append(("error", bad[0], secs))
            continue
        try:
            if plan.prep.kind == "train":
                prep, api = plan.prep, _axle_api()
                merged = api.track_table(api.assemble_axle(
                    prep.source, prep.source.recordings[index], prep.settings,
                    [p[1] for p in parts]))
            else:
                from torquemod.process.revtasks import merge_revolutions
                merged = merge_revolutions(rplan, [p[1] for p in parts])
            out.append(("ok", merged, secs))
        except Exception as exc:
            out.append(("error", _one_line(exc), secs))
    return out


def run_tasks(client, paths: list[Path], names: list[str], out: str, force: bool,
               fit: bool, progress: bool, revolutions_per_task: int | None = None,
               axle_chunk_s: float | None = None) -> list[dict]:
    """The fleet's task graph, grown as results arrive: per run a :func:`plan_run` task; for
    a run to process, per recording one :func:`work_item` task, or for a rig recording that
    may be split a :func:`scan_item` task and then one :func:`part_item` task per group of
    revolutions; once every recording of the run has its tasks, a :func:`finish_run` task on
    their results. Returns the summary rows; a task lost with its worker (killed, out of
    memory) becomes a failed row."""
    from dask.distributed import as_completed
    from tqdm import tqdm

    from torquemod.fleet.run import (
        SUMMARY_COLUMNS,
        Plan,
        finish_run,
        manifest_kind,
        one_line,
        plan_run,
        work_item,
    )

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
