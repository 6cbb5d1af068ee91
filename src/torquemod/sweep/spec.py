"""The sweep file ``SWEEP.toml``: parsed and checked into typed points (format in
docs/sweep.md).

A sweep names a base twin configuration (the V-Track default, or a config TOML as
``torquemod simulate`` reads it; or a train run: ``base = "train"``, or a train config TOML
with ``kind = "train"``, see :mod:`torquemod.sweep.trainpoint`), the twin parameters to vary
by their dotted config key (``"modulation.frequency_hz"``, ``"contact.mu0"``,
``"sensors.torque_noise_nm"``, ...; the keys of the twin's configuration,
:class:`~torquemod.twins.vtrack.simconfig.SimTables`, or the train's), as a cartesian
``[grid]`` and/or a list of ``[[point]]`` tables, the mode (``"full"``: twin + processing
chain + fits; ``"theory"``: large-signal theory only) and the seeds. Every mistake is an
:class:`InputError` naming the sweep file and the key, with the nearest known key when it
looks like a typo.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path

from torquemod._util.tomlcheck import (
    between,
    checked,
    checked_value,
    default_checks,
    one_of,
    read_table,
    unknown_keys,
)
from torquemod.errors import InputError
from torquemod.sweep.conditions import conditions

__all__ = ["CONDITION_KEY", "MAX_POINTS", "RecommendOptions", "SweepPoint", "SweepSpec",
           "conditions", "load_sweep", "parse_sweep", "twin_keys"]

#: A sweep-only key: a named friction condition filling the five Polach parameters
CONDITION_KEY = "contact.condition"
_TOP_KEYS = ("name", "description", "base", "mode", "seeds", "repeats", "max_utilisation",
             "fixed", "steps", "grid", "point", "recommend", "processing")
_MODES = ("full", "theory")
_POLACH_KEYS = ("mu0", "a_ratio", "b_s_m", "k_a", "k_s")


def twin_keys() -> dict[str, object]:
    """Every dotted key of the rig twin's configuration with its default value.

    The keys are the fields of :class:`~torquemod.twins.vtrack.simconfig.SimTables`, the
    values those read from the default file.

    Returns
    -------
    dict of str to object
        ``section.key`` -> default.
    """
    from torquemod.twins.vtrack.simconfig import default_tables
    tables = default_tables()
    return {f"{s.name}.{f.name}": getattr(getattr(tables, s.name), f.name)
            for s in fields(tables) for f in fields(getattr(tables, s.name))}


@dataclass(frozen=True)
class RecommendOptions:
    """Limits of the recommendation (``[recommend]``).

    Attributes
    ----------
    max_utilisation : float
        Highest utilisation whose steps the mu-from-phase fit may use, and below which the
        disturbance is judged [-]. Default 0.8.
    max_creepage_swing : float
        Largest creepage swing amplitude the modulation may add [-]. Default 0.002.
    max_torque_ripple_pct : float
        Largest torque ripple: modulation amplitude of the measured torque [% of the
        saturation torque]. Default 15.
    max_mu_error : float
        Train sweeps: a mu row counts when its relative error is within this [-].
        Default 0.1.
    min_coverage : float
        Train sweeps: a setting qualifies when its 95 % intervals hold the truth in this
        share of the rows with mu [-]. Default 0.9.
    max_torque_ripple_dc_pct : float
        Train sweeps: largest median torque ripple [% of the DC torque]. Default 25.
    """

    max_utilisation: float = 0.8
    max_creepage_swing: float = 2.0e-3
    max_torque_ripple_pct: float = 15.0
    #: train sweeps: a mu row counts when its error is within ``max_mu_error`` [-]; a
    #: setting qualifies when its 95 % intervals hold the truth in ``min_coverage`` [-] of
    #: the rows with mu, and its torque ripple (median) stays within
    #: ``max_torque_ripple_dc_pct`` [%] of the DC torque
    max_mu_error: float = 0.10
    min_coverage: float = 0.90
    max_torque_ripple_dc_pct: float = 25.0


@dataclass(frozen=True)
class SweepPoint:
    """One point of the sweep.

    Attributes
    ----------
    index : int
        Its order in the file.
    params : dict
        Dotted twin key -> value, the fixed ones included.
    seed : int
        The twin's random seed.

    Notes
    -----
    ``point_id`` is a digest of the parameters and the seed (stable when the grid is
    reordered or extended).
    """

    index: int
    params: dict
    seed: int

    @property
    def point_id(self) -> str:
        blob = json.dumps({"params": self.params, "seed": self.seed}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:12]

    def overrides(self) -> dict:
        """The parameters as ``load_config(overrides=...)`` takes them (nested sections);
        a ``contact.condition`` becomes its five Polach values, a Polach key given as well
        wins over the condition's."""
        nested: dict = {}
        cond = self.params.get(CONDITION_KEY)
        if cond is not None:
            nested["contact"] = conditions()[cond].as_dict()
        for key, value in self.params.items():
            if key == CONDITION_KEY:
                continue
            section, name = key.split(".", 1)
            nested.setdefault(section, {})[name] = value
        return nested


