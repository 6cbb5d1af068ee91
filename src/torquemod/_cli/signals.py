"""SIGTERM unwinding as Ctrl-C does, so that a stopped command leaves nothing half-written."""

from __future__ import annotations

import contextlib
import signal
import threading

TERMINATED = threading.Event()


class Terminated(KeyboardInterrupt):
    """SIGTERM, unwinding as Ctrl-C does (exit code 143 instead of 130)."""


@contextlib.contextmanager
def terminate_as_interrupt():
    """SIGTERM (``kill``, a job scheduler's stop) unwinds like Ctrl-C, so temporary outputs
    are removed and nothing half-written is left (main thread only); the exit code is
    143."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(_signum, _frame):
        TERMINATED.set()  # also when a library turns the exception into a new one
        raise Terminated

    TERMINATED.clear()  # a SIGTERM of an earlier main() in this process is not this one's
    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
