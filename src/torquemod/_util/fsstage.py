"""Publishing inside outputs a run resumes (the fleet's and the sweep's): a part folder
replaced whole (:func:`replace_dir`) and the summary files moved in together
(:func:`staged_dir`). The rules of :mod:`torquemod._util.fsutil` hold: written under a
hidden temporary name, published by rename, nothing left behind on an error or an
interrupt, a write error reported as one :class:`~torquemod.errors.OutputError` naming the
final path.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from torquemod._util.fsutil import (
    _converted,
    _exchange,
    _mkdtemp_beside,
    _publishable,
    moved_noreplace,
    output_error,
    output_lock,
)

__all__ = ["STAGE_PREFIX", "replace_dir", "staged_dir"]

#: name prefix of the hidden staging folder :func:`staged_dir` makes inside the output
STAGE_PREFIX = ".stage-"
_STAGE = re.compile(re.escape(STAGE_PREFIX) + r"[A-Za-z0-9_]{8}")


def _swap_in(new: Path, target: Path) -> None:
    """Move the folder ``new`` to ``target``; an existing ``target`` is exchanged with it
    (left at ``new``'s path, for the caller to delete)."""
    if not moved_noreplace(new, target):
        _exchange(new, target)


@contextlib.contextmanager
def replace_dir(target: str | Path) -> Iterator[Path]:
    """Yield a fresh temporary folder beside ``target`` (a hidden ``.{name}.tmp-XXXXXXXX``,
    which dataset readers skip); when the block ends it replaces ``target`` whole, in one
    step where the system allows (``RENAME_EXCHANGE``), and the old folder is deleted. For a
    part of an output the run owns (a fleet run's partition, a sweep point): no marker, no
    ``force`` check. On any error ``target`` is left as it was and the temporary folder is
    removed."""
    out = Path(os.path.abspath(target))
    with output_lock(out):
        tmp = _mkdtemp_beside(out)
        try:
            try:
                yield tmp
                _publishable(tmp, 0o777)
            except OSError as exc:
                if (err := _converted(exc, out, tmp)) is not None:
                    raise err from None
                raise
            try:
                _swap_in(tmp, out)
            except OSError as exc:
                raise output_error(exc, out, doing="cannot publish the output") from None
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


@contextlib.contextmanager
def staged_dir(folder: str | Path) -> Iterator[Path]:
    """Yield a hidden staging folder inside the existing output ``folder`` for the files
    that summarise it; when the block ends every entry moves into ``folder`` by one rename
    each (a file replaced with ``os.replace``, a folder such as ``figures/`` swapped in
    whole). On any error the staging folder is removed and ``folder``'s files are as they
    were. Staging folders left by a killed run are removed first."""
    out = Path(os.path.abspath(folder))
    with output_lock(out):
        out.mkdir(parents=True, exist_ok=True)
        with contextlib.suppress(OSError):
            for entry in os.scandir(out):
                if _STAGE.fullmatch(entry.name) and entry.is_dir(follow_symlinks=False):
                    shutil.rmtree(entry.path, ignore_errors=True)
        try:
            tmp = Path(tempfile.mkdtemp(prefix=STAGE_PREFIX, dir=out))
        except OSError as exc:
            raise output_error(exc, out, doing="cannot write in the output") from None
        try:
            try:
                yield tmp
            except OSError as exc:
                if (err := _converted(exc, out, tmp)) is not None:
                    raise err from None
                raise
            try:
                for name in sorted(os.listdir(tmp)):
                    src, dst = tmp / name, out / name
                    if src.is_dir() and not src.is_symlink():
                        _swap_in(src, dst)  # the old folder, if any, is left at src
                    else:
                        os.replace(src, dst)
            except OSError as exc:
                raise output_error(exc, out, doing="cannot publish the output") from None
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
