"""Writing output folders and files so that no data is ever lost.

The rules every output of torquemod follows:

* An output is assembled under a temporary name beside its place and published at the end in
  one rename, so it appears whole or not at all; on any error the temporary copy is removed
  and the target is left exactly as it was.
* An output never is, nor holds, one of the run's inputs (:func:`refuse_inputs`), also with
  ``force``.
* ``force`` replaces only a folder that holds torquemod output: one with the marker file
  :data:`MARKER` (written into every folder published here), or an older results folder made
  only of the results layout's files (:func:`is_torquemod_dir`). An empty folder is used
  without ``force``.
* Publishing never replaces a folder that appeared meanwhile (``renameat2`` with
  ``RENAME_NOREPLACE`` on Linux, a checked rename elsewhere); a forced replacement swaps the
  new folder in and the old one out in one step (``RENAME_EXCHANGE``) and deletes the old one
  after, so the target is never missing where the system allows it.
* One run at a time writes a target: an exclusive ``flock`` on ``.{name}.lock`` beside it
  (:func:`output_lock`); a second run fails at once.
* A full disk, a read-only or unwritable target, a quota or a damaged target end in one
  :class:`~torquemod.errors.OutputError` naming the path and the system's reason
  (:func:`output_error`); the CLI prints it as one line with exit code 2.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import hashlib
import json
import os
import re
import shutil
import stat
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import TextIO

from torquemod._util.fslock import output_lock
from torquemod._version import __version__
from torquemod.errors import OutputError

__all__ = ["MARKER", "atomic_dir", "atomic_file", "check_output_dir", "environment_error",
           "is_torquemod_dir", "output_error", "output_lock", "publish", "refuse_inputs",
           "sha256_file", "update_dir", "write_atomic", "write_marker"]

#: Marker file in every folder torquemod publishes; JSON ``{"format", "version", "kind", ...}``.
MARKER = ".torquemod-results"
MARKER_FORMAT = "torquemod-output"
MARKER_VERSION = 1
#: Files of a results folder written before the marker existed (a folder made only of these,
#: with ``steps.csv`` among them, counts as torquemod output).
LEGACY_RESULTS = frozenset({"cycles.csv", "steps.csv", "provenance.json", "fit.json",
                            "traces.npz", "figures", "report.html", "result.json", MARKER})
#: errno values that mean the system or the user's target is at fault, not torquemod: they end
#: in exit code 2 with one line, never in an internal error.
ENVIRONMENT_ERRNOS = frozenset(getattr(errno, name) for name in (
    "ENOSPC", "EDQUOT", "EFBIG", "EROFS", "EACCES", "EPERM", "EIO", "ENOTDIR", "EISDIR",
    "ENAMETOOLONG", "ELOOP", "ENOENT", "EEXIST", "ENOTEMPTY", "EMFILE", "ENFILE", "EXDEV",
    "EBUSY", "ETXTBSY", "ESTALE", "EMLINK", "ENXIO", "ENODEV") if hasattr(errno, name))
_H5_ERRNO = re.compile(r"errno = (\d+)")


# --------------------------------------------------------------------------- error messages

def environment_error(exc: BaseException) -> OSError | None:
    """The :class:`OSError` behind ``exc`` (itself, its cause or context) whose errno is one
    of :data:`ENVIRONMENT_ERRNOS`, else None. h5py's OSErrors carry the errno only in their
    text (``errno = 28``); it is read from there and set on the returned error."""
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            if exc.errno in ENVIRONMENT_ERRNOS:
                return exc
            if exc.errno is None and (m := _H5_ERRNO.search(str(exc))):
                code = int(m.group(1))
                if code in ENVIRONMENT_ERRNOS:
                    return OSError(code, os.strerror(code), exc.filename)
        exc = exc.__cause__ or exc.__context__
    return None


def _reason(exc: OSError) -> str:
    if exc.errno is not None:
        return exc.strerror or os.strerror(exc.errno)
    return " ".join(str(exc).split()) or type(exc).__name__


def output_error(exc: OSError, path: str | Path, *, doing: str = "cannot write",
                 tmp: Path | None = None, final: Path | None = None) -> OutputError:
    """One-line :class:`OutputError` for ``exc``: ``"{path}: {doing} ({reason})"``. The path is
    the file the error names when there is one (moved from the temporary folder ``tmp`` to
    its final place ``final``), else ``path``."""
    where = Path(path)
    name = exc.filename
    if isinstance(name, (str, bytes, os.PathLike)):
        where = Path(os.fsdecode(name))
        if tmp is not None and final is not None and where.is_relative_to(tmp):
            where = final / where.relative_to(tmp)
    return OutputError(f"{where}: {doing} ({_reason(exc)})")


# --------------------------------------------------------------------------- checks

def refuse_inputs(out: str | Path, inputs: Iterable[str | Path]) -> None:
    """Raise :class:`OutputError` if ``out`` is one of ``inputs`` or holds one (paths resolved,
    symbolic links followed): publishing there would delete the input, also with ``force``."""
    target = Path(out).resolve()
    for item in inputs:
        p = Path(item).resolve()
        if p == target or target in p.parents:
            what = "is" if p == target else "holds"
            raise OutputError(f"{out}: the output {what} the input {item}, which replacing it "
                              "would delete; choose an --out outside the inputs")


def _entries(folder: Path) -> list[str]:
    return sorted(os.listdir(folder))


def _marker_ok(folder: Path) -> bool:
    path = folder / MARKER
    try:
        if not stat.S_ISREG(path.lstat().st_mode) or path.stat().st_size > 4096:
            return False
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(doc, dict) and doc.get("format") == MARKER_FORMAT


def is_torquemod_dir(folder: str | Path, *, legacy_steps_only: bool = False) -> bool:
    """True if ``folder`` holds torquemod output: it has a valid :data:`MARKER`, or it is a
    results folder from before the marker (``steps.csv`` and nothing outside
    :data:`LEGACY_RESULTS`), or an old demo folder (``experiment/`` with the simulator's
    ``truth.json`` and ``results/``). With ``legacy_steps_only`` a ``steps.csv`` alone
    suffices (what ``fit``/``report`` accept)."""
    folder = Path(folder)
    if _marker_ok(folder):
        return True
    try:
        names = set(_entries(folder))
    except OSError:
        return False
    if names and names <= {"experiment", "results", MARKER}:  # an old demo folder
        return ((folder / "experiment" / "truth.json").is_file()
                and is_torquemod_dir(folder / "results"))
    if "steps.csv" not in names:
        return False
    return legacy_steps_only or names <= LEGACY_RESULTS


def check_output_dir(out_dir: str | Path, *, force: bool, inputs: Iterable = ()) -> Path:
    """Check an output folder before any work and return it: never an input or a folder
    holding one; a missing or empty folder is fine; a non-empty one only with ``force`` and
    only if it holds torquemod output (:func:`is_torquemod_dir`)."""
    out = Path(out_dir)
    refuse_inputs(out, inputs)
    try:
        st = out.lstat()
    except FileNotFoundError:
        _check_parent(out)
        return out
    except OSError as exc:
        raise output_error(exc, out, doing="cannot use as output folder") from None
    if stat.S_ISLNK(st.st_mode):
        raise OutputError(f"{out}: is a symbolic link; give the folder it points to as --out")
    if not stat.S_ISDIR(st.st_mode):
        raise OutputError(f"{out}: exists and is not a folder; choose another --out")
    try:
        names = _entries(out)
    except OSError as exc:
        raise output_error(exc, out, doing="cannot read the output folder") from None
    if names and not force:
        raise OutputError(f"{out}: folder already exists and is not empty; pass force=True to "
                          "replace it whole (torquemod results only) or choose another --out")
    if names and not is_torquemod_dir(out):
        raise OutputError(f"{out}: force=True replaces only a folder of torquemod results, and "
                          f"this one holds other files (e.g. '{_foreign(names)}') and no "
                          f"{MARKER}; "
                          "move them away or choose another --out")
    return out


def _foreign(names: list[str]) -> str:
    return next((n for n in names if n not in LEGACY_RESULTS), names[0])


def _check_parent(out: Path) -> None:
    """Refuse early a missing ``out`` whose nearest existing ancestor is not a writable
    folder (the run would otherwise fail only when it publishes)."""
    anc = Path(os.path.abspath(out)).parent
    while not os.path.lexists(anc) and anc != anc.parent:
        anc = anc.parent
    code = None
    if not anc.is_dir():
        code = errno.ENOTDIR
    elif not os.access(anc, os.W_OK | os.X_OK):
        code = errno.EROFS if _read_only_fs(anc) else errno.EACCES
    if code is not None:
        raise OutputError(f"{out}: cannot write in {anc} ({os.strerror(code)})")


def _read_only_fs(path: Path) -> bool:
    try:
        return bool(os.statvfs(path).f_flag & os.ST_RDONLY)
    except OSError:
        return False


# --------------------------------------------------------------------------- renaming

_AT_FDCWD = -100
_RENAME_NOREPLACE = 1
_RENAME_EXCHANGE = 2


def _load_renameat2():
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError, TypeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                   ctypes.c_uint]
    fn.restype = ctypes.c_int
    return fn


_renameat2_fn = _load_renameat2()


def _renameat2(src: Path, dst: Path, flags: int) -> bool:
    """Linux ``renameat2``; True when done, False when the system or file system lacks it
    (the caller falls back). Other failures raise OSError naming ``dst``."""
    if _renameat2_fn is None:
        return False
    if _renameat2_fn(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), flags) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.ENOSYS, errno.EINVAL, getattr(errno, "ENOTSUP", -1),
                getattr(errno, "EOPNOTSUPP", -1)):
        return False
    raise OSError(code, os.strerror(code), str(dst))


def _rename_noreplace(src: Path, dst: Path) -> None:
    """Move ``src`` to ``dst``, failing with FileExistsError if ``dst`` exists (a folder that
    appeared there is never replaced)."""
    if _renameat2(src, dst, _RENAME_NOREPLACE):
        return
    if src.is_dir() and not src.is_symlink():
        # rename(2) onto a non-empty folder fails (ENOTEMPTY/EEXIST); only an empty folder
        # that appeared after this check could be replaced, which loses nothing
        if os.path.lexists(dst):
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst))
        os.rename(src, dst)
        return
    try:
        os.link(src, dst)  # fails with EEXIST if dst exists, atomically
    except FileExistsError:
        raise
    except OSError:  # no hard links here: checked rename
        if os.path.lexists(dst):
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst)) from None
        os.rename(src, dst)
        return
    os.unlink(src)


def moved_noreplace(src: Path, dst: Path) -> bool:
    """Move ``src`` to ``dst`` when nothing is there (:func:`_rename_noreplace`): True when
    moved, False when ``dst`` exists (left as it is, ``src`` too); other errors propagate."""
    try:
        _rename_noreplace(src, dst)
        return True
    except (FileExistsError, IsADirectoryError, NotADirectoryError):
        return False
    except OSError as exc:
        if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST):
            raise
        return False


def _exchange(new: Path, old: Path) -> None:
    """Swap folder ``new`` into ``old``'s place; afterwards ``new``'s path holds the old
    folder (for the caller to delete). One atomic step with ``RENAME_EXCHANGE``; elsewhere
    the old folder is moved aside first and put back if the new one cannot move in."""
    if _renameat2(new, old, _RENAME_EXCHANGE):
        return
    aside = Path(tempfile.mkdtemp(prefix=f".{old.name}.old-", dir=old.parent))
    try:
        os.rename(old, aside / old.name)
        try:
            _rename_noreplace(new, old)
        except BaseException:
            os.rename(aside / old.name, old)
            raise
        os.rename(aside / old.name, new)
    finally:
        shutil.rmtree(aside, ignore_errors=True)


def publish(tmp: str | Path, target: str | Path, *, force: bool = False,
            update: bool = False) -> None:
    """Move the finished folder ``tmp`` to ``target`` (both in one parent folder).

    A missing target is created by a no-replace rename; a target that exists by now must be
    an empty folder, or with ``force`` a folder of torquemod output, and is swapped out (then
    left at ``tmp``'s path for the caller to delete). Anything else, including a folder that
    appeared while the run was working, is refused with :class:`OutputError` and left as it
    is. ``update`` (what :func:`update_dir` passes) also accepts an older results folder with
    a ``steps.csv`` and files of its own."""
    tmp, target = Path(tmp), Path(target)
    try:
        if moved_noreplace(tmp, target):
            return
        if target.is_symlink() or not target.is_dir():
            raise OutputError(f"{target}: something else appeared at the output's place "
                              "while this run was working; it was left as it is, and the "
                              "results were not written; choose another --out")
        if _entries(target):
            if not force:
                raise OutputError(f"{target}: a folder appeared there while this run was "
                                  "working; it was left as it is, and the results were not "
                                  "written; rerun with another --out")
            if not is_torquemod_dir(target, legacy_steps_only=update):
                raise OutputError(f"{target}: force=True replaces only a folder of torquemod "
                                  f"results, and this one holds other files and no {MARKER}; "
                                  "the results were not written; choose another --out")
        _exchange(tmp, target)
    except OutputError:
        raise
    except OSError as exc:
        raise output_error(exc, target, doing="cannot publish the output") from None


# --------------------------------------------------------------------------- folders

def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _publishable(path: Path, mode: int) -> None:
    """Give a temporary file or folder (created private by ``mkstemp``/``mkdtemp``) the
    permissions a plain ``open``/``mkdir`` would have given it under the current umask."""
    os.chmod(path, mode & ~_umask())


def write_marker(folder: str | Path, kind: str = "results") -> Path:
    """Write :data:`MARKER` into ``folder``: JSON with format, version, kind and the
    torquemod version that wrote it."""
    path = Path(folder) / MARKER
    doc = {"format": MARKER_FORMAT, "version": MARKER_VERSION, "kind": kind,
           "torquemod_version": __version__}
    path.write_text(json.dumps(doc) + "\n", encoding="utf-8")
    return path


def _mkdtemp_beside(target: Path) -> Path:
    """A new temporary folder ``.{name}.tmp-XXXXXXXX`` beside ``target``. Called with the
    target's lock held, so older ones (left by a killed run) are removed first."""
    _sweep_stale(target)
    try:
        return Path(tempfile.mkdtemp(prefix=f".{target.name}.tmp-", dir=target.parent))
    except OSError as exc:
        raise output_error(exc, target, doing="cannot create the output") from None


def _sweep_stale(target: Path) -> None:
    pattern = re.compile(re.escape(f".{target.name}.") + r"(tmp|old)-[A-Za-z0-9_]{8}")
    with contextlib.suppress(OSError):
        for entry in os.scandir(target.parent):
            if pattern.fullmatch(entry.name) and entry.is_dir(follow_symlinks=False):
                shutil.rmtree(entry.path, ignore_errors=True)


def _converted(exc: BaseException, target: Path, tmp: Path) -> OutputError | None:
    """The OutputError for an exception raised while the caller wrote into ``tmp``: an
    OSError naming a file in ``tmp``, or a full disk, quota, too large a file or read-only
    file system without a file name (h5py's errno in its text included). Others (an input
    that cannot be read, say) are left to the caller."""
    if isinstance(exc, OutputError) or not isinstance(exc, OSError):
        return None
    name = exc.filename
    if isinstance(name, (str, os.PathLike)) and Path(name).is_relative_to(tmp):
        return output_error(exc, target, tmp=tmp, final=target)
    env = environment_error(exc)
    if env is not None and env.filename is None and env.errno in _WRITE_ERRNOS:
        return output_error(env, target)
    return None


_WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EFBIG, errno.EROFS,
                           getattr(errno, "EDQUOT", errno.ENOSPC)})


