"""The fleet's tasks below a run: the tasks of a rig recording spanning many revolutions (a
cheap scan, one task per group of revolutions, and their merge in the run's assembly,
:func:`torquemod.fleet.plan.finish_run`) and a train axle's chunks. The work itself is
:mod:`torquemod.processing.revtasks` and :mod:`torquemod.ontrain.chunks`; the graph that sends
them to Dask is :func:`torquemod.fleet.run.run_tasks`. ``plan`` arguments are
:class:`torquemod.fleet.plan.Plan`."""

from __future__ import annotations

import time

from torquemod._util.blas import single_blas
from torquemod.errors import TorquemodError

#: seconds of a train axle's recording per task (the windows it measures) by default
AXLE_TASK_S = 600.0
#: by default a train recording is scanned for chunks only from this size [bytes] (16 MiB:
#: ~10 min of torque, wheel speed and time at 1 kHz in float64)
AXLE_SCAN_MIN_BYTES = 16 * 2**20


def _fresh_sha256(plan, index: int) -> str | None:
    """The recording's SHA-256 when the plan computed it just now (not kept from the last
    run's state by size and modification time): then no task reads the file to hash it."""
    path = str(plan.prep.source.recordings[index].path)
    return plan.prep.files[path][2] if path in plan.prep.fresh else None


def one_line(exc: BaseException) -> str:
    """An error as the command line prints it after ``torquemod: error:`` (one line).

    Parameters
    ----------
    exc : BaseException
        The error.

    Returns
    -------
    str
        The message; ``internal error: <type>: <text>`` for an error that is not torquemod's
        or the system's.
    """
    from torquemod._util.fsutil import environment_error
    if not isinstance(exc, TorquemodError) and (env := environment_error(exc)) is not None:
        reason = env.strerror or " ".join(str(env).split())
        return f"{env.filename}: {reason}" if env.filename else reason
    text = " ".join(str(exc).split())
    if isinstance(exc, TorquemodError):
        return text
    return f"internal error: {type(exc).__name__}: {text}"


def _axle_api():
    """:mod:`torquemod.ontrain.run` when it can measure an axle in chunks, else None."""
    from torquemod.ontrain import run as onboard_run
    names = ("plan_axle_chunks", "measure_axle_chunk", "assemble_axle")
    return onboard_run if all(hasattr(onboard_run, n) for n in names) else None


def may_split(plan, index: int) -> bool:
    """Whether a recording may be cut into several tasks (then :func:`scan_item` decides).

    A rig recording without a manifest cycle (groups of revolutions, under any NaN policy);
    a train axle file of :data:`AXLE_SCAN_MIN_BYTES` or more (chunks of ``axle_chunk_s``,
    default :data:`AXLE_TASK_S`).

    Parameters
    ----------
    plan : Plan
        The run.
    index : int
        The recording, in manifest order.

    Returns
    -------
    bool
        True when it may be split.
    """
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
    return entry.cycle is None


@single_blas
def scan_item(plan, index: int) -> tuple:
    """Decide cheaply whether a recording becomes one task per group. Never raises (a Dask task).

    Rig: groups of ``plan.revolutions_per_task`` revolutions (default about a minute of
    recording, :mod:`torquemod.processing.revtasks`); train: chunks of the axle. When the
    scan meets an error the one :func:`~torquemod.fleet.plan.work_item` task then gives the
    error ``process`` gives.

    Parameters
    ----------
    plan : Plan
        The run.
    index : int
        The recording, in manifest order.

    Returns
    -------
    tuple
        ``("split", RevolutionPlan or None, groups, seconds [s], first)`` (``first`` the first
        group's item when the scan computed it, else None), or
        ``("whole", None, None, seconds [s], None)``.
    """
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
        from torquemod.processing.pipeline import resolve_config
        from torquemod.processing.revtasks import scan_revolutions
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
def part_item(plan, index: int, rplan, first: int, stop: int) -> tuple:
    """Process revolutions ``first:stop`` of a recording. Never raises (a Dask task).

    Parameters
    ----------
    plan : Plan
        The run.
    index : int
        The recording, in manifest order.
    rplan : RevolutionPlan
        :func:`scan_item`'s plan of the recording (None for a train axle's chunk).
    first : int
        First revolution (train: first row).
    stop : int
        Revolution (row) after the last.

    Returns
    -------
    tuple
        ``("ok", RevolutionPart (train: AxlePart), seconds [s])`` or
        ``("error", one-line message, seconds [s])``.
    """
    t0 = time.perf_counter()
    prep = plan.prep
    try:
        if prep.kind == "train":
            out = _axle_api().measure_axle_chunk(prep.source, prep.source.recordings[index],
                                                 prep.settings, first, stop)
            return "ok", out, time.perf_counter() - t0
        from torquemod.processing.pipeline import resolve_config
        from torquemod.processing.revtasks import process_revolutions
        out = process_revolutions(prep.source.recordings[index], prep.source,
                                  resolve_config(prep.source), rplan, first, stop,
                                  sha256=_fresh_sha256(plan, index) if first == 0 else None)
        return "ok", out, time.perf_counter() - t0
    except Exception as exc:
        return "error", one_line(exc), time.perf_counter() - t0


def _recording_items(plan, items: tuple, layout: list | None) -> list[tuple]:
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
                from torquemod.processing.revtasks import merge_revolutions
                merged = merge_revolutions(rplan, [p[1] for p in parts])
            out.append(("ok", merged, secs))
        except Exception as exc:
            out.append(("error", one_line(exc), secs))
    return out
