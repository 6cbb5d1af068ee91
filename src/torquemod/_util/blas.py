"""The chain's numerical work on one BLAS thread, whatever the machine.

OpenBLAS (numpy's and scipy's copies) splits a matrix product over its threads, and the
partial sums then add up in an order that depends on the thread count. The chain's small
least-squares designs (a few hundred rows, tens of columns) gain nothing from a second
thread, but their last bits move with it: measured on the twin's rig files, a cycle's phase
moved by up to 1e-10 deg and its standard error by 6.5e-6 deg between one and two threads.
Dask starts its workers with one BLAS thread (``OMP_NUM_THREADS=1``), a plain process uses
every core, so `fleet` and `process` gave different last bits. :func:`one_blas_thread` runs
the processing entry points (``process_experiment``, the on-board estimate of an axle, the
fleet's tasks) on one BLAS thread, so that their numbers are the same on any machine, in any
worker, on any number of cores; measured here it also halves the CPU time of ``process`` at
the same wall time (the second thread only spun).

The limit is process-wide while the block runs (threadpoolctl sets the libraries' thread
count) and the previous count is restored at its end.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator

_CONTROLLER = None


def _controller():
    """threadpoolctl's view of the BLAS libraries, built once, after numpy and scipy.linalg
    (which brings its own OpenBLAS) are loaded."""
    global _CONTROLLER
    if _CONTROLLER is None:
        import numpy  # noqa: F401
        import scipy.linalg  # noqa: F401
        from threadpoolctl import ThreadpoolController
        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Every loaded BLAS library on one thread for the duration of the block."""
    with _controller().limit(limits=1, user_api="blas"):
        yield


def single_blas(fn):
    """Decorator: ``fn`` runs inside :func:`one_blas_thread`."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with one_blas_thread():
            return fn(*args, **kwargs)
    return wrapper