@contextlib.contextmanager
def atomic_dir(out_dir: str | Path, *, force: bool = False, inputs: Iterable = (),
               kind: str = "results") -> Iterator[Path]:
    """Yield a fresh temporary folder beside ``out_dir`` to write the output into; when the
    block ends it gets :data:`MARKER` (``kind`` in it) and is published at ``out_dir``
    (:func:`publish`). The rules of :func:`check_output_dir` hold at the start and again at
    the end; the run holds :func:`output_lock` throughout. On any error the temporary folder
    is removed and ``out_dir`` is left as it was; a write error in it (full disk, read-only,
    ...) becomes one :class:`OutputError` naming the final path."""
    out = Path(os.path.abspath(out_dir))
    inputs = list(inputs)
    with output_lock(out):
        check_output_dir(out, force=force, inputs=inputs)
        tmp = _mkdtemp_beside(out)
        try:
            try:
                yield tmp
                write_marker(tmp, kind)
                _publishable(tmp, 0o777)
            except OSError as exc:
                if (err := _converted(exc, out, tmp)) is not None:
                    raise err from None
                raise
            refuse_inputs(out, inputs)
            publish(tmp, out, force=force)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


def _writable(folder: Path) -> None:
    """Refuse a folder the user made read-only (or on a read-only file system) up front:
    its update would otherwise replace it by a writable copy."""
    if os.access(folder, os.W_OK):
        return
    code = errno.EROFS if _read_only_fs(folder) else errno.EACCES
    raise output_error(OSError(code, os.strerror(code), str(folder)), folder,
                       doing="cannot update the results folder")


