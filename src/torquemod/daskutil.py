"""The Dask client that ``fleet`` and ``sweep`` share: a local cluster of worker processes by
default, or an existing scheduler.

Processes, not threads: the chain and the twin hold the GIL for most of their time, so a second
thread in one process gains nothing (measured 1.09x on the chain); one thread per worker
process is the parallel unit.

Dask starts worker processes with ``OMP_NUM_THREADS=1`` (and ``MKL_``, ``OPENBLAS_``), so
their BLAS runs on one thread while a plain ``torquemod process`` runs it on every core. The
chain's least-squares products then sum in another order and its numbers move in the last
bits (measured on the twin's rig files: up to 1e-10 deg in a cycle's phase, 6.5e-6 deg in
its standard error). ``same_blas`` gives a local cluster's workers the BLAS thread count
of the calling process (:class:`BlasThreads`), so a fleet's numbers are the single run's,
with OpenBLAS's idle spinning shortened (:data:`OPENBLAS_THREAD_TIMEOUT`).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

import dask
from distributed.diagnostics.plugin import WorkerPlugin


def blas_threads() -> int | None:
    """The number of threads of the BLAS libraries this process has loaded (the largest),
    None when threadpoolctl finds none."""
    import numpy  # noqa: F401  (loads numpy's BLAS)
    from threadpoolctl import threadpool_info
    counts = [i["num_threads"] for i in threadpool_info() if i.get("user_api") == "blas"]
    return max(counts) if counts else None


class BlasThreads(WorkerPlugin):
    """A Dask worker plugin that sets the worker process's BLAS libraries to ``n`` threads
    (threadpoolctl) when the worker starts, also a worker restarted after a loss."""

    name = "torquemod-blas-threads"

    def __init__(self, n: int) -> None:
        self.n = int(n)

    def setup(self, worker=None) -> None:
        import numpy  # noqa: F401
        import scipy.linalg  # noqa: F401  (scipy's own BLAS copy, loaded before it is set)
        from threadpoolctl import threadpool_limits
        threadpool_limits(limits=self.n, user_api="blas")


#: OpenBLAS's idle threads spin for 2**n cycles after each call before they sleep (default
#: n = 28, about 0.1 s); with several BLAS threads per worker process that spinning takes the
#: cores from the other workers: measured on two processes running the chain at once, 2
#: BLAS threads each, CPU 0.62-0.80 s with the default against 0.27-0.32 s with n = 4 (one
#: thread: 0.30 s); the numbers are the same bits (only the idle wait changes)
OPENBLAS_THREAD_TIMEOUT = "4"


def _spawn_env(same_blas: bool) -> dict:
    """Dask config for the local workers' environment: with ``same_blas``, OpenBLAS's idle
    spin shortened (:data:`OPENBLAS_THREAD_TIMEOUT`, unless the caller's environment sets
    it)."""
    if not same_blas:
        return {}
    env = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}) or {})
    env["OPENBLAS_THREAD_TIMEOUT"] = os.environ.get("OPENBLAS_THREAD_TIMEOUT",
                                                    OPENBLAS_THREAD_TIMEOUT)
    return {"distributed.nanny.pre-spawn-environ": env}


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, n_workers: int | None = None,
                on_dashboard=None, *, same_blas: bool = False) -> Iterator[object]:
    """A ``dask.distributed.Client`` for the duration of the block.

    ``scheduler`` is the address of a running scheduler (``tcp://host:8786``, e.g. started by
    dask-jobqueue or on Kubernetes); None starts a ``LocalCluster`` of ``n_workers``
    single-threaded worker processes (default: the CPU count) and stops it on exit.
    ``on_dashboard(link)`` is called with the dashboard address when the cluster has one.
    ``same_blas``: the local cluster's workers use as many BLAS threads as this process
    (:class:`BlasThreads`; an existing cluster's workers keep their own setting).
    """
    from dask.distributed import Client, LocalCluster

    cluster = None
    if scheduler is None:
        with dask.config.set(_spawn_env(same_blas)):
            cluster = LocalCluster(n_workers=n_workers or os.cpu_count() or 1,
                                   threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=40)
        client = Client(cluster)
        if same_blas and (n := blas_threads()) is not None:
            client.register_plugin(BlasThreads(n))
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
