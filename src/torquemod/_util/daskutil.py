"""The Dask client that ``fleet`` and ``sweep`` share: a local cluster of worker processes by
default, or an existing scheduler.

Processes, not threads: the chain and the twin hold the GIL for most of their time, so a second
thread in one process gains nothing (measured 1.09x on the chain); one thread per worker
process is the parallel unit.

What a user can get wrong is refused before any work: a malformed scheduler address and a
worker count below one at once (:func:`check_scheduler`, :func:`check_workers`), a scheduler
that does not answer within ``connect_timeout_s`` as one :class:`InputError`. Local workers
ignore the terminal's Ctrl-C (the command stops them itself, quietly) and keep their scratch
files in a temporary folder that is removed at the end.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import signal
import threading
from collections.abc import Iterator

from torquemod.errors import InputError

#: seconds to wait for an existing scheduler to answer (``--connect-timeout``)
CONNECT_TIMEOUT_S = 10.0
#: address schemes of Dask's communication layers
_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")
_HINT = ("give the scheduler's address as tcp://HOST:PORT (e.g. tcp://10.0.0.5:8786), or leave "
         "out --scheduler for a local cluster")


#: Dask settings of the local cluster. Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_=65536`` in
#: its workers' environment by default, which also stops glibc from raising its mmap
#: threshold: every array above 128 kB is then mapped and unmapped at each allocation and
#: its pages faulted in again (+25 % CPU on a sweep point, measured). The sampling profiler
#: (every 10 ms) and the event loops' health checks take CPU from the task as well; the
#: dashboard keeps its task stream and progress without them.
LOCAL_CLUSTER_CONFIG = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "200ms",
    "distributed.admin.system-monitor.interval": "1s",
    "distributed.worker.memory.monitor-interval": "500ms",
}


#: the environment Dask's nanny gives a spawned worker by default
#: (``distributed.nanny.pre-spawn-environ``): one thread for the numerical libraries; a
#: worker forked from the fork server (:func:`start_worker_server`) has the server's
_WORKER_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def start_worker_server(modules: tuple[str, ...] | list[str]) -> None:
    """Start multiprocessing's fork server, from which the local cluster's workers are then
    forked (:func:`dask_client` with ``worker_modules``), with ``modules`` imported in it.

    A spawned worker imports everything its tasks need itself (about 2 CPU-s for a sweep
    point); forked from the server, it finds them imported once for all workers. The server
    starts at once and imports in its own process, so a caller that starts it before its
    own imports overlaps the two. It gets the environment a spawned worker gets
    (:data:`_WORKER_ENV`) and ignores Ctrl-C, as do the workers forked from it. Nothing
    happens when the server already runs; it ends with this process.

    Parameters
    ----------
    modules : sequence of str
        Importable module names (one that fails to import is left out by the server).
    """
    import multiprocessing
    from multiprocessing import forkserver

    if not forking_available():
        return
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["distributed", *modules])
    saved = {k: os.environ.get(k) for k in _WORKER_ENV}
    os.environ.update(_WORKER_ENV)
    try:
        with _sigint_ignored():
            forkserver.ensure_running()
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    global _SERVER_STOP_REGISTERED
    if not _SERVER_STOP_REGISTERED:
        import atexit
        atexit.register(stop_worker_server)
        _SERVER_STOP_REGISTERED = True


_SERVER_STOP_REGISTERED = False


#: The longest path an AF_UNIX socket takes on Linux [bytes]: ``sun_path`` holds 108 with its
#: terminating NUL (unix(7)).
_UNIX_SOCKET_PATH_MAX = 107

#: What multiprocessing adds to the temporary folder for the fork server's socket:
#: ``/pymp-XXXXXXXX/listener-XXXXXXXX`` (eight random characters each).
_SERVER_SOCKET_SUFFIX = "/pymp-12345678/listener-12345678"


def forking_available() -> bool:
    """Whether the local cluster's workers can be forked from multiprocessing's fork server:
    the platform has one (not Windows), and the temporary folder (``TMPDIR``) is short enough
    for the server's socket, whose path multiprocessing makes inside it. With a longer
    folder the server would fail to start ("AF_UNIX path too long"), so the workers are
    spawned instead: slower to start, the same results."""
    import multiprocessing
    import tempfile

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return False
    socket_path = os.fsencode(tempfile.gettempdir()) + _SERVER_SOCKET_SUFFIX.encode()
    return len(socket_path) <= _UNIX_SOCKET_PATH_MAX


def stop_worker_server() -> None:
    """End the fork server and wait for it (registered for the exit; a benchmark may call it
    before it reads its children's CPU time). By then the clusters are closed and the
    server has reaped the workers it forked, so their CPU time counts as this process's
    children's, as a spawned worker's does; a server still importing (no cluster was
    needed, or the input was refused) is ended at once rather than waited for."""
    from multiprocessing import forkserver
    server = forkserver._forkserver
    pid = getattr(server, "_forkserver_pid", None)
    if pid is None:
        return
    with contextlib.suppress(OSError):
        os.kill(pid, signal.SIGTERM)
    with contextlib.suppress(Exception):
        server._stop()  # closes its "alive" pipe and waits for it


def check_scheduler(address: str) -> str:
    """The scheduler ``address`` with its scheme (``host:port`` means ``tcp://host:port``);
    an :class:`InputError` at once when it is not ``SCHEME://HOST:PORT``."""
    text = str(address).strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    host, colon, port = rest.rpartition(":")
    if scheme not in _SCHEMES:
        raise InputError(f"scheduler address {address!r}: unknown scheme '{scheme}://'",
                         hint=f"use one of {', '.join(s + '://' for s in _SCHEMES)}; {_HINT}")
    if not colon or not host.strip("[]") or not port.isdigit() or not 0 < int(port) < 65536:
        raise InputError(f"scheduler address {address!r} is not HOST:PORT", hint=_HINT)
    return f"{scheme}://{rest}"


def check_workers(n_workers: int | None) -> None:
    """Refuse a local cluster of fewer than one worker (None: the CPU count)."""
    if n_workers is not None and (isinstance(n_workers, bool) or not isinstance(n_workers, int)
                                  or n_workers < 1):
        raise InputError(f"--workers must be 1 or more, got {n_workers!r}",
                         hint="leave it out for one worker per CPU")


def check_cluster(scheduler: str | None, n_workers: int | None,
                  connect_timeout_s: float = CONNECT_TIMEOUT_S) -> str | None:
    """All of the cluster options checked (before any output is made): the scheduler's
    address with its scheme, or None for a local cluster."""
    check_workers(n_workers)
    if not (isinstance(connect_timeout_s, int | float) and 0 < connect_timeout_s < 1e6):
        raise InputError(f"--connect-timeout must be a positive number of seconds, got "
                         f"{connect_timeout_s!r}")
    return None if scheduler is None else check_scheduler(scheduler)


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while the block runs (processes started now inherit it: the terminal's
    Ctrl-C reaches the whole process group, and the workers are stopped by this process);
    only in the main thread, where Python's handler lives."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def _quiet_logs() -> Iterator[None]:
    """Dask's and tornado's loggers silenced while the client closes (an interrupted run's
    closing comms log errors that are not the user's business)."""
    import logging
    names = ("distributed", "tornado", "asyncio", "bokeh")
    loggers = [logging.getLogger(n) for n in names]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


def _close(client, cluster, scratch) -> None:
    """Close the client and the local cluster quietly, then remove the workers' scratch
    folder (``scratch``: its ``TemporaryDirectory``)."""
    with _quiet_logs():
        if client is not None:
            with contextlib.suppress(Exception):
                client.close()
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close()
    scratch.cleanup()


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, n_workers: int | None = None,
                on_dashboard=None, *, connect_timeout_s: float = CONNECT_TIMEOUT_S,
                closing: list | None = None,
                worker_modules: tuple[str, ...] | None = None,
                started: EarlyCluster | None = None) -> Iterator[object]:
    """A ``dask.distributed.Client`` for the duration of the block.

    ``scheduler`` is the address of a running scheduler (``tcp://host:8786``, e.g. started by
    dask-jobqueue or on Kubernetes), which must answer within ``connect_timeout_s`` [s];
    None starts a ``LocalCluster`` of ``n_workers`` single-threaded worker processes
    (default: the CPU count) and stops it on exit. ``on_dashboard(link)`` is called with the
    dashboard address when the cluster has one. Bad options and an unreachable scheduler
    raise :class:`InputError`.

    ``closing``: a list; when given, the client and the cluster are closed after the block
    in a thread that is appended to it (the worker processes take about a second to end:
    the caller goes on meanwhile and joins the thread before it returns); else they are
    closed before the block ends.

    ``worker_modules``: the local cluster's workers are forked from multiprocessing's fork
    server with these modules imported (:func:`start_worker_server`, started here unless
    the caller started it earlier) instead of spawned; ignored with a scheduler or where
    there is no fork server (Windows).

    ``started``: a local cluster already starting (:class:`EarlyCluster`, of the same
    workers), used instead of a new one when there is no ``scheduler``; this block then
    owns it and closes it as its own.
    """
    address = check_cluster(scheduler, n_workers, connect_timeout_s)
    if started is not None and address is None:
        client, link = started.take()
        try:
            if link and on_dashboard is not None:
                on_dashboard(link)
            yield client
        finally:
            started.close(closing)
        return
    import logging
    import tempfile

    import dask
    from dask.distributed import Client, LocalCluster

    cluster = client = None
    scratch_dir = tempfile.TemporaryDirectory(prefix="torquemod-dask-",
                                              ignore_cleanup_errors=True)
    with contextlib.ExitStack() as stack:
        scratch = scratch_dir.name
        forked = address is None and worker_modules is not None and forking_available()
        stack.enter_context(dask.config.set({"temporary-directory": scratch,
                                             **(LOCAL_CLUSTER_CONFIG if address is None
                                                else {}),
                                             **({"distributed.worker.multiprocessing-method":
                                                 "forkserver"} if forked else {})}))
        try:
            if forked:
                start_worker_server(worker_modules)
            if address is None:
                with _sigint_ignored():
                    cluster = LocalCluster(n_workers=n_workers or os.cpu_count() or 1,
                                           threads_per_worker=1, processes=True,
                                           dashboard_address=":0", local_directory=scratch,
                                           silence_logs=logging.CRITICAL)
                client = Client(cluster)
            else:
                try:
                    client = Client(address, timeout=connect_timeout_s)
                except (OSError, TimeoutError) as exc:
                    raise InputError(f"cannot reach the Dask scheduler at {address} within "
                                     f"{connect_timeout_s:g} s ({_reason(exc)})",
                                     hint="check that it runs and the address; or leave out "
                                          "--scheduler for a local cluster") from None
            link = getattr(client, "dashboard_link", None)
            if link and on_dashboard is not None:
                on_dashboard(link)
            yield client
        finally:
            if closing is None:
                with _sigint_ignored():
                    _close(client, cluster, scratch_dir)
            else:  # a thread: the terminal's Ctrl-C never reaches it
                closer = threading.Thread(target=_close, args=(client, cluster, scratch_dir),
                                          name="torquemod-dask-close")
                closer.start()
                closing.append(closer)


class EarlyCluster:
    """A local cluster (:func:`dask_client` with ``worker_modules``) starting in a thread
    from now on, so that the caller's own work (its imports, reading its inputs) overlaps
    the wait for the fork server's imports and the workers' start.

    Hand it to :func:`dask_client` (``started=``), which waits for it and then owns it; a
    caller that ends up not running anything calls :meth:`close`. Only where workers are
    forked from the fork server (:func:`forking_available`): they ignore Ctrl-C as the
    server does, which a thread could not arrange for spawned workers.

    Parameters
    ----------
    n_workers : int or None
        Single-threaded worker processes; None: the CPU count.
    worker_modules : sequence of str
        What the fork server imports (:func:`start_worker_server`).
    """

    def __init__(self, n_workers: int | None, worker_modules: tuple[str, ...]) -> None:
        check_workers(n_workers)
        self.n_workers = n_workers
        self._stack = contextlib.ExitStack()
        self._closing: list = []
        self._links: list = []
        self._client = None
        self._error: BaseException | None = None
        self._closed = False
        # the start and the close run in one context (a client entered as a context
        # manager sets a context variable that must be reset in the context it was set in)
        self._context = contextvars.copy_context()
        start_worker_server(worker_modules)
        self._thread = threading.Thread(target=self._context.run,
                                        args=(self._start, tuple(worker_modules)),
                                        name="torquemod-dask-start", daemon=True)
        self._thread.start()

    def _start(self, worker_modules: tuple[str, ...]) -> None:
        try:
            self._client = self._stack.enter_context(dask_client(
                None, self.n_workers, self._links.append, closing=self._closing,
                worker_modules=worker_modules))
        except BaseException as exc:  # raised again by take()
            self._error = exc

    def take(self) -> tuple[object, str | None]:
        """Wait for the start: ``(client, dashboard address or None)``; its error raised
        when it failed."""
        self._thread.join()
        if self._error is not None:
            self.close()
            raise self._error
        return self._client, (self._links[0] if self._links else None)

    def close(self, closing: list | None = None) -> None:
        """Close the cluster (waiting for its start first): in a thread appended to
        ``closing`` when given (the caller joins it), else before this returns."""
        if self._closed:
            return
        self._closed = True
        self._thread.join()
        with _sigint_ignored():
            self._context.run(self._stack.close)
        if closing is not None:
            closing.extend(self._closing)
        else:
            for thread in self._closing:
                thread.join()


def _reason(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    if isinstance(exc, TimeoutError) or "Timed out" in text:
        return "no answer"
    return text[:200] or type(exc).__name__