@contextlib.contextmanager
def update_dir(folder: str | Path) -> Iterator[Path]:
    """Update the results folder ``folder`` atomically (``torquemod fit`` and ``report``):
    yields a temporary copy of it beside it to modify, then swaps the copy in
    (:func:`publish` with ``force``), so readers see the old folder or the new one and a
    failure halfway leaves the old folder untouched. Files are copied, never hard-linked, so
    writing into the copy cannot reach the old folder. Refused (:class:`OutputError`): a
    missing folder, one without :data:`MARKER` and without ``steps.csv``, a read-only one,
    one another run is writing."""
    folder = Path(os.path.abspath(folder))
    if not folder.is_dir() or folder.is_symlink():
        raise OutputError(f"{folder}: no such results folder; run 'torquemod process' first")
    with output_lock(folder):
        if not is_torquemod_dir(folder, legacy_steps_only=True):
            raise OutputError(f"{folder}: not a torquemod results folder (no {MARKER} and no "
                              "steps.csv); give the folder 'torquemod process' wrote")
        _writable(folder)
        tmp = _mkdtemp_beside(folder)
        try:
            try:
                shutil.copytree(folder, tmp, symlinks=True, dirs_exist_ok=True)
                yield tmp
                if not _marker_ok(tmp):
                    write_marker(tmp, "results")
            except shutil.Error as exc:  # copytree's list of failures
                first = exc.args[0][0] if exc.args and isinstance(exc.args[0], list) else exc
                raise OutputError(f"{folder}: cannot copy the results folder to update it "
                                  f"({' '.join(str(first).split())})") from None
            except OSError as exc:
                if (err := _converted(exc, folder, tmp)) is not None:
                    raise err from None
                raise
            publish(tmp, folder, force=True, update=True)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


