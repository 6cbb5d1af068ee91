"""How a sweep's points are cut into Dask tasks (:func:`point_batches`), and what a sweep
says it is about to do (:func:`plan_line`)."""

from __future__ import annotations

import os
from pathlib import Path

from torquemod.results import resume
from torquemod.sweep.evaluate import PointTask
from torquemod.sweep.spec import SweepSpec
from torquemod.sweep.state import partition_path

__all__ = ["BATCHES_PER_SLOT", "POINT_SECONDS", "plan_line", "point_batches"]

#: the share of the points left that the next batch takes is 1/(this x worker slots)
#: (:func:`point_batches`)
BATCHES_PER_SLOT = 2


def point_batches(todo: list[PointTask], slots: int,
                  per_slot: int = BATCHES_PER_SLOT) -> list[list[PointTask]]:
    """The points cut into batches, one Dask task each, largest first.

    Each batch takes ``ceil(left / (per_slot*slots))`` of the points left (guided
    self-scheduling, Polychronopoulos and Kuck 1987, IEEE Trans. Comput. 36(12)): the first
    batches hold many points, the last ones a single point, so that the workers, taking
    the batches in order, finish within about one point of each other. The points are
    dealt with a stride, so that neighbours in the grid (often alike in cost: the same
    frequency, the same condition) spread over the batches.

    Parameters
    ----------
    todo : list of PointTask
        The points to run.
    slots : int
        Worker slots [-].
    per_slot : int
        Divisor of the share per slot [-]. Default :data:`BATCHES_PER_SLOT`.

    Returns
    -------
    list of list of PointTask
        The batches, in the order to run them; every point once.
    """
    stride = max(1, min(len(todo), slots * per_slot))
    order = [t for k in range(stride) for t in todo[k::stride]]
    batches, share = [], max(1, slots * per_slot)
    while order:
        size = -(-len(order) // share)
        batches.append(order[:size])
        order = order[size:]
    return batches


#: rough seconds a point takes on one worker of a 2-core machine under load (theory: docs;
#: a full rig point of the default procedure and a train point of the default 4 km run are
#: larger, measured once with ``torquemod sweep``); a resumed sweep uses its own points' times
POINT_SECONDS = {("rig", "theory"): 0.5, ("rig", "full"): 5.0, ("train", "full"): 120.0}


def plan_line(spec: SweepSpec, out: str | Path, *, n_workers: int | None = None,
              scheduler: str | None = None) -> str:
    """What the sweep is about to do, said before it starts.

    Parameters
    ----------
    spec : SweepSpec
        The sweep.
    out : str or pathlib.Path
        The output folder (points already done there are counted).
    n_workers : int or None
        Local workers; None: the CPU count.
    scheduler : str or None
        A scheduler's address, when the points run there.

    Returns
    -------
    str
        The points (to run, finished) and a rough time on the workers.
    """
    out = Path(out)
    done, seconds = 0, []
    for p in spec.points:
        rec = resume.read_record(out, p.point_id)
        if rec is None:
            continue
        done += partition_path(out, p.point_id).is_file()
        if isinstance(rec.extra.get("seconds"), int | float):
            seconds.append(float(rec.extra["seconds"]))
    per = (sorted(seconds)[len(seconds) // 2] if seconds
           else POINT_SECONDS.get((spec.kind, spec.mode), 60.0))
    workers = n_workers or (None if scheduler else os.cpu_count() or 1)
    todo = len(spec.points) - done
    total = todo * per / (workers or 1)
    where = f"{workers} worker{'s' if workers != 1 else ''}" if workers else "the cluster"
    when = (f"about {_duration(total)} on {where}" if workers
            else f"about {_duration(todo * per)} of worker time")
    return (f"sweep: {len(spec.points)} points ({todo} to run, {done} finished); {when} "
            f"(~{per:.3g} s a point{'' if seconds else ', a rough guess'})")


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
