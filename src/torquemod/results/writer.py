"""The one writer of torquemod's output folders, and the reader of their provenance.

Every command writes through :func:`write_folder`: ``process`` (and ``fit``/``report``
updating its folder), ``onboard``, the fleet (each run's partitions and the fleet's summary)
and the sweep (each point's partition and the sweep's summary). The writer

* takes the output's lock (one run at a time writes it:
  :func:`~torquemod._util.fsutil.output_lock`),
* hands the caller a temporary folder beside the output (or, for a summary, a staging folder
  inside it) to write the files into,
* writes the provenance block (:func:`~torquemod.processing.provenance.provenance_block`:
  torquemod, Python and library versions, the parameters, the inputs with their SHA-256, the
  time and command line) as ``provenance.json``,
* and publishes by rename when the block ends, or removes everything on an error or an
  interrupt (Ctrl-C), so no partial results are ever left.

The modes, by what is written:

``"new"``
    A whole new folder (``process``, ``onboard``): refused when occupied unless ``force``
    (torquemod output only), never an input or a folder holding one; gets the marker file
    (:data:`~torquemod._util.fsutil.MARKER`) that lets ``force`` replace it later.
``"update"``
    An existing results folder rewritten (``fit``, ``report``): a copy is modified and swapped
    in, so readers see the old folder or the new one.
``"replace"``
    A part of a resumable output the run owns (a fleet run's partition, a sweep point),
    replaced whole; no provenance file (dataset readers would take it for data: the part's
    provenance is its resume record, :mod:`torquemod.results.resume`).
``"into"``
    The summary files of a resumable output (the fleet's, the sweep's), staged inside it and
    moved in together; :meth:`Writing.drop` removes a file that no longer applies.
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from torquemod._util.fsstage import replace_dir, staged_dir
from torquemod._util.fsutil import atomic_dir, update_dir
from torquemod._util.jsonutil import write_json
from torquemod.errors import InputError
from torquemod.processing.provenance import BLOCK_KEYS, SOFTWARE_KEYS

__all__ = ["MODES", "PROVENANCE_FILE", "Writing", "read_provenance", "write_folder"]

#: the file of the provenance block in every folder the writer publishes
PROVENANCE_FILE = "provenance.json"
MODES = ("new", "update", "replace", "into")


@dataclass
class Writing:
    """A folder being written by :func:`write_folder`.

    Attributes
    ----------
    path : pathlib.Path
        The temporary folder to write the files into (published when the block ends).
    target : pathlib.Path
        Where they will be.
    provenance : dict or None
        The provenance block that will be written (for reports that show it).
    dropped : list of str
        Files of the target to remove when the block succeeds (:meth:`drop`).
    """

    path: Path
    target: Path
    provenance: dict | None
    dropped: list[str] = field(default_factory=list)

    def drop(self, name: str) -> None:
        """Remove the file ``name`` of the target when the block succeeds (mode
        ``"into"``: a summary file that no longer applies)."""
        self.dropped.append(name)


def _opened(target: Path, mode: str, *, kind: str, force: bool, refuse: list):
    if mode == "new":
        return atomic_dir(target, force=force, inputs=refuse, kind=kind)
    if mode == "update":
        return update_dir(target)
    if mode == "replace":
        return replace_dir(target)
    if mode == "into":
        return staged_dir(target)
    raise ValueError(f"mode must be one of {MODES}, not {mode!r}")


@contextlib.contextmanager
def write_folder(target, *, mode: str = "new", kind: str = "results",
                 provenance: dict | None = None, force: bool = False,
                 refuse: Iterable = ()) -> Iterator[Writing]:
    """Write the output folder ``target`` atomically (see the module docstring).

    Parameters
    ----------
    target : str or os.PathLike
        The output folder.
    mode : {"new", "update", "replace", "into"}, default "new"
        What is written (module docstring).
    kind : str, default "results"
        Recorded in the marker of a new folder.
    provenance : dict, optional
        The provenance block (:func:`~torquemod.processing.provenance.provenance_block`, or
        a record that holds it), written as :data:`PROVENANCE_FILE` when the block succeeds.
    force : bool, default False
        Mode ``"new"``: replace an existing folder of torquemod output.
    refuse : iterable of path
        Mode ``"new"``: the inputs, which the folder must never be or hold.

    Yields
    ------
    Writing
        ``.path`` is the folder to write into.

    Raises
    ------
    OutputError
        The target is occupied, is or holds an input, is being written by another run, or
        cannot be written; nothing partial is left behind.
    """
    target = Path(target)
    dropped: list[str] = []
    with _opened(target, mode, kind=kind, force=force, refuse=list(refuse)) as tmp:
        writing = Writing(Path(tmp), target, provenance, dropped)
        yield writing
        if provenance is not None:
            write_json(Path(tmp) / PROVENANCE_FILE, provenance)
    for name in dropped:
        (target / name).unlink(missing_ok=True)


def read_provenance(folder) -> dict:
    """The provenance block of an output folder (its ``provenance.json``).

    Parameters
    ----------
    folder : str or os.PathLike
        A folder torquemod wrote (``process``, ``onboard``, ``fleet``, ``sweep``).

    Returns
    -------
    dict
        The document; it holds every key of
        :data:`~torquemod.processing.provenance.BLOCK_KEYS` (``process`` adds the
        experiment, warnings, per-cycle details and timing).

    Raises
    ------
    InputError
        The file is missing, is not JSON or lacks a key of the block (named).
    """
    path = Path(folder) / PROVENANCE_FILE
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("no provenance here", path=path,
                         hint="give a folder torquemod wrote") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"unreadable provenance ({exc})", path=path) from None
    if not isinstance(doc, dict):
        raise InputError("damaged provenance: not a JSON object", path=path)
    missing = [k for k in BLOCK_KEYS if k not in doc and k != "kind"]  # kind: added later
    if not missing and isinstance(doc["software"], dict):
        missing = [f"software.{k}" for k in SOFTWARE_KEYS if k not in doc["software"]]
    if missing:
        raise InputError(f"damaged provenance: key(s) {missing} missing", path=path,
                         hint="written by an older torquemod? run the command again")
    return doc