# --------------------------------------------------------------------------- files

@contextlib.contextmanager
def atomic_file(out_path: str | Path, *, force: bool = False, inputs: Iterable = ()
                ) -> Iterator[Path]:
    """Yield a temporary path (same name, in a temporary folder beside ``out_path``) to
    write one output file; published at the end without replacing an existing file unless
    ``force``. ``out_path`` is never one of ``inputs`` (also through a link), nor a folder.
    On any error nothing is left behind and ``out_path`` is as it was."""
    out = Path(os.path.abspath(out_path))
    inputs = list(inputs)
    with output_lock(out):
        _check_output_file(out, force=force, inputs=inputs)
        tmp_dir = _mkdtemp_beside(out)
        tmp = tmp_dir / out.name
        try:
            try:
                yield tmp
                _publishable(tmp, 0o666)
            except OSError as exc:
                if (err := _converted(exc, out, tmp_dir)) is not None:
                    raise err from None
                raise
            _check_output_file(out, force=force, inputs=inputs)
            try:
                if force:
                    os.replace(tmp, out)
                else:
                    _rename_noreplace(tmp, out)
            except FileExistsError:
                raise OutputError(f"{out}: a file appeared there while this run was "
                                  "working; it was left as it is; pass force=True to replace it "
                                  "or choose another --out") from None
            except OSError as exc:
                raise output_error(exc, out, doing="cannot publish the output") from None
        finally:
            shutil.rmtree(tmp_dir, ignore_errors=True)


