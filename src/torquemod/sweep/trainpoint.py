"""A sweep over a train run (``base = "train"`` or a ``kind = "train"`` config): its keys,
the configuration of one point, and the point's rows of the sweep table (one per friction
segment).

Keys (docs/sweep.md): the train configuration's own, by section (``test.*``, ``run.*``,
``vehicle.*``, ``sensors.*``, ``track.*``, ``controller.*``), the on-board estimator's
settings (``onboard.*``, :class:`~torquemod.ontrain.estimator.OnboardConfig`) and sweep-only
keys that reach into the track's segments and the probe legs:

* ``track.condition`` -- a named condition for every segment; ``track.mu0`` (``a_ratio``,
  ``b_s_m``, ``k_a``, ``k_s``) -- one Polach parameter for every segment;
* ``track.segment.N.condition`` / ``track.segment.N.mu0`` ... -- the same for segment N
  (1 = the first along the track);
* ``controller.probe_levels`` -- the levels of every probe leg (fractions of the available
  adhesion); ``controller.probe_depth`` -- the top level, the levels spread evenly from the
  leg's first level to it (the same count); ``controller.probe_step_m`` -- their length.

One point: the twin writes the run into a temporary folder
(:func:`torquemod.twins.train.run_train_simulation`), the on-board estimator reads it back
(:func:`torquemod.ontrain.run.estimate_axle`, no figures), and each window is compared with
the twin's truth at its position (as ``benchmarks/onboard.py`` does). The disturbance the
modulation adds is taken from the twin's true signals: the run integrated once more with the
same seed (identical) and once without the modulation, their difference per modulation
period without a change of the driver's demand (:func:`disturbance`).
"""

from __future__ import annotations

import dataclasses
import math
import shutil
import tempfile
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from torquemod.errors import InputError

__all__ = ["BANDS", "PROBE_KEYS", "TrackStats", "band_name", "disturbance", "evaluate_train_point",
           "segment_rows", "train_config", "train_keys"]

_POLACH = ("mu0", "a_ratio", "b_s_m", "k_a", "k_s")
#: sweep-only keys of the probe legs
PROBE_KEYS = ("controller.probe_levels", "controller.probe_depth", "controller.probe_step_m")
#: utilisation bands (truth: CoA / available adhesion) of the phase and creep-coefficient
#: columns, [lo, hi)
BANDS = ((0.0, 0.3), (0.3, 0.5), (0.5, 0.7), (0.7, 0.85), (0.85, 1.0))
#: the disturbance leaves out the run's first second [s] (the motor torque starts at zero)
STARTUP_S = 1.0
#: the low_adhesion share is counted over the windows at or below this utilisation
LOW_ADHESION_UTILISATION = 0.5


def band_name(band: tuple[float, float]) -> str:
    """The suffix of a utilisation band's columns.

    Parameters
    ----------
    band : tuple of float
        (low, high) utilisation [-].

    Returns
    -------
    str
        e.g. ``"u30_50"``.

    Examples
    --------
    >>> band_name((0.3, 0.5))
    'u30_50'
    """
    return f"u{round(100 * band[0])}_{round(100 * band[1])}"


def base_doc(base: str | Path | None) -> dict:
    """The base train configuration as a TOML document.

    Parameters
    ----------
    base : str or pathlib.Path or None
        The configuration file; None: the packaged default.

    Returns
    -------
    dict
        The parsed TOML.

    Raises
    ------
    InputError
        The file cannot be read.
    """
    from torquemod.twins.train.params import default_train_config_text
    if base is None:
        return tomllib.loads(default_train_config_text())
    try:
        return tomllib.loads(Path(base).read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"cannot read the train configuration ({exc})", path=base) from None


def train_keys(base: str | Path | None = None) -> tuple[str, ...]:
    """Every dotted key a train sweep takes over a base configuration.

    Parameters
    ----------
    base : str or pathlib.Path or None
        The base configuration; None: the packaged default.

    Returns
    -------
    tuple of str
        The keys.
    """
    from torquemod.ontrain.estimator import OnboardConfig
    from torquemod.twins.train.params import (
        ControllerParams,
        TrackParams,
        TrainSensorParams,
        VehicleParams,
    )
    keys = ["test.modulation_frequency_hz", "test.modulation_amplitude_nm",
            "run.initial_speed_m_s", "run.substeps"]
    keys += [f"vehicle.{k}" for k in VehicleParams.__dataclass_fields__]
    keys += [f"sensors.{k}" for k in TrainSensorParams.__dataclass_fields__]
    keys += [f"track.{k}" for k in TrackParams.__dataclass_fields__ if k != "segments"]
    keys += [f"controller.{k}" for k in ControllerParams.__dataclass_fields__ if k != "legs"]
    keys += [f"onboard.{k}" for k in OnboardConfig.__dataclass_fields__]
    keys += ["track.condition", *(f"track.{k}" for k in _POLACH), *PROBE_KEYS]
    n_seg = len(base_doc(base).get("track", {}).get("segment", []))
    for i in range(1, n_seg + 1):
        keys += [f"track.segment.{i}.condition", *(f"track.segment.{i}.{k}" for k in _POLACH)]
    return tuple(keys)


