"""The local cluster's workers forked from a fork server with their modules imported
(:func:`torquemod._util.daskutil.start_worker_server`)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

SRC = str(Path(__file__).resolve().parents[2] / "src")

_SCRIPT = """
import os, sys
from torquemod._util.daskutil import EarlyCluster, dask_client

def probe():
    import os, sys
    return "colorsys" in sys.modules, os.getppid()

modules = ("colorsys",) if sys.argv[1] != "spawned" else None
early = EarlyCluster(1, modules) if sys.argv[1] == "early" else None
if early is not None:
    unused = EarlyCluster(1, modules)  # started, then not needed: closed before it returns
    unused.close()
    closing, links = [], []
    with dask_client(n_workers=1, started=early, closing=closing,
                     on_dashboard=links.append) as client:
        had, ppid = client.submit(probe, pure=False).result()
    for thread in closing:
        thread.join()
    early.close()  # a second close does nothing
    print(had, ppid == os.getpid(), len(links), client.status)
else:
    with dask_client(n_workers=1, worker_modules=modules) as client:
        had, ppid = client.submit(probe, pure=False).result()
    print(had, ppid == os.getpid())
"""


def _run(how: str) -> str:
    env = {**os.environ, "PYTHONPATH": SRC}
    done = subprocess.run([sys.executable, "-c", _SCRIPT, how], env=env, capture_output=True,
                          text=True, timeout=120, check=True)
    return done.stdout.split()


def test_workers_fork_from_a_server_that_imported_their_modules():
    """With ``worker_modules`` a worker's parent is the fork server, not this process, and a
    module no worker imports by itself (colorsys) is there before its first task; without,
    the worker is spawned by this process and has not imported it."""
    assert _run("forked") == ["True", "False"]
    assert _run("spawned") == ["False", "True"]


def test_a_cluster_started_early_is_used_then_closed():
    """A cluster started in a thread (:class:`EarlyCluster`) is the one the block gets, its
    workers forked from the server, its dashboard reported; the block closes it (in the
    thread it hands back); one never used is closed by ``close``."""
    assert _run("early") == ["True", "False", "1", "closed"]


def test_the_command_preloads_what_the_sweep_names():
    """``torquemod sweep`` starts the server before importing the sweep (its own copy of the
    module list) with the modules the sweep's cluster asks for."""
    from torquemod._cli.commands import SWEEP_WORKER_MODULES
    from torquemod.sweep.run import WORKER_MODULES
    assert SWEEP_WORKER_MODULES == WORKER_MODULES
    import importlib
    for name in WORKER_MODULES:
        assert importlib.util.find_spec(name) is not None


_SOCKET_SCRIPT = """
from multiprocessing import forkserver
from torquemod._util.daskutil import forking_available
predicted = forking_available()
try:
    forkserver.ensure_running()
    started = True
except OSError:
    started = False
print(predicted, started)
"""


def test_forking_is_predicted_to_fail_exactly_when_the_servers_socket_path_is_too_long():
    """The fork server's socket lives in the temporary folder; one byte past the longest
    folder :func:`forking_available` accepts, multiprocessing itself fails to start the
    server ("AF_UNIX path too long", as under a test runner's long TMPDIR), so the workers
    are spawned instead. Checked against the real server at both lengths."""
    import tempfile

    from torquemod._util.daskutil import _SERVER_SOCKET_SUFFIX, _UNIX_SOCKET_PATH_MAX
    longest = _UNIX_SOCKET_PATH_MAX - len(_SERVER_SOCKET_SUFFIX)
    base = tempfile.mkdtemp(prefix="tm-", dir="/tmp")
    try:
        seen = []
        for length in (longest, longest + 1):
            folder = base + "/" + "d" * (length - len(base) - 1)
            os.makedirs(folder)
            assert len(folder) == length
            env = {**os.environ, "PYTHONPATH": SRC, "TMPDIR": folder}
            done = subprocess.run([sys.executable, "-c", _SOCKET_SCRIPT], env=env, text=True,
                                  capture_output=True, timeout=60, check=True)
            seen.append(done.stdout.split())
        assert seen == [["True", "True"], ["False", "False"]]
    finally:
        import shutil
        shutil.rmtree(base, ignore_errors=True)