def _check_output_file(out: Path, *, force: bool, inputs: list) -> None:
    for item in inputs:
        p = Path(item)
        same = p.resolve() == out.resolve()
        with contextlib.suppress(OSError):
            same = same or os.path.samefile(p, out)
        if same:
            raise OutputError(f"{out}: the output is the input {item}; choose another --out "
                              "(force=True never overwrites an input)")
    if out.is_dir():
        raise OutputError(f"{out}: is a folder; give the output file's name")
    if os.path.lexists(out) and not force:
        raise OutputError(f"{out}: file already exists; pass force=True to replace it or choose "
                          "another --out")


def write_atomic(path: str | Path, write: Callable[[TextIO], object]) -> Path:
    """Write a text file through ``write(fh)`` into a temporary file beside ``path`` and move
    it into place with ``os.replace``: readers see the old file or the new one, never half."""
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
                write(fh)
            _publishable(Path(tmp), 0o666)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except OSError as exc:
        raise OutputError(f"{path}: cannot write ({exc.strerror or exc})") from None
    return path


def sha256_file(path: str | Path, *, chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


@contextlib.contextmanager
def removed_if_left_empty(folder: str | Path) -> Iterator[Path]:
    """A folder the block may create (a resumable output such as the fleet's or the
    sweep's): when the block fails and the folder did not exist before, it is removed again
    with any empty folders inside it, so a run that stopped before writing a result (an
    unreachable cluster, an interrupt at the start) leaves nothing; anything written stays
    (a rerun resumes from it)."""
    folder = Path(folder)
    existed = os.path.lexists(folder)
    try:
        yield folder
    except BaseException:
        if not existed and folder.is_dir():
            for sub, _dirs, _files in os.walk(folder, topdown=False):
                with contextlib.suppress(OSError):
                    os.rmdir(sub)
        raise
