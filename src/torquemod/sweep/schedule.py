"""How a sweep's points are cut into Dask tasks (:func:`point_batches`)."""

from __future__ import annotations

from torquemod.sweep.evaluate import PointTask

__all__ = ["BATCHES_PER_SLOT", "point_batches"]

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