#: the sweep-only keys' checks (a condition's: a known name, checked where it is needed)
_PROBE_CHECKS = {
    "controller.probe_levels": ((tuple, float, None), "e.g. [0.2, 0.4, 0.6, 0.8]; a grid of "
                                "them is a list of lists"),
    "controller.probe_depth": (float, "the top level, a fraction of the available adhesion"),
    "controller.probe_step_m": (float, "the length of each probe level [m]"),
}


def check_train_value(key: str, value, where: str, path) -> None:
    """Check a train sweep's value before any point runs, as the readers check it.

    A condition must be known, probe levels and depth fractions in (0, 1), the probe step
    positive, an ``onboard.*`` value as run.toml's ``[onboard]`` takes it
    (:func:`torquemod._util.tomlcheck.checked_value`); other keys must be a number, a
    string, true/false or a list of numbers (the train reader checks them per point).

    Parameters
    ----------
    key : str
        The dotted key.
    value : object
        Its value.
    where : str
        The sweep's table, named in the message (e.g. "[grid]").
    path : object
        The sweep file, named in the message.

    Raises
    ------
    InputError
        The value is unusable for the key; the message names the file, the table and the
        key.
    """
    from torquemod._util.tomlcheck import POSITIVE, between, checked_value, one_of
    from torquemod.ontrain.estimator import OnboardConfig
    from torquemod.sweep.conditions import conditions
    hint = None
    try:
        if key.endswith(".condition"):
            hint = ("or give the Polach parameters (track.mu0, a_ratio, b_s_m, k_a, k_s)")
            checked_value(value, str, key, None, one_of(*conditions()))
        elif key in _PROBE_CHECKS:
            kind, hint = _PROBE_CHECKS[key]
            check = POSITIVE if key.endswith("step_m") else between(
                0.0, 1.0, lo_open=True, hi_open=True)
            checked_value(value, kind, key, None, check)
        elif key.startswith("onboard."):
            OnboardConfig.from_dict({key.split(".", 1)[1]: value}, source=None)
        elif not (isinstance(value, bool | str) or
                  (isinstance(value, int | float) and math.isfinite(value)) or
                  (isinstance(value, list) and all(isinstance(v, int | float)
                                                   and not isinstance(v, bool)
                                                   for v in value))):
            raise InputError(f"'{key}' has an unusable value {value!r}", hint="give a number, "
                             "a string, true/false or a list of numbers")
    except InputError as exc:
        raise InputError(f"{where}: {exc}", path=path, hint=hint) from None


def _polach_with(pol, values: dict):
    return dataclasses.replace(pol, **values) if values else pol


