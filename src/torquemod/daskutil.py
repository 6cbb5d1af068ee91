"""The Dask client that ``fleet`` and ``sweep`` share: a local cluster of worker processes by
default, or an existing scheduler.

Processes, not threads: the chain and the twin hold the GIL for most of their time, so a second
thread in one process gains nothing (measured 1.09x on the chain); one thread per worker
process is the parallel unit.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, n_workers: int | None = None,
                on_dashboard=None) -> Iterator[object]:
    """A ``dask.distributed.Client`` for the duration of the block.

    ``scheduler`` is the address of a running scheduler (``tcp://host:8786``, e.g. started by
    dask-jobqueue or on Kubernetes); None starts a ``LocalCluster`` of ``n_workers``
    single-threaded worker processes (default: the CPU count) and stops it on exit.
    ``on_dashboard(link)`` is called with the dashboard address when the cluster has one.
    """
    from dask.distributed import Client, LocalCluster

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(n_workers=n_workers or os.cpu_count() or 1,
                               threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=40)
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        link = getattr(client, "dashboard_link", None)
        if link and on_dashboard is not None:
            on_dashboard(link)
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
