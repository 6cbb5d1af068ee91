"""Fleet tasks for a rig recording spanning many revolutions (issue 11): a cheap scan, one
task per group of revolutions, and their merge in the run's assembly
(:func:`torquemod.fleet.finish_run`). The work itself is :mod:`torquemod.revtasks`."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .fleet import Plan


def _one_line(exc: BaseException) -> str:
    from .fleet import one_line
    return one_line(exc)


def may_split(plan: Plan, index: int) -> bool:
    """Whether recording ``index`` may be cut into groups of revolutions (a rig recording
    without a manifest cycle, NaN policy ``raise``): then :func:`scan_item` decides."""
    if plan.prep.kind != "rig":
        return False
    entry = plan.prep.source.recordings[index]
    return entry.cycle is None and plan.prep.settings.nan_policy == "raise"


def scan_item(plan: Plan, index: int) -> tuple:
    """Recording ``index`` of a rig plan, cheaply: ``("split", RevolutionPlan, groups,
    seconds)`` when it becomes one task per group of revolutions (``plan.revolutions_per_task``
    each, default about a minute of recording; :mod:`torquemod.revtasks`), else ``("whole",
    None, None, seconds)``: one :func:`work_item` (also when the scan meets an error: the
    one task then gives the error ``process`` gives). Never raises (a Dask task)."""
    t0 = time.perf_counter()
    prep = plan.prep
    try:
        from .pipeline import resolve_config
        from .revtasks import plan_revolutions
        rplan = plan_revolutions(prep.source.recordings[index], prep.source,
                                 resolve_config(prep.source),
                                 revolutions_per_task=plan.revolutions_per_task)
    except Exception:
        rplan = None
    if rplan is None:
        return "whole", None, None, time.perf_counter() - t0
    return ("split", rplan, rplan.groups(plan.revolutions_per_task),
            time.perf_counter() - t0)


def part_item(plan: Plan, index: int, rplan, first: int, stop: int) -> tuple:
    """Revolutions ``first:stop`` of recording ``index`` (:func:`scan_item`'s plan):
    ``("ok", RevolutionPart, seconds)`` or ``("error", one-line message, seconds)``. Never
    raises (a Dask task)."""
    t0 = time.perf_counter()
    prep = plan.prep
    try:
        from .pipeline import resolve_config
        from .revtasks import process_revolutions
        out = process_revolutions(prep.source.recordings[index], prep.source,
                                  resolve_config(prep.source), rplan, first, stop)
        return "ok", out, time.perf_counter() - t0
    except Exception as exc:
        return "error", _one_line(exc), time.perf_counter() - t0


def _recording_items(items: tuple, layout: list | None) -> list[tuple]:
    """One item per recording: ``layout`` (per recording None for one :func:`work_item`,
    or ``(RevolutionPlan, number of parts, scan seconds)``) says which items are the parts
    of a split recording; they are merged (the first failed part, in order, is the
    recording's error: the one the sequential read meets first)."""
    if layout is None:
        return list(items)
    out, pos = [], 0
    for lay in layout:
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
        from .revtasks import merge_revolutions
        try:
            out.append(("ok", merge_revolutions(rplan, [p[1] for p in parts]), secs))
        except Exception as exc:
            out.append(("error", _one_line(exc), secs))
    return out