@dataclass(frozen=True)
class SweepSpec:
    """A parsed sweep file.

    Attributes
    ----------
    path : pathlib.Path or None
        Where it came from.
    text : str
        Its text.
    name : str
        The sweep's name.
    description : str
        Its description.
    base : pathlib.Path or None
        The base configuration; None: the packaged default.
    mode : {"theory", "full"}
        Theory only, or twin -> chain -> fits.
    seeds : tuple of int
        The seeds each grid point runs with.
    points : tuple of SweepPoint
        The points.
    swept : tuple of str
        The swept keys, in file order.
    fixed : dict
        The ``[fixed]`` values.
    fractions_of_peak : tuple of float or None
        DC torques as fractions of each point's creep-curve peak torque [-]; None: the base
        procedure's torques.
    recommend : RecommendOptions
        The recommendation's limits.
    processing : dict
        The chain's ``[processing]`` table (full mode).
    kind : {"rig", "train"}
        The twin. Default "rig".
    """

    path: Path | None
    text: str
    name: str
    description: str
    base: Path | None
    mode: str
    seeds: tuple[int, ...]
    points: tuple[SweepPoint, ...]
    swept: tuple[str, ...]
    fixed: dict = field(default_factory=dict)
    fractions_of_peak: tuple[float, ...] | None = None
    recommend: RecommendOptions = RecommendOptions()
    processing: dict = field(default_factory=dict)
    #: "rig" (the V-Track twin, one row per torque step) or "train" (a train run, one row
    #: per friction segment)
    kind: str = "rig"

    def to_dict(self) -> dict:
        return {"name": self.name, "description": self.description,
                "path": None if self.path is None else str(self.path),
                "base": None if self.base is None else str(self.base), "mode": self.mode,
                "seeds": list(self.seeds), "swept": list(self.swept), "fixed": self.fixed,
                "fractions_of_peak": (None if self.fractions_of_peak is None
                                      else list(self.fractions_of_peak)),
                "recommend": self.recommend.__dict__, "processing": self.processing,
                "kind": self.kind, "n_points": len(self.points)}


def _flatten(table: dict, prefix: str = "") -> dict:
    """``{"contact": {"mu0": [..]}}`` and ``{"contact.mu0": [..]}`` alike -> dotted keys."""
    out = {}
    for key, value in table.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flatten(value, name + "."))
        else:
            out[name] = value
    return out


def _check_value(key: str, value, where: str, path, kind: str = "rig") -> None:
    """A parameter's value checked as the twin's reader checks its key (type and range,
    :func:`~torquemod.twins.vtrack.simconfig.twin_key_check`; a condition: a known name),
    so that a mistake names the sweep file, the table and the key before any point runs."""
    if kind == "train":
        from torquemod.sweep.trainpoint import check_train_value
        check_train_value(key, value, where, path)
        return
    try:
        if key == CONDITION_KEY:
            checked_value(value, str, key, None, one_of(*conditions()))
        else:
            from torquemod.twins.vtrack.simconfig import twin_key_check
            twin_key_check(key, value, None)
    except InputError as exc:
        hint = ("or give the Polach parameters (contact.mu0, a_ratio, b_s_m, k_a, k_s)"
                if key == CONDITION_KEY else None)
        raise InputError(f"{where}: {exc}", path=path, hint=hint) from None


def _params(table, where: str, path, allowed) -> dict:
    if not isinstance(table, dict):
        raise InputError(f"{where} must be a table of 'section.key = value'", path=path)
    flat = _flatten(table)
    unknown_keys(flat, allowed, where, path, takes="twin parameters are")
    return flat


def _seeds(doc: dict, path) -> tuple[int, ...]:
    if "seeds" in doc and "repeats" in doc:
        raise InputError("give 'seeds' or 'repeats', not both", path=path)
    if "repeats" in doc:
        n = doc["repeats"]
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise InputError(f"'repeats' must be a positive integer, got {n!r}", path=path)
        return tuple(range(n))
    seeds = doc.get("seeds", [0])
    if isinstance(seeds, int) and not isinstance(seeds, bool):
        seeds = [seeds]
    if (not isinstance(seeds, list) or not seeds
            or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0
                       for s in seeds)):
        raise InputError(f"'seeds' must be a non-empty list of integers >= 0, got {seeds!r}",
                         path=path)
    return tuple(dict.fromkeys(seeds))


