"""Finding the runs of a fleet: the manifests under a folder, their kind (rig experiment or train
run), the run names they get and the partition values of their tables.
"""

from __future__ import annotations

import datetime as _dt
import glob
import hashlib
import tomllib
from collections.abc import Iterable
from pathlib import Path

from torquemod.errors import InputError

MANIFEST_NAME = "experiment.toml"


RUN_NAME = "run.toml"


def find_manifests(runs: Iterable[str | Path]) -> list[Path]:
    """Run manifests from paths, folders, glob patterns or list files.

    Parameters
    ----------
    runs : iterable of str or pathlib.Path
        Manifest files, folders (every ``experiment.toml`` and ``run.toml`` below them), glob
        patterns, or list files (``.txt``/``.lst``: one of the above a line, ``#``
        comments).

    Returns
    -------
    list of pathlib.Path
        Sorted, without duplicates.
    """
    return sorted(_spellings(runs))


def _spellings(runs: Iterable[str | Path]) -> dict[Path, str]:
    """{resolved manifest path: the path as found} (the first spelling: a folder's or a
    list file's path joined with what was found there, as the user wrote it). ``runs`` may
    also be a single path or pattern."""
    out: dict[Path, str] = {}
    for p in _found(_as_list(runs)):
        out.setdefault(p.resolve(), str(p))
    return out


def _as_list(runs: Iterable[str | Path] | str | Path) -> list[str | Path]:
    """``runs`` as a list: a single path or pattern is a list of one (not its characters)."""
    return [runs] if isinstance(runs, str | Path) else list(runs)


def _found(runs: Iterable[str | Path]) -> list[Path]:
    found: list[Path] = []
    for item in runs:
        text = str(item)
        path = Path(text)
        if path.is_dir():
            found += sorted([*path.rglob(MANIFEST_NAME), *path.rglob(RUN_NAME)])
        elif path.is_file() and path.suffix.lower() in (".txt", ".lst"):
            lines = [ln.split("#", 1)[0].strip() for ln in path.read_text().splitlines()]
            found += _found([path.parent / ln for ln in lines if ln])
        elif path.is_file():
            found.append(path)
        elif any(ch in text for ch in "*?["):
            found += _found(sorted(glob.glob(text, recursive=True)))
        else:
            raise InputError("no such run manifest, folder or list", path=path,
                             hint="give experiment.toml or run.toml files, folders holding "
                                  "them, a glob or a .txt list of them")
    return found


def manifest_kind(path: Path) -> str:
    """Whether a manifest is a train run or a rig experiment.

    By content (a ``[vehicle]`` table without ``[rig]`` is a run, as the readers decide), else
    by the file name (``run.toml``) when the file does not parse (its reader then names the
    problem).

    Parameters
    ----------
    path : pathlib.Path
        The manifest.

    Returns
    -------
    {"train", "rig"}
        The kind.
    """
    try:
        doc = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        doc = None
    if isinstance(doc, dict) and ("vehicle" in doc or "rig" in doc):
        return "train" if "vehicle" in doc and "rig" not in doc else "rig"
    return "train" if Path(path).name == RUN_NAME else "rig"


def _safe(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in text)


def run_names(manifests: list[Path]) -> list[str]:
    """A partition name per manifest.

    Its folder's name (``folder-stem`` for a manifest not named experiment.toml or run.toml),
    with a short hash of the full path when two manifests share a name.

    Parameters
    ----------
    manifests : list of pathlib.Path
        The manifests.

    Returns
    -------
    list of str
        One name each, unique.
    """
    base = [m.parent.name if m.name in (MANIFEST_NAME, RUN_NAME) or not m.parent.name
            else f"{m.parent.name}-{m.stem}" for m in manifests]
    out = []
    for m, b in zip(manifests, base, strict=True):
        safe = _safe(b or m.stem)
        if base.count(b) > 1:
            safe += "-" + hashlib.sha256(str(m).encode()).hexdigest()[:8]
        out.append(safe)
    return out


def partition_value(value: object, *, day: bool = False) -> str:
    """A hive partition value.

    Characters other than letters, digits and ``-_.`` are replaced by ``_`` (no ``/`` or
    ``=`` can enter the path).

    Parameters
    ----------
    value : object
        The label (vehicle, date).
    day : bool
        Give the ISO day of a date, a date-time or a text starting with an ISO date.
        Default False.

    Returns
    -------
    str
        The value; ``unknown`` for nothing.

    Examples
    --------
    >>> partition_value("ICE 4/12")
    'ICE_4_12'
    >>> partition_value("2024-05-01T10:00", day=True)
    '2024-05-01'
    >>> partition_value(None)
    'unknown'
    """
    if value is None or (isinstance(value, str) and not value.strip()):
        return "unknown"
    if day:
        if isinstance(value, _dt.datetime):
            return value.date().isoformat()
        if isinstance(value, _dt.date):
            return value.isoformat()
        try:
            return _dt.date.fromisoformat(str(value).strip()[:10]).isoformat()
        except ValueError:
            pass
    return _safe(str(value).strip())[:80]
