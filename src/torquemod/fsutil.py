"""Writing result folders so that nothing half-written is ever left in place."""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TextIO

from .errors import OutputError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _publishable(path: Path, mode: int) -> None:
    """Give a temporary file or folder (created private by ``mkstemp``/``mkdtemp``) the
    permissions a plain ``open``/``mkdir`` would have given it under the current umask."""
    os.chmod(path, mode & ~_umask())


def check_output_dir(out_dir: str | Path, *, force: bool) -> Path:
    """Refuse an existing non-empty ``out_dir`` unless ``force`` (checked before any work)."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out}: exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise OutputError(f"{out}: folder already exists and is not empty; use --force to "
                          "replace it whole or choose another --out")
    return out


@contextlib.contextmanager
def atomic_dir(out_dir: str | Path, *, force: bool = False) -> Iterator[Path]:
    """Yield a fresh temporary folder beside ``out_dir``; on success it replaces ``out_dir``
    in one rename (an existing folder is replaced whole, only with ``force``); on any error
    the temporary folder is removed and ``out_dir`` is left as it was."""
    out = check_output_dir(out_dir, force=force).absolute()
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    except OSError as exc:
        raise OutputError(f"{out}: cannot create the results folder ({exc.strerror})") from None
    try:
        yield tmp
        _publishable(tmp, 0o777)
        if out.exists():
            trash = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
            os.replace(out, trash / out.name)
            os.replace(tmp, out)
            shutil.rmtree(trash, ignore_errors=True)
        else:
            os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


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
