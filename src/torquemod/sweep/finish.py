"""What a sweep does as its points finish and after them, beside its points: the points'
partitions read as their batches finish (:func:`read_parts`), the report's imports in the
command (:func:`import_report_modules`) and in the workers (:func:`warm_workers`) on the
cores the last points leave free, and the report's figures drawn as tasks on the workers,
side by side (:func:`draw_on`)."""

from __future__ import annotations

import time
from pathlib import Path

import pandas as pd

from torquemod.sweep.state import partition_path

__all__ = ["FigureDrawer", "draw_on", "import_report_modules", "read_parts", "warm_workers"]


def read_parts(rows: list[dict], out: Path, frames: dict) -> None:
    """Read the partitions of the points of ``rows`` that are done or skipped into
    ``frames``, as :func:`~torquemod.sweep.run.assemble` reads them; one that cannot be
    read is left to it (it says why).

    Parameters
    ----------
    rows : list of dict
        Status rows of finished points (``point_id``, ``status``).
    out : pathlib.Path
        The sweep's output folder.
    frames : dict
        Point id -> its table, filled here.
    """
    for row in rows:
        if row["status"] in ("done", "skipped"):
            try:
                frames[row["point_id"]] = pd.read_parquet(
                    partition_path(out, row["point_id"]))
            except Exception:
                frames.pop(row["point_id"], None)


def warm_workers(client) -> list:
    """Each worker imports the report's drawing code
    (:func:`~torquemod.sweep.figurejobs.import_drawing`) once its points are done: a task
    of lower priority than the points, bound to it.

    Parameters
    ----------
    client : dask.distributed.Client
        The sweep's client.

    Returns
    -------
    list of dask.distributed.Future
        The tasks' futures, to be kept until the figures are drawn (a released future's
        task would be dropped).
    """
    from torquemod.sweep.figurejobs import import_drawing
    return [client.submit(import_drawing, workers=[address], allow_other_workers=False,
                          priority=-1, pure=False, key=f"torquemod-warm-{k}-{time.time_ns()}")
            for k, address in enumerate(client.scheduler_info()["workers"])]


class FigureDrawer:
    """The report's figures drawn and encoded as tasks on the sweep's workers, side by
    side (the dearest handed out first).

    :meth:`submit` hands jobs to the workers at once (those drawn from the table alone
    while the point summary is worked out); calling it with every job of the report
    returns their PNG bytes, the jobs submitted before (by file stem) not submitted again.
    A figure whose task fails (a lost worker) is drawn here instead (a figure's own error
    is then raised here, as without workers).

    Parameters
    ----------
    client : dask.distributed.Client
        The sweep's client (its cluster still open).
    """

    def __init__(self, client) -> None:
        self.client = client
        self._futures: dict = {}

    def submit(self, jobs: list) -> None:
        """Hand ``jobs`` (:class:`~torquemod.sweep.figurejobs.FigureJob`) to the workers,
        the dearest first; a stem already submitted is left as it is.

        Parameters
        ----------
        jobs : list of FigureJob
            The figures.
        """
        from torquemod.sweep.figurejobs import draw_png
        for job in sorted(jobs, key=lambda j: -j.cost):
            if job.stem not in self._futures:
                self._futures[job.stem] = self.client.submit(
                    draw_png, job, pure=False,
                    key=f"torquemod-figure-{job.stem}-{time.time_ns()}")

    def __call__(self, jobs: list) -> list:
        """``draw(jobs)`` for :func:`~torquemod.sweep.report.write_report`.

        Parameters
        ----------
        jobs : list of FigureJob
            Every figure of the report.

        Returns
        -------
        list
            The PNG bytes (or None: nothing to draw) of each job, in their order.
        """
        from torquemod.sweep.figurejobs import draw_png
        self.submit(jobs)
        pngs = []
        for job in jobs:
            try:
                pngs.append(self._futures.pop(job.stem).result())
            except Exception:
                pngs.append(draw_png(job))
        return pngs


def draw_on(client) -> FigureDrawer:
    """The report's figures drawn on the sweep's workers (:class:`FigureDrawer`).

    Parameters
    ----------
    client : dask.distributed.Client
        The sweep's client (its cluster still open).

    Returns
    -------
    FigureDrawer
        ``draw(jobs)`` for :func:`~torquemod.sweep.report.write_report`, whose
        ``submit(jobs)`` starts figures early.
    """
    return FigureDrawer(client)


def import_report_modules(kind: str, drawing: bool = True) -> None:
    """Import what the report will need in this process: run while the last points
    finish, so that the report does not wait for it after them.

    A module that fails to import is left to the report (it says why).

    Parameters
    ----------
    kind : str
        ``"rig"`` or ``"train"``: the sweep's kind.
    drawing : bool
        Also what drawing the rig report's figures needs (matplotlib's canvas, the figure
        functions, the twin's theory for the creep curves); False when the workers draw
        them. Default True.
    """
    import importlib
    names = (("torquemod.sweep.trainreport", "matplotlib.backends.backend_agg")
             if kind == "train" else ("torquemod.sweep.report",))
    if drawing and kind != "train":
        names += ("torquemod.sweep.evaluate", "torquemod.sweep.figures",
                  "torquemod.twins.vtrack.theory", "torquemod.analysis.contact.polach",
                  "matplotlib.backends.backend_agg")
    for name in names:
        try:
            importlib.import_module(name)
        except Exception:  # the report imports it again and says why
            return