@dataclass(frozen=True)
class _Steps:
    """``[steps]``: the DC torques as fractions of each point's creep-curve peak torque."""

    fractions_of_peak: tuple[float, ...] | None = checked(None, between(0.0, 1.0, hi_open=True))


def _fractions(doc: dict, path) -> tuple[float, ...] | None:
    return read_table(_Steps, doc.get("steps"), section="steps", path=path).fractions_of_peak


def _recommend(doc: dict, path) -> RecommendOptions:
    """The ``[recommend]`` table (and a top-level ``max_utilisation``), every value checked
    (:func:`torquemod._util.tomlcheck.read_table`): shares in (0, 1), the rest positive."""
    table = doc.get("recommend", {})
    if not isinstance(table, dict):
        raise InputError("[recommend] must be a table", path=path)
    if "max_utilisation" in doc:
        table = {**table, "max_utilisation": doc["max_utilisation"]}
    share = between(0.0, 1.0, lo_open=True)
    return read_table(RecommendOptions, table, section="recommend", path=path,
                      checks=default_checks(RecommendOptions, {
                          "max_utilisation": between(0.0, 1.0, lo_open=True, hi_open=True),
                          "min_coverage": share}))


def _processing(doc: dict, path) -> dict:
    """The ``[processing]`` table (the chain's parameters as an experiment manifest takes
    them, docs/processing.md), checked now so that a typo names the sweep file."""
    table = doc.get("processing", {})
    from torquemod.io.config import ProcessingConfig
    ProcessingConfig.from_dict(table, source=f"{path} [processing]")
    return table


def _base(doc: dict, path, where) -> tuple[Path | None, str]:
    """``(base config path or None, kind)``: ``"rig"`` and ``"train"`` are the packaged
    defaults; a path (relative to the sweep file) is a train config when it says
    ``kind = "train"``, else a rig config."""
    base = doc.get("base", "rig")
    if not isinstance(base, str):
        raise InputError("'base' must be \"rig\", \"train\" or the path of a twin config "
                         "TOML", path=where)
    if base in ("rig", "train"):
        return None, base
    base_path = Path(base)
    if not base_path.is_absolute() and path is not None:
        base_path = Path(path).parent / base_path
    if not base_path.is_file():
        raise InputError(f"base config {base!r} not found", path=where,
                         hint="give \"rig\" (the V-Track default), \"train\" (the default "
                              "train run) or a config TOML (relative to the sweep file)")
    try:
        kind = tomllib.loads(base_path.read_text(encoding="utf-8")).get("kind", "rig")
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"cannot read the base config ({exc})", path=base_path) from None
    kind = "train" if kind == "train" else "rig"
    # every value of the base checked now (the error names the base file and the key), not
    # by each point's worker
    if kind == "train":
        from torquemod.twins.train.params import load_train_config
        load_train_config(base_path)
    else:
        from torquemod.twins.vtrack.simulate import load_config
        load_config(base_path)
    return base_path, kind


def _train_only(doc: dict, mode: str, where) -> None:
    """What a train sweep cannot take: the rig's theory mode, torque steps, chain settings."""
    if mode != "full":
        raise InputError(f"mode {mode!r} is for the rig; a train sweep runs the twin and the "
                         "on-board estimator (mode = \"full\")", path=where)
    for key, instead in (("steps", "controller.probe_levels or controller.probe_depth"),
                         ("processing", "onboard.* keys in [fixed], [grid] or [[point]]")):
        if key in doc:
            raise InputError(f"[{key}] is for the rig; a train sweep does not take it",
                             path=where, hint=f"use {instead}")


_DC_KEY = "procedure.dc_torques_nm"


#: the most points a sweep runs without being told (``max_points``; --max-points, --yes)
MAX_POINTS = 2000


def _count(grid: dict, rows: list, seeds: tuple) -> int:
    """Points of the grid over the listed points and seeds, before duplicates are merged
    (an upper bound, known without building them)."""
    return math.prod(len(v) for v in grid.values()) * max(1, len(rows)) * len(seeds)