def train_config(base: str | Path | None, params: dict):
    """The train twin's and the estimator's configuration of a point.

    The base document with the plain keys set (so the train reader checks them), then the
    sweep-only segment and probe keys.

    Parameters
    ----------
    base : str or pathlib.Path or None
        The base configuration; None: the packaged default.
    params : dict
        The point's parameters (dotted keys).

    Returns
    -------
    config : TrainConfig
        The twin's configuration.
    onboard : OnboardConfig
        The estimator's settings.

    Raises
    ------
    InputError
        A bad key or value.
    """
    from torquemod.ontrain.estimator import OnboardConfig
    from torquemod.sweep.conditions import conditions
    from torquemod.twins.train.params import config_from_dict
    doc = base_doc(base)
    doc.pop("onboard", None)
    onboard, special = {}, {}
    for key, value in params.items():
        section, name = key.split(".", 1)
        if section == "onboard":
            onboard[name] = value
        elif key in PROBE_KEYS or name == "condition" or name in _POLACH or "." in name:
            special[key] = value
        else:
            doc.setdefault(section, {})[name] = value
    where = f"train sweep point {params}"
    cfg = config_from_dict(doc, where=str(base) if base else "train_default.toml")
    # segments: every segment first, then each named one; a Polach key wins over a condition
    segs = list(cfg.track.segments)
    known = conditions()

    def apply(i: int, prefix: str) -> None:
        cond = special.get(f"{prefix}condition")
        if cond is not None:
            segs[i] = dataclasses.replace(segs[i], condition=cond, polach=known[cond])
        vals = {k: float(special[f"{prefix}{k}"]) for k in _POLACH if f"{prefix}{k}" in special}
        segs[i] = dataclasses.replace(segs[i], polach=_polach_with(segs[i].polach, vals))

    for i in range(len(segs)):
        apply(i, "track.")
    for i in range(len(segs)):
        apply(i, f"track.segment.{i + 1}.")
    legs = []
    for leg in cfg.controller.legs:
        if leg.mode == "probe":
            levels = tuple(float(v) for v in special.get("controller.probe_levels", leg.levels))
            if "controller.probe_depth" in special and levels:
                levels = tuple(np.linspace(levels[0], float(special["controller.probe_depth"]),
                                           len(levels)).tolist())
            leg = dataclasses.replace(leg, levels=levels, step_m=float(
                special.get("controller.probe_step_m", leg.step_m)))
        legs.append(leg)
    cfg = dataclasses.replace(
        cfg, track=dataclasses.replace(cfg.track, segments=tuple(segs)),
        controller=dataclasses.replace(cfg.controller, legs=tuple(legs)))
    return cfg, OnboardConfig.from_dict(onboard, source=where)


# ------------------------------------------------------------------------- evaluation

def _median(x) -> float:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.median(x)) if x.size else math.nan


