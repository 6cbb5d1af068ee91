"""What a sweep's folder holds of its points and its study: each point's fingerprint and the
digests its resume record keeps (:func:`fingerprint`; :mod:`torquemod.results.resume`), the
study the folder belongs to (:func:`study_key`, :func:`one_study`) and the provenance block
of the folder (:func:`sweep_provenance`). :mod:`torquemod.sweep.run` runs the points.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

from torquemod._util.fsutil import write_atomic
from torquemod._version import __version__
from torquemod.errors import InputError
from torquemod.processing.provenance import provenance_block
from torquemod.results import resume
from torquemod.sweep.evaluate import PointTask
from torquemod.sweep.spec import SweepSpec

__all__ = ["STUDY_FILE", "digests", "fingerprint", "one_study", "partition_path",
           "study_key", "sweep_provenance"]


def partition_path(out: Path, point_id: str) -> Path:
    """Where a finished point's rows are: ``out/points/point=<id>/part-0.parquet``.

    Parameters
    ----------
    out : pathlib.Path
        The sweep's output folder.
    point_id : str
        The point's id.

    Returns
    -------
    pathlib.Path
        The Parquet file of its rows.
    """
    return out / "points" / f"point={point_id}" / "part-0.parquet"


def _fingerprint_doc(task: PointTask) -> dict:
    """What :func:`fingerprint` digests."""
    from torquemod.twins.train.params import default_train_config_text
    from torquemod.twins.vtrack.simulate import default_config_text
    default = default_train_config_text if task.kind == "train" else default_config_text
    base_text = (Path(task.base).read_text(encoding="utf-8") if task.base else default())
    extra = {"kind": task.kind, "max_mu_error": task.max_mu_error} if task.kind != "rig" else {}
    if task.kind == "rig" and task.mode == "full":  # the run-in rule (evaluate.settle_time_s)
        from torquemod.sweep.evaluate import CHAIN_RULE, SETTLE_RULE, SETTLE_TIME_CONSTANTS
        extra["rules"] = [SETTLE_RULE, SETTLE_TIME_CONSTANTS, CHAIN_RULE]
    return {**extra, "params": task.params, "seed": task.seed, "mode": task.mode,
            "fractions": task.fractions_of_peak,
            "max_utilisation": task.max_utilisation, "version": __version__,
            "processing": task.processing,
            "base": hashlib.sha256(base_text.encode()).hexdigest()}


def fingerprint(task: PointTask) -> str:
    """SHA-256 over what a point's rows depend on.

    Its parameters and seed, the mode, the torque fractions, the utilisation limit of the
    phase fit, the base config's text (the default config's when none), the torquemod
    version and, in full mode, the run-in rule and the chain's frequency scaling (a changed
    rule reruns the points). The resume record keeps it (:mod:`torquemod.results.resume`).

    Parameters
    ----------
    task : PointTask
        The point.

    Returns
    -------
    str
        Hex digest.
    """
    return resume.digest(_fingerprint_doc(task))


def digests(task: PointTask) -> tuple[str, str, str]:
    """The digests a point's resume record keeps.

    Parameters
    ----------
    task : PointTask
        The point.

    Returns
    -------
    tuple of str
        (fingerprint, digest of its parameters, digest of its input: the base config's
        text), hex.
    """
    doc = _fingerprint_doc(task)
    params = {k: v for k, v in doc.items() if k not in ("version", "base")}
    return resume.digest(doc), resume.digest(params), doc["base"]


#: the file in ``_state`` that names the study whose points the folder holds
STUDY_FILE = "study.json"


def study_key(spec: SweepSpec) -> str:
    """SHA-256 of what makes every point's rows comparable.

    Mode, kind, the base config's text, the torque fractions and the ``[processing]`` table
    (the points themselves are compared by their ids).

    Parameters
    ----------
    spec : SweepSpec
        The sweep.

    Returns
    -------
    str
        Hex digest.
    """
    base = Path(spec.base).read_text(encoding="utf-8") if spec.base else spec.kind
    return resume.digest({"mode": spec.mode, "kind": spec.kind,
                          "base": hashlib.sha256(base.encode()).hexdigest(),
                          "fractions": spec.fractions_of_peak, "processing": spec.processing})


def _held_points(out: Path) -> set[str]:
    """Ids of the points whose partition or state the folder holds."""
    ids = {p.name.split("=", 1)[1] for p in (out / "points").glob("point=*")}
    ids |= {p.stem for p in (out / resume.STATE_DIR).glob("*.json") if p.name != STUDY_FILE}
    return ids


def one_study(out: Path, spec: SweepSpec, todo: list[PointTask], force: bool):
    """Make sure ``out`` holds one study.

    Points of a sweep file whose grid, ``[fixed]`` values, mode, base, torque fractions or
    ``[processing]`` differ from ``spec``'s are never left beside its points. A folder
    holding such points is refused at once, or with ``force`` they are removed (a new study)
    by the function returned; a grown grid (every held point still in the sweep) resumes.

    Parameters
    ----------
    out : pathlib.Path
        The sweep's output folder.
    spec : SweepSpec
        The sweep.
    todo : list of PointTask
        Its points.
    force : bool
        Start a new study in a folder of another one.

    Returns
    -------
    callable
        ``begin()``: removes the other study's points (with ``force``), creates ``out``
        and records the study; called once the cluster answers.

    Raises
    ------
    InputError
        The folder holds another study's points and not ``force``.
    """
    key = study_key(spec)
    state = out / resume.STATE_DIR / STUDY_FILE
    try:
        old_key = json.loads(state.read_text(encoding="utf-8")).get("key")
    except (OSError, ValueError, AttributeError):
        old_key = None
    ids = {t.point_id for t in todo}
    stale = sorted(_held_points(out) - ids) if out.is_dir() else []
    changed = old_key is not None and old_key != key
    if stale or changed:
        why = (f"{len(stale)} of its points are not in this sweep (grid or [fixed] changed)"
               if stale else "mode, base, [steps] or [processing] changed")
        if not force:
            raise InputError(f"the folder holds the results of another study ({why})",
                             path=out, hint="choose another --out, or pass --force to start "
                                            "a new study there (the old points are removed)")

    def begin() -> None:
        if stale or changed:
            for pid in stale if not changed else sorted(_held_points(out)):
                shutil.rmtree(out / "points" / f"point={pid}", ignore_errors=True)
                resume.drop_record(out, pid)
            for name in ("sweep.parquet", "sweep.json", "failures.csv"):
                (out / name).unlink(missing_ok=True)
        state.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(state, lambda fh: fh.write(json.dumps(
            {"key": key, "sweep": str(spec.path), "n_points": len(ids)})))
    return begin


def sweep_provenance(spec: SweepSpec) -> dict:
    """The provenance block of a sweep's folder.

    Parameters
    ----------
    spec : SweepSpec
        The sweep.

    Returns
    -------
    dict
        :func:`~torquemod.processing.provenance.provenance_block` (kind ``"sweep"``) of the
        spec as parameters, the sweep file and its base config with their SHA-256.
    """
    inputs = [{"file": p, "role": role} for p, role in ((spec.path, "sweep"),
                                                        (spec.base, "base"))
              if p is not None]
    return provenance_block("sweep", spec.to_dict(), inputs)
