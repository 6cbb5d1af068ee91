"""A disk cache for deterministic tables of numbers (numpy ``.npz`` files).

Tables that take seconds to build and depend on nothing but torquemod's code and a few
parameters (e.g. the creep-law family's lookup tables) are built once per machine instead of
once per process: :func:`cached_arrays` keeps them in the user's cache folder
(:func:`cache_dir`: ``$XDG_CACHE_HOME/torquemod``, else ``~/.cache/torquemod``), one file per
key. The key names the torquemod and numpy versions and whatever the caller passes (the
tables' parameters, a digest of the source that builds them); the file stores its key again
and is used only when that matches. A file that cannot be read or does not hold what the key
promises is rebuilt; a folder that cannot be written leaves the cache out (the tables are then
built in every process, as without it). Files appear in one rename, so processes that build
the same tables at once never read half a file.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from torquemod._util.fsutil import sha256_file
from torquemod._version import __version__

__all__ = ["cache_dir", "cached_arrays", "source_digest"]

_KEY = "__cache_key__"


def cache_dir() -> Path:
    """The folder of torquemod's cache files: ``$XDG_CACHE_HOME/torquemod`` when that
    variable is set to an absolute path, else ``~/.cache/torquemod``."""
    base = os.environ.get("XDG_CACHE_HOME", "")
    root = Path(base) if base and os.path.isabs(base) else Path.home() / ".cache"
    return root / "torquemod"


def source_digest(*files: str | os.PathLike) -> str:
    """SHA-256 over the given source files' SHA-256 (:func:`~torquemod._util.fsutil.sha256_file`),
    in order (a missing file counts as empty):
    part of a key, so that a change of the code that builds the tables rebuilds them."""
    h = hashlib.sha256()
    for f in files:
        try:
            h.update(sha256_file(f).encode())
        except OSError:
            pass
        h.update(b"\0")
    return h.hexdigest()


def _load(path: Path, key_text: str, names: tuple[str, ...] | None) -> dict | None:
    try:
        with np.load(path, allow_pickle=False) as npz:
            if _KEY not in npz.files or str(npz[_KEY]) != key_text:
                return None
            out = {k: npz[k] for k in npz.files if k != _KEY}
    except Exception:  # any damage to the file means: build it again
        return None
    if names is not None and set(out) != set(names):
        return None
    return out


def _store(path: Path, key_text: str, arrays: dict[str, np.ndarray]) -> bool:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp", dir=path.parent)
    except OSError:
        return False
    stored = False
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **{_KEY: np.array(key_text)}, **arrays)
        os.replace(tmp, path)
        stored = True
    except OSError:
        pass
    finally:
        if os.path.exists(tmp):
            try:
                os.unlink(tmp)
            except OSError:
                pass
    return stored


def cached_arrays(name: str, key: dict, build: Callable[[], dict[str, np.ndarray]], *,
                  names: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
    """The arrays ``build()`` returns, from the disk cache when it holds them for ``key``.

    Parameters
    ----------
    name : str
        Name of the tables (the start of the file's name; letters, digits, ``_``, ``-``).
    key : dict
        JSON-serialisable description of everything the arrays depend on besides the
        torquemod and numpy versions (added here).
    build : callable
        Builds the arrays, ``{name: ndarray}`` (numeric or boolean arrays; no objects).
    names : tuple of str, optional
        The array names a valid file must hold.

    Returns
    -------
    dict of str to numpy.ndarray
        The arrays, equal bit for bit to what ``build()`` gives (``.npz`` stores them
        exactly).
    """
    full = {"torquemod": __version__, "numpy": np.__version__, "name": name, **key}
    key_text = json.dumps(full, sort_keys=True, default=repr)
    digest = hashlib.sha256(key_text.encode()).hexdigest()[:20]
    path = cache_dir() / f"{name}-{digest}.npz"
    if path.is_file():
        got = _load(path, key_text, names)
        if got is not None:
            return got
    arrays = build()
    if _store(path, key_text, arrays):
        _prune(path)
    return arrays


def _prune(kept: Path) -> None:
    """Remove the other files of the same tables (older versions or sources): one file of a
    name is kept, so the cache does not grow with every upgrade."""
    name = kept.name.rsplit("-", 1)[0]
    for old in kept.parent.glob(f"{name}-*.npz"):
        if old != kept:
            try:
                old.unlink()
            except OSError:
                pass
