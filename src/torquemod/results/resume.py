"""The resume record: what a resumable output (the fleet's runs, the sweep's points) holds
of each finished part, read back to decide whether a rerun skips the part or redoes it.

One JSON file per part, ``OUT/_state/<name>.json``, written atomically once the part's
outputs are in place (:func:`write_record`) and removed when the part fails
(:func:`drop_record`). :func:`read_record` is the only reader and :func:`decide` the only
rule: a part is skipped when its fingerprint (a digest of everything its outputs depend on:
inputs, parameters, torquemod version) is unchanged and its outputs are in place, and redone
otherwise, with the reason (which of version, parameters and inputs changed).

The record keeps the keys earlier versions wrote (the fleet's ``partitions``, ``files``,
``row``, ``manifest``; the sweep's ``point_id``, ``params``, ``seed``, ``n_rows``,
``seconds``) beside the common ones, so folders written before resume as before.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

from torquemod._util.fsutil import write_atomic
from torquemod._util.jsonutil import to_jsonable
from torquemod._version import __version__
from torquemod.processing.provenance import utc_now

__all__ = ["STATE_DIR", "Decision", "ResumeRecord", "decide", "digest", "drop_record",
           "read_record", "record_path", "write_record"]

#: the folder of the records inside the output
STATE_DIR = "_state"
_COMMON = ("name", "status", "fingerprint", "version", "parameters_digest", "inputs_digest",
           "outputs", "created_utc")


def digest(obj) -> str:
    """SHA-256 of a JSON-able object.

    Parameters
    ----------
    obj : object
        Dicts, lists, numbers, text (other objects as their text).

    Returns
    -------
    str
        The hex digest of its canonical JSON (sorted keys).
    """
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()


@dataclass(frozen=True)
class ResumeRecord:
    """A finished part of a resumable output.

    Attributes
    ----------
    name : str
        The part: a fleet run's name, a sweep point's id.
    fingerprint : str
        Digest of everything the part's outputs depend on (decides the skip).
    parameters_digest, inputs_digest : str or None
        Digests of its parameters and of its inputs (say what changed).
    version : str
        The torquemod version that wrote it.
    status : str
        ``"done"``.
    outputs : tuple of str
        The part's outputs, relative to the output folder; all must exist for a skip.
    created_utc : str
        When it was written (ISO 8601, UTC).
    extra : dict
        The command's own keys, kept at the top level of the file.
    """

    name: str
    fingerprint: str
    parameters_digest: str | None = None
    inputs_digest: str | None = None
    version: str = __version__
    status: str = "done"
    outputs: tuple[str, ...] = ()
    created_utc: str = ""
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """The JSON document (the command's keys first, then the common ones)."""
        return {**self.extra, "name": self.name, "status": self.status,
                "fingerprint": self.fingerprint, "version": self.version,
                "parameters_digest": self.parameters_digest,
                "inputs_digest": self.inputs_digest, "outputs": list(self.outputs),
                "created_utc": self.created_utc or utc_now()}

    @classmethod
    def from_dict(cls, doc: dict, name: str) -> ResumeRecord:
        """A record from its document (one an earlier version wrote included: its
        ``partitions`` are the outputs; a missing version is unknown)."""
        outputs = doc.get("outputs", doc.get("partitions")) or ()
        return cls(name=str(doc.get("name") or name), fingerprint=str(doc.get("fingerprint")),
                   parameters_digest=doc.get("parameters_digest"),
                   inputs_digest=doc.get("inputs_digest"),
                   version=str(doc.get("version") or "unknown"),
                   status=str(doc.get("status") or "done"),
                   outputs=tuple(str(o) for o in outputs),
                   created_utc=str(doc.get("created_utc") or ""),
                   extra={k: v for k, v in doc.items() if k not in _COMMON})


def record_path(out, name: str) -> Path:
    """The record file of a part.

    Parameters
    ----------
    out : str or pathlib.Path
        The output folder.
    name : str
        The part.

    Returns
    -------
    pathlib.Path
        ``out/_state/<name>.json``.
    """
    return Path(out) / STATE_DIR / f"{name}.json"


def read_record(out, name: str) -> ResumeRecord | None:
    """The record of a part: the one reader of the resume state.

    Parameters
    ----------
    out : str or pathlib.Path
        The output folder.
    name : str
        The part.

    Returns
    -------
    ResumeRecord or None
        None when there is none or it cannot be read (the part is then redone).
    """
    try:
        doc = json.loads(record_path(out, name).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or not doc.get("fingerprint"):
        return None
    return ResumeRecord.from_dict(doc, name)


def write_record(out, record: ResumeRecord) -> Path:
    """Write a record atomically: a reader sees the old record or the new one.

    Parameters
    ----------
    out : str or pathlib.Path
        The output folder.
    record : ResumeRecord
        The finished part's record.

    Returns
    -------
    pathlib.Path
        The record's file.
    """
    path = record_path(out, record.name)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(to_jsonable(record.to_dict()), default=str, allow_nan=False)
    return write_atomic(path, lambda fh: fh.write(text))


def drop_record(out, name: str) -> None:
    """Remove the record of a part (its outputs are gone or stale).

    Parameters
    ----------
    out : str or pathlib.Path
        The output folder.
    name : str
        The part.
    """
    record_path(out, name).unlink(missing_ok=True)


@dataclass(frozen=True)
class Decision:
    """:func:`decide`'s answer.

    Attributes
    ----------
    redo : bool
        Redo the part (else skip it).
    reason : str
        Why: ``"new"``, ``"forced"``, ``"unchanged"`` or what changed.
    """

    redo: bool
    reason: str

    @property
    def message(self) -> str:
        """What to tell the user: empty for a new, forced or unchanged part, else
        ``"redone: <what changed>"``."""
        return "" if self.reason in ("new", "forced", "unchanged") else f"redone: {self.reason}"


def decide(record: ResumeRecord | None, fingerprint: str, *, outputs_ok: bool = True,
           parameters_digest: str | None = None, inputs_digest: str | None = None,
           force: bool = False) -> Decision:
    """Skip or redo a part: the one rule of the fleet and the sweep.

    Parameters
    ----------
    record : ResumeRecord or None
        What :func:`read_record` found.
    fingerprint : str
        The part's fingerprint now.
    outputs_ok : bool
        Whether the part's outputs are in place. Default True.
    parameters_digest, inputs_digest : str or None
        Its parameters' and inputs' digests now (to say what changed). Default None.
    force : bool
        Redo it anyway. Default False.

    Returns
    -------
    Decision
        Skipped when ``record`` holds ``fingerprint``, the outputs are in place and not
        ``force``; else redone, saying what changed (torquemod version, parameters, inputs,
        or outputs missing) when the record tells.
    """
    if record is None:
        return Decision(True, "new")
    if force:
        return Decision(True, "forced")
    if record.fingerprint == fingerprint:
        return (Decision(False, "unchanged") if outputs_ok
                else Decision(True, "its outputs are missing"))
    changed = []
    if record.version != __version__:
        changed.append(f"torquemod version {record.version} -> {__version__}")
    if parameters_digest is not None and record.parameters_digest not in (None,
                                                                          parameters_digest):
        changed.append("parameters changed")
    if inputs_digest is not None and record.inputs_digest not in (None, inputs_digest):
        changed.append("inputs changed")
    return Decision(True, ", ".join(changed) or "fingerprint changed")
