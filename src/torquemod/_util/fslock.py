"""One torquemod run at a time per output: an exclusive ``flock`` on ``.{name}.lock`` beside
the output (see :mod:`torquemod._util.fsutil`, which re-exports :func:`output_lock`)."""

from __future__ import annotations

import contextlib
import errno
import os
import threading
from collections.abc import Iterator
from pathlib import Path

from torquemod.errors import OutputError

try:  # POSIX only; elsewhere runs are not locked against each other
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

__all__ = ["output_lock"]


def _reason(exc: OSError) -> str:
    return exc.strerror or " ".join(str(exc).split()) or type(exc).__name__


_held: dict[str, list] = {}  # lock path -> [owner thread id, depth]
_held_guard = threading.Lock()


def _lock_path(target: Path) -> Path:
    parent = target.parent.resolve()
    return parent / f".{target.name}.lock"


@contextlib.contextmanager
def output_lock(target: str | Path) -> Iterator[Path]:
    """Hold the exclusive lock of the output ``target`` (``.{name}.lock`` beside it, created
    and removed here; ``fcntl.flock``) while the block runs. Re-entrant in one thread; a
    second holder (another process or thread) gets :class:`OutputError` at once. Missing
    parent folders are created, and removed again if still empty at the end (a failed run
    leaves nothing). Yields the lock file's path."""
    target = Path(os.path.abspath(target))
    made = _make_parents(target)
    try:
        with _locked(target) as lock:
            yield lock
    finally:
        for folder in made:  # deepest first; stops at the first one that is not empty
            try:
                os.rmdir(folder)
            except OSError:
                break


def _make_parents(target: Path) -> list[Path]:
    missing, folder = [], target.parent
    while not os.path.lexists(folder) and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    if not folder.is_dir():
        raise OutputError(f"{target}: cannot write in {folder} "
                          f"({os.strerror(errno.ENOTDIR)})")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        for made in missing:
            with contextlib.suppress(OSError):
                os.rmdir(made)
        raise OutputError(f"{target}: cannot create its folder {target.parent} "
                          f"({_reason(exc)})") from None
    return missing


@contextlib.contextmanager
def _locked(target: Path) -> Iterator[Path]:
    lock = _lock_path(target)
    key, me = str(lock), threading.get_ident()
    with _held_guard:
        entry = _held.get(key)
        if entry is not None and entry[0] == me:
            entry[1] += 1
            reentered = True
        else:
            reentered = False
    if reentered:
        try:
            yield lock
        finally:
            with _held_guard:
                _held[key][1] -= 1
        return
    if entry is not None:
        raise _busy(target, lock)
    fd = _acquire(target, lock)
    with _held_guard:
        _held[key] = [me, 1]
    try:
        yield lock
    finally:
        with _held_guard:
            del _held[key]
        with contextlib.suppress(OSError):
            os.unlink(lock)  # still holding the flock: a waiter re-checks the inode
        os.close(fd)


def _busy(target: Path, lock: Path) -> OutputError:
    return OutputError(f"{target}: another torquemod run is writing this folder (lock "
                       f"{lock.name}); wait for it to finish or choose another --out")


def _acquire(target: Path, lock: Path) -> int:
    """Open, flock and verify the lock file (a lock file unlinked by its previous holder
    between our open and our flock is not the lock any more: retry)."""
    flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0)
    while True:
        try:
            fd = os.open(lock, flags, 0o644)
        except OSError as exc:
            raise OutputError(f"{target}: cannot write in {target.parent} "
                              f"({_reason(exc)})") from None
        if fcntl is None:  # pragma: no cover - no flock: no protection against other runs
            return fd
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise _busy(target, lock) from None
        except OSError:  # a file system without flock: go on unprotected
            return fd
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}\n".encode())
            return fd
        os.close(fd)