def disturbance(raw: np.ndarray, raw0: np.ndarray, cfg) -> pd.DataFrame:
    """What the modulation adds, per modulation period of the twin's true signals.

    ``raw`` and ``raw0`` are the same run (seed, irregularity) with and without the
    modulation, so that the track irregularity's own creepage variation cancels. Periods
    where the driver's demand changed or the anti-slip control acted in either run, and the
    first :data:`STARTUP_S`, are left out.

    Parameters
    ----------
    raw : ndarray
        The run's true signals (:data:`torquemod.twins.train.dynamics.OUT` columns).
    raw0 : ndarray
        The same run without the modulation.
    cfg : TrainConfig
        The twin's configuration.

    Returns
    -------
    pandas.DataFrame
        Per period: position [m], segment index (0-based), the creepage swing (half the
        peak-to-peak of the creepage difference) [-], the motor torque's modulation amplitude
        (half the peak-to-peak of the torque difference) [N*m], the mean torque (DC) [N*m]
        and the torque ripple, amplitude/|DC| [%].
    """
    fs = cfg.sensors.sample_rate_hz
    m = max(2, round(fs / cfg.modulation_frequency_hz))
    nb = min(raw.shape[0], raw0.shape[0]) // m
    blk = raw[:nb * m].reshape(nb, m, raw.shape[1])
    blk0 = raw0[:nb * m].reshape(nb, m, raw0.shape[1])
    steady = np.ones(nb, dtype=bool)
    for b in (blk, blk0):
        steady &= np.ptp(b[:, :, 11], axis=1) == 0.0  # the demand did not change
        steady &= b[:, :, 10].min(axis=1) >= 1.0  # nor did the anti-slip control cut it
    steady &= blk[:, 0, 0] >= STARTUP_S  # the motor torque starts from zero
    blk, blk0 = blk[steady], blk0[steady]
    amp = 0.5 * np.ptp(blk[:, :, 1] - blk0[:, :, 1], axis=1)
    dc = blk[:, :, 1].mean(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ripple = np.where(np.abs(dc) > 0, 100.0 * amp / np.abs(dc), np.inf)
    return pd.DataFrame({"position_m": blk[:, :, 5].mean(axis=1),
                         "segment": np.round(blk[:, :, 12].mean(axis=1)).astype(int),
                         "creepage_swing": 0.5 * np.ptp(blk[:, :, 8] - blk0[:, :, 8], axis=1),
                         "torque_amplitude_nm": amp, "dc_torque_nm": dc,
                         "torque_ripple_pct": ripple})


@dataclass(frozen=True)
class TrackStats:
    """The windows of one run beside the truth at their positions.

    Attributes
    ----------
    segment : ndarray of int
        The friction segment of each window (0-based).
    mu_true : ndarray
        The truth's available adhesion there [-].
    utilisation : ndarray
        The truth's utilisation there [-].
    """

    segment: np.ndarray
    mu_true: np.ndarray
    utilisation: np.ndarray


def truth_at_windows(track: pd.DataFrame, truth: pd.DataFrame, starts) -> TrackStats:
    """The truth interpolated to each window's centre.

    Parameters
    ----------
    track : pandas.DataFrame
        The estimator's track (``position_m``).
    truth : pandas.DataFrame
        The truth table.
    starts : array_like
        The windows' first rows.

    Returns
    -------
    TrackStats
        ``mu_true`` is the available adhesion (the creep curve's peak, ``adhesion_peak``),
        which the estimator's ``mu`` estimates (the friction at the slip velocity, ``mu``,
        for truth tables without it).
    """
    x = track["position_m"].to_numpy(float)
    tx = truth["position_m"].to_numpy(float)
    seg = np.clip(np.searchsorted(np.asarray(starts, float), x, side="right") - 1, 0,
                  len(starts) - 1)
    col = "adhesion_peak" if "adhesion_peak" in truth else "mu"
    return TrackStats(seg, np.interp(x, tx, truth[col].to_numpy(float)),
                      np.interp(x, tx, truth["utilisation"].to_numpy(float)))


def segment_rows(track: pd.DataFrame, truth: pd.DataFrame, cfg, onboard_cfg,
                 dist: pd.DataFrame | None = None, *, max_error: float = 0.10) -> list[dict]:
    """One row per friction segment the run reached: the estimator's windows against the truth.

    Parameters
    ----------
    track : pandas.DataFrame
        The estimator's track.
    truth : pandas.DataFrame
        The truth table.
    cfg : TrainConfig
        The twin's configuration.
    onboard_cfg : OnboardConfig
        The estimator's settings.
    dist : pandas.DataFrame or None
        The modulation's disturbance per period (:func:`disturbance`). Default None.
    max_error : float
        A mu row counts when its relative error is within this [-]. Default 0.10.

    Returns
    -------
    list of dict
        The rows (docs/sweep.md for the columns).
    """
    segs = cfg.track.segments
    starts = [s.start_m for s in segs]
    ts = truth_at_windows(track, truth, starts)
    mu = track["mu"].to_numpy(float)
    lo = track["mu_low_95"].to_numpy(float)
    hi = track["mu_high_95"].to_numpy(float)
    steady = ((track["dc_step_ratio"].to_numpy(float) <= onboard_cfg.max_dc_step_ratio)
              & ~track["slip"].to_numpy(bool)) if "dc_step_ratio" in track else \
        ~track["slip"].to_numpy(bool)
    rows = []
    for j in np.unique(ts.segment):
        sel = ts.segment == j
        s = segs[j]
        end = segs[j + 1].start_m if j + 1 < len(segs) else cfg.track.length_m
        mt, given = ts.mu_true[sel], np.isfinite(mu[sel])
        err = np.abs(mu[sel][given] / mt[given] - 1.0)
        cov = (lo[sel][given] <= mt[given]) & (mt[given] <= hi[sel][given])
        bound = ~given & np.isfinite(lo[sel])
        util = ts.utilisation[sel]
        low_u = util <= LOW_ADHESION_UTILISATION
        row = {"segment": int(j) + 1, "condition": s.condition, "start_m": float(s.start_m),
               "end_m": float(min(end, cfg.track.length_m)),
               **{f"seg_{k}": float(getattr(s.polach, k)) for k in _POLACH},
               "mu_true_median": _median(mt),
               "n_windows": int(sel.sum()), "n_mu": int(given.sum()),
               "mu_given_share": float(given.mean()),
               "mu_error_median": _median(err),
               "n_mu_within_error": int((err <= max_error).sum()),
               "n_mu_covered": int(cov.sum()),
               "coverage_95": float(cov.mean()) if given.any() else math.nan,
               "n_lower_bound": int(bound.sum()),
               "lower_bound_above_truth_share": float(
                   (lo[sel][bound] > mt[bound]).mean()) if bound.any() else math.nan,
               "utilisation_max": float(np.nanmax(util)) if util.size else math.nan,
               "n_low_utilisation": int(low_u.sum()),
               "low_adhesion_share_u50": float(track["low_adhesion"].to_numpy(bool)[sel][
                   low_u].mean()) if low_u.any() else math.nan,
               "slip_share": float(track["slip"].to_numpy(bool)[sel].mean())}
        for band in BANDS:
            b = sel & steady & (ts.utilisation >= band[0]) & (ts.utilisation < band[1])
            name = band_name(band)
            row[f"n_windows_{name}"] = int(b.sum())
            row[f"phase_deg_{name}"] = _median(track["phase_deg"].to_numpy(float)[b])
            row[f"creep_coefficient_{name}"] = _median(
                track["creep_coefficient"].to_numpy(float)[b])
            tb = truth["utilisation"].between(*band, inclusive="left") & np.isin(
                np.clip(np.searchsorted(starts, truth["position_m"], side="right") - 1, 0,
                        len(starts) - 1), [j])
            row[f"creep_coefficient_true_{name}"] = _median(truth.loc[tb, "creep_coefficient"])
        if dist is not None:
            d = dist[dist["segment"] == j]
            row.update(creepage_swing_median=_median(d["creepage_swing"]),
                       creepage_swing_max=float(d["creepage_swing"].max()) if len(d)
                       else math.nan,
                       torque_amplitude_nm=_median(d["torque_amplitude_nm"]),
                       torque_ripple_pct_median=_median(d["torque_ripple_pct"]),
                       torque_ripple_pct_max=float(d["torque_ripple_pct"].max()) if len(d)
                       else math.nan)
        rows.append(row)
    return rows


def point_info(cfg) -> dict:
    """The point's setting and vehicle, repeated on each of its rows.

    Parameters
    ----------
    cfg : TrainConfig
        The twin's configuration.

    Returns
    -------
    dict
        Modulation frequency [Hz] (actual and nominal), amplitude [N*m], probe depth [-]
        and step [m], speed [m/s], normal load [N], wheel radius [m], inertia [kg*m^2] and
        track length [m].
    """
    probe = [leg for leg in cfg.controller.legs if leg.mode == "probe"]
    levels = [v for leg in probe for v in leg.levels]
    return {"modulation_frequency_hz": cfg.modulation_frequency_hz,
            "modulation_frequency_nominal_hz": cfg.modulation_frequency_hz,
            "modulation_amplitude_nm": cfg.modulation_amplitude_nm,
            "probe_depth": max(levels) if levels else math.nan,
            "probe_step_m": probe[0].step_m if probe else math.nan,
            "speed_m_s": cfg.initial_speed_m_s, "normal_load_n": cfg.vehicle.normal_load_n,
            "wheel_radius_m": cfg.vehicle.wheel_radius_m,
            "inertia_kg_m2": cfg.vehicle.inertia_kg_m2, "track_length_m": cfg.track.length_m}


def evaluate_train_point(task, *, workdir: str | Path | None = None) -> pd.DataFrame:
    """The rows of one train point: twin -> run folder -> on-board estimator -> segment rows.

    Parameters
    ----------
    task : PointTask
        The point (``kind = "train"``).
    workdir : str or pathlib.Path or None
        Where the run's temporary folder is made; None: the system's temporary folder.

    Returns
    -------
    pandas.DataFrame
        One row per friction segment reached.

    Raises
    ------
    InputError
        A bad parameter, or the train twin failed.
    """
    from torquemod.io.run import read_run
    from torquemod.ontrain.run import estimate_axle
    from torquemod.twins.train import integrate_run, run_train_simulation
    t0 = time.perf_counter()
    cfg, onboard_cfg = train_config(task.base, task.params)
    tmp = Path(tempfile.mkdtemp(prefix=f"sweep-{task.point_id}-", dir=workdir))
    try:
        try:
            sim = run_train_simulation(cfg, tmp / "run", seed=task.seed)
        except RuntimeError as exc:  # the twin diverged or the train stopped
            raise InputError(f"the train twin failed: {exc}") from None
        run = read_run(tmp / "run" / "run.toml")
        res = estimate_axle(run, run.recordings[0], onboard_cfg)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    quiet = dataclasses.replace(cfg, modulation_amplitude_nm=0.0)
    dist = disturbance(integrate_run(cfg, seed=task.seed), integrate_run(quiet, seed=task.seed),
                       cfg)
    rows = segment_rows(res.track, res.truth, cfg, onboard_cfg, dist,
                        max_error=task.max_mu_error)
    df = pd.DataFrame(rows)
    head = {"point_id": task.point_id, "point_index": task.index, **task.params,
            "seed": task.seed, "kind": "train", "mode": task.mode}
    for key, value in reversed(list(head.items())):
        df.insert(0, key, [value] * len(df) if isinstance(value, list) else value)
    info = {**point_info(cfg), "n_windows_run": len(res.track),
            "run_duration_s": sim["duration_s"], "antislip_share": sim["antislip_share"],
            "point_wall_s": time.perf_counter() - t0}
    for key, value in info.items():
        df[key] = value
    return df