def parse_sweep(text: str, *, path: str | Path | None = None,
                max_points: int | None = None) -> SweepSpec:
    """Parse and check a sweep file's text.

    Parameters
    ----------
    text : str
        The TOML text.
    path : str or pathlib.Path or None
        Names the file in errors and anchors a relative ``base``. Default None.
    max_points : int or None
        A sweep of more points is refused before its points are built; None: no limit.

    Returns
    -------
    SweepSpec
        The sweep.

    Raises
    ------
    InputError
        TOML syntax, an unknown mode or key, a bad value, a grid that is not a list, too many
        points, or the DC torques given twice; the message names the file and key.
    """
    where = path if path is not None else "<sweep>"
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"TOML syntax error: {exc}", path=where,
                         hint="fix the line named") from None
    unknown_keys(doc, _TOP_KEYS, "sweep file", where, takes="a sweep takes")
    mode = doc.get("mode", "full")
    if mode not in _MODES:
        raise InputError(f"unknown mode {mode!r}", path=where,
                         hint="use \"full\" (twin + chain + fits) or \"theory\" "
                              "(large-signal theory only)")
    base_path, kind = _base(doc, path, where)
    if kind == "train":
        from torquemod.sweep.trainpoint import train_keys
        _train_only(doc, mode, where)
        allowed = train_keys(base_path)
    else:
        allowed = (*twin_keys(), CONDITION_KEY)
    fixed = _params(doc.get("fixed", {}), "[fixed]", where, allowed)
    for key, value in fixed.items():
        _check_value(key, value, "[fixed]", where, kind)
    grid = _params(doc.get("grid", {}), "[grid]", where, allowed)
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise InputError(f"[grid] '{key}' must be a non-empty list of values", path=where,
                             hint=f"e.g. {key} = [a, b, c]; a single value goes in [fixed]")
        for v in values:
            _check_value(key, v, "[grid]", where, kind)
    listed = doc.get("point", [])
    if not isinstance(listed, list):
        raise InputError("'point' must be an array of tables ([[point]])", path=where)
    rows = [_params(p, f"[[point]] #{i + 1}", where, allowed) for i, p in enumerate(listed)]
    for i, row in enumerate(rows):
        for key, value in row.items():
            _check_value(key, value, f"[[point]] #{i + 1}", where, kind)
    # the grid runs over each listed point (or over the base alone when none is listed)
    seeds = _seeds(doc, where)
    n = _count(grid, rows, seeds)
    if max_points is not None and n > max_points:
        shape = " x ".join([*(str(len(v)) for v in grid.values()),
                            *([f"{len(rows)} [[point]]"] if rows else []),
                            f"{len(seeds)} seed{'s' if len(seeds) > 1 else ''}"])
        raise InputError(f"the sweep has {n} points ({shape}), more than the limit of "
                         f"{max_points}", path=where,
                         hint=f"make the grid smaller, or run it on purpose with "
                              f"--max-points {n} (or --yes)")
    combos = [dict(zip(grid, vals, strict=True)) for vals in itertools.product(*grid.values())]
    bases = rows or [{}]
    points, seen = [], set()
    for row in bases:
        for combo in combos:
            params = {**fixed, **row, **combo}
            for seed in seeds:
                pt = SweepPoint(index=len(points), params=params, seed=seed)
                if pt.point_id not in seen:
                    seen.add(pt.point_id)
                    points.append(pt)
    swept = tuple(dict.fromkeys([*(k for r in rows for k in r), *grid]))
    fr = _fractions(doc, where)
    if fr is not None and any(_DC_KEY in p.params for p in points):
        # [steps] sets every point's DC torques: a given list would be ignored silently
        raise InputError(f"'{_DC_KEY}' is given together with [steps] fractions_of_peak, "
                         "which sets every point's DC torques", path=where,
                         hint=f"drop one of the two: [steps] for fractions of each point's "
                              f"creep-curve peak, {_DC_KEY} for torques in N*m")
    return SweepSpec(path=None if path is None else Path(path), text=text,
                     name=str(doc.get("name", Path(str(where)).stem)),
                     description=str(doc.get("description", "")), base=base_path, mode=mode,
                     seeds=seeds, points=tuple(points), swept=swept, fixed=fixed,
                     fractions_of_peak=fr, recommend=_recommend(doc, where),
                     processing=_processing(doc, where), kind=kind)


def load_sweep(path: str | Path, *, max_points: int | None = None) -> SweepSpec:
    """Read and check ``SWEEP.toml``.

    Parameters
    ----------
    path : str or pathlib.Path
        The sweep file.
    max_points : int or None
        See :func:`parse_sweep`.

    Returns
    -------
    SweepSpec
        The sweep.

    Raises
    ------
    InputError
        The file cannot be read, or :func:`parse_sweep` refuses it.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the sweep file ({exc})", path=path) from None
    return parse_sweep(text, path=path, max_points=max_points)
