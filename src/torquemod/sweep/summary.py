"""From the sweep table to per-point figures of merit and the recommendation.

Per point (:func:`point_summary`): the sensitivity ``dphi/du`` (slope of a straight line
through the phase against the utilisation over the steps in the band 50-80 %), the error of
mu from the phase against the available adhesion (the peak of the twin's adhesion-creepage
curve at the operating speed, ``mu_true``; Polach (2005) Eqs. 1-9), the disturbance the
modulation adds below the utilisation limit (largest creepage swing amplitude, largest
torque ripple in % of the saturation torque) and the largest twin-minus-theory phase
difference.

The recommendation (:func:`recommend`) is computed from those, never stated in advance: among
the modulation settings (frequency x amplitude) whose disturbance stays within the limits of
``[recommend]``, the one with the smallest RMS mu-from-phase error over the other swept
parameters (conditions, speeds, seeds, ...). The error of a point whose mu is not determined
is that of the lower bound the fit does give (what the method tells the user), or 100 %
when the fit gave nothing.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from torquemod.sweep.conditions import CONDITION_COLUMN, condition_labels, short_name
from torquemod.sweep.spec import SweepSpec

__all__ = ["BAND", "agreement", "point_summary", "recommend", "setting_table", "slipped_mask"]

#: utilisation band of the sensitivity dphi/du [-]
BAND = (0.5, 0.8)
#: a modulation setting: nominal frequency [Hz] and motor-torque amplitude [N*m]
SETTING = ("modulation_frequency_nominal_hz", "modulation_amplitude_nm")


def _slope(u: np.ndarray, phi: np.ndarray) -> float:
    ok = np.isfinite(u) & np.isfinite(phi) & (u >= BAND[0] - 1e-9) & (u <= BAND[1] + 1e-9)
    if ok.sum() < 2 or np.ptp(u[ok]) <= 0:
        return math.nan
    return float(np.polyfit(u[ok], phi[ok], 1)[0]) / 100.0  # deg per % of utilisation


def agreement(table: pd.DataFrame) -> dict:
    """How the twin and the chain agree with the large-signal theory.

    Over every step that did not slip (:func:`slipped_mask`).

    Parameters
    ----------
    table : pandas.DataFrame
        The sweep table (``sweep.parquet``: one row per point and step).

    Returns
    -------
    dict
        ``n_steps``; ``twin_minus_theory_max_deg`` and ``twin_minus_theory_median_deg``, the
        largest and median |twin - theory| phase [deg] (full mode; None otherwise); the
        chain's |phase - theory| / standard error ``chain_z_median`` and ``chain_z_max`` [-].
    """
    live = table[~slipped_mask(table)]
    d = live["phase_twin_minus_theory_deg"].abs().dropna()
    z = ((live["phase_deg"] - live["phase_theory_deg"]) / live["phase_se_deg"]).abs().dropna()
    return {"n_steps": len(live),
            "twin_minus_theory_max_deg": float(d.max()) if len(d) else None,
            "twin_minus_theory_median_deg": float(d.median()) if len(d) else None,
            "chain_z_median": float(z.median()) if len(z) else None,
            "chain_z_max": float(z.max()) if len(z) else None}


def slipped_mask(g: pd.DataFrame) -> pd.Series:
    """Steps where the wheel slipped.

    In the theory (no periodic state under the modulation) or, in full mode, in the twin.

    Parameters
    ----------
    g : pandas.DataFrame
        Rows of the sweep table.

    Returns
    -------
    pandas.Series of bool
        True where the step slipped (same index).
    """
    out = g["slipped"].eq(True)
    if "slipped_twin" in g:
        out |= g["slipped_twin"].eq(True)
    return out


def effective_error(mu_phase, lo, mu_true, determined) -> float:
    """The error of mu from the phase as the method tells it to the user.

    Parameters
    ----------
    mu_phase : float
        mu from the phase [-] (NaN when the fit gave nothing).
    lo : float
        The lower bound the fit gives [-].
    mu_true : float
        The available adhesion of the twin [-].
    determined : bool
        mu is determined.

    Returns
    -------
    float
        |mu/mu_true - 1| [-] when determined, else that of the lower bound, else 1 (100 %).

    Examples
    --------
    >>> round(effective_error(0.33, 0.3, 0.30, True), 12)
    0.1
    >>> effective_error(float("nan"), float("nan"), 0.30, False)
    1.0
    """
    value = mu_phase if determined else lo
    if value is None or not np.isfinite(value):
        return 1.0
    return abs(float(value) / float(mu_true) - 1.0)


def point_summary(table: pd.DataFrame, spec: SweepSpec) -> pd.DataFrame:
    """One row per point: its figures of merit.

    Its swept parameters, seed, setting, the sensitivity dphi/du (slope of a straight line
    through the phase against the utilisation over the steps in the band 50-80 %), the error
    of mu from the phase against the available adhesion (the peak of the twin's
    adhesion-creepage curve at the operating speed [1]_), the disturbances below the
    utilisation limit (largest creepage swing amplitude, largest torque ripple in % of the
    saturation torque) and the twin-vs-theory phase difference.

    Parameters
    ----------
    table : pandas.DataFrame
        The sweep table (``sweep.parquet``: one row per point and step).
    spec : SweepSpec
        The sweep's specification (swept keys, ``[recommend]`` limits).

    Returns
    -------
    pandas.DataFrame
        Sorted by ``point_index``.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (1)-(9).
    """
    lim = spec.recommend.max_utilisation
    labels = condition_labels(table, spec.swept)
    rows = []
    for pid, g in table.groupby("point_id", sort=False):
        first = g.iloc[0]
        slipped = slipped_mask(g)
        live = g[~slipped]
        theory = g[~g["slipped"].eq(True)]  # the theory's steps (the twin may slip earlier)
        below = live[live["utilisation"] <= lim + 1e-9]
        u = live["utilisation"].to_numpy(float)
        row = {"point_id": pid, "point_index": int(first["point_index"]),
               CONDITION_COLUMN: labels.loc[g.index[0]],
               **{k: first.get(k) for k in spec.swept}, "seed": int(first["seed"]),
               **{k: float(first[k]) for k in SETTING},
               "mu_true": float(first["mu_true"]),
               "mu_phase": float(first["mu_phase"]), "mu_phase_lo": float(first["mu_phase_lo"]),
               "mu_phase_hi": float(first["mu_phase_hi"]),
               "mu_phase_determined": bool(first["mu_phase_determined"]),
               "dphi_du_theory": _slope(theory["utilisation"].to_numpy(float),
                                        theory["phase_theory_deg"].to_numpy(float)),
               "dphi_du_chain": _slope(u, live["phase_deg"].to_numpy(float)),
               "creepage_swing_max": float(below["creepage_swing"].max()),
               "torque_ripple_pct_max": float(below["torque_ripple_pct"].max()),
               "phase_se_median_deg": float(np.nanmedian(
                   below["phase_se_deg"] if below["phase_se_deg"].notna().any()
                   else below["phase_crlb_deg"])) if len(below) else math.nan,
               "twin_minus_theory_max_deg": float(np.nanmax(np.abs(
                   live["phase_twin_minus_theory_deg"])))
               if live["phase_twin_minus_theory_deg"].notna().any() else math.nan,
               "n_steps": len(live), "slipped_at_step": (
                   int(g.loc[slipped, "step"].min()) if slipped.any() else None)}
        if "mu_forces" in g:
            row.update(mu_forces=float(first["mu_forces"]),
                       mu_forces_determined=bool(first["mu_forces_determined"]))
        # mu from the phase is judged against the available adhesion, the peak of the
        # twin's adhesion-creepage curve at the operating speed (mu_true); the friction at
        # the top step's slip velocity is kept for reference
        truth = row["mu_true"]
        if "mu_friction" in g:
            row["mu_friction"] = float(first["mu_friction"])
        row["mu_phase_error_pct"] = 100.0 * (row["mu_phase"] / truth - 1.0)
        row["mu_phase_lo_error_pct"] = 100.0 * (row["mu_phase_lo"] / truth - 1.0)
        row["mu_phase_hi_error_pct"] = 100.0 * (row["mu_phase_hi"] / truth - 1.0)
        row["effective_error_pct"] = 100.0 * effective_error(
            row["mu_phase"], row["mu_phase_lo"], truth, row["mu_phase_determined"])
        # the truth inside the 95 % interval (determined) or not below the lower bound
        lo, hi = row["mu_phase_lo"], row["mu_phase_hi"]
        row["covered"] = bool(np.isfinite(lo) and lo <= truth
                              and (not row["mu_phase_determined"] or truth <= hi))
        rows.append(row)
    return pd.DataFrame(rows).sort_values("point_index", ignore_index=True)


def setting_table(summary: pd.DataFrame, spec: SweepSpec) -> pd.DataFrame:
    """One row per modulation setting (frequency x amplitude).

    Parameters
    ----------
    summary : pandas.DataFrame
        The point summary (:func:`point_summary`).
    spec : SweepSpec
        The sweep's specification (swept keys, ``[recommend]`` limits).

    Returns
    -------
    pandas.DataFrame
        Points, mu-from-phase determined, RMS and largest effective error [%], mean
        sensitivity [deg/%], largest creepage swing [-] and torque ripple [%] below the
        utilisation limit, and whether those stay within the limits.
    """
    opts = spec.recommend
    rows = []
    for (f, a), g in summary.groupby(list(SETTING), sort=True):
        err = g["effective_error_pct"].to_numpy(float)
        sens = g["dphi_du_theory"].to_numpy(float)
        swing, ripple = float(g["creepage_swing_max"].max()), float(
            g["torque_ripple_pct_max"].max())
        det = g[g["mu_phase_determined"]]
        rows.append({"modulation_frequency_nominal_hz": f, "modulation_amplitude_nm": a,
                     "n_points": len(g), "n_determined": len(det),
                     "n_covered": int(g["covered"].sum()),
                     "bias_pct": float(det["mu_phase_error_pct"].mean()) if len(det)
                     else math.nan,
                     "rms_error_pct": float(np.sqrt(np.mean(err**2))),
                     "max_error_pct": float(np.max(err)),
                     "dphi_du_mean": float(np.nanmean(sens)) if np.isfinite(sens).any()
                     else math.nan,
                     "creepage_swing_max": swing, "torque_ripple_pct_max": ripple,
                     "phase_se_median_deg": float(np.nanmedian(g["phase_se_median_deg"])),
                     "within_limits": bool(swing <= opts.max_creepage_swing
                                           and ripple <= opts.max_torque_ripple_pct)})
    return pd.DataFrame(rows)


def _name(row) -> str:
    return (f"{row['modulation_frequency_nominal_hz']:.4g} Hz, "
            f"{row['modulation_amplitude_nm']:.4g} N*m")


def noise_keys(spec: SweepSpec) -> list[str]:
    """The swept keys that set the noise level (``sensors.*``, ``disturbances.*``).

    Parameters
    ----------
    spec : SweepSpec
        The sweep's specification (swept keys, ``[recommend]`` limits).

    Returns
    -------
    list of str
        The keys, in the sweep's order.
    """
    return [k for k in spec.swept if k.startswith(("sensors.", "disturbances."))]


def recommend(table: pd.DataFrame, spec: SweepSpec, *,
              summary: pd.DataFrame | None = None) -> dict:
    """The modulation setting that gives the most accurate mu from the phase, and why.

    Among the settings whose disturbance stays within the limits of ``[recommend]``, the one
    with the smallest RMS effective error (:func:`effective_error`) over the other swept
    parameters, below the utilisation limit. Computed from the sweep, never stated in
    advance.

    Parameters
    ----------
    table : pandas.DataFrame
        The sweep table (``sweep.parquet``: one row per point and step).
    spec : SweepSpec
        The sweep's specification (swept keys, ``[recommend]`` limits).
    summary : pandas.DataFrame or None
        :func:`point_summary` of ``table`` when the caller has it. Default None
        (computed here).

    Returns
    -------
    dict
        JSON-ready: ``setting``, ``reasoning`` text, ``settings`` table, ``limits``. When the
        sweep varies the noise (:func:`noise_keys`), one recommendation per noise level in
        ``by_noise`` (``noise``, ``setting``, ``reasoning``, ``settings``); the top level then
        holds the first level's, and the reasoning all of them.
    """
    summary = point_summary(table, spec) if summary is None else summary
    keys = noise_keys(spec)
    if not keys:
        return _recommend(summary, spec)
    groups = []
    for value, g in summary.groupby(keys, sort=False):
        value = value if isinstance(value, tuple) else (value,)
        noise = dict(zip(keys, (v.item() if hasattr(v, "item") else v for v in value),
                         strict=True))
        groups.append({"noise": noise, **_recommend(g, spec)})
    doc = {k: groups[0][k] for k in ("limits", "settings", "setting")}
    doc["by_noise"] = groups
    doc["reasoning"] = " ".join(
        "At " + ", ".join(f"{k} = {v}" for k, v in grp["noise"].items()) + ": "
        + grp["reasoning"] for grp in groups)
    return doc


def _recommend(summary: pd.DataFrame, spec: SweepSpec) -> dict:
    opts = spec.recommend
    settings = setting_table(summary, spec)
    limits = {"max_utilisation": opts.max_utilisation,
              "max_creepage_swing": opts.max_creepage_swing,
              "max_torque_ripple_pct": opts.max_torque_ripple_pct}
    doc = {"limits": limits, "settings": settings.to_dict(orient="records"), "setting": None}
    others = [k for k in spec.swept if k not in ("modulation.frequency_hz",
                                                 "modulation.amplitude_nm",
                                                 *noise_keys(spec))]
    per = int(settings["n_points"].max()) if len(settings) else 0
    varying = []
    if others:
        n_cond = summary[CONDITION_COLUMN].nunique()
        varying.append(f"{n_cond} condition{'s' if n_cond != 1 else ''} of "
                       + ", ".join(short_name(k) or "friction condition" for k in others))
    if len(spec.seeds) > 1:
        varying.append(f"{len(spec.seeds)} seeds")
    over = (f"each over its {per} points ({'; '.join(varying)})" if varying
            else f"each over its {per} point(s)")
    if len(settings) < 2:
        doc["reasoning"] = ("The sweep varies no modulation setting (one frequency and "
                            "amplitude), so there is nothing to choose between; sweep "
                            "modulation.frequency_hz and/or modulation.amplitude_nm.")
        if len(settings):
            doc["setting"] = settings.iloc[0][list(SETTING)].to_dict()
        return doc
    ok = settings[settings["within_limits"]]
    pool = ok if len(ok) else settings
    ranked = pool.sort_values(["rms_error_pct", "torque_ripple_pct_max",
                               "creepage_swing_max"], ignore_index=True)
    best = ranked.iloc[0]
    doc["setting"] = {k: float(best[k]) for k in SETTING}
    lines = [f"Compared {len(settings)} modulation settings {over}, using mu from the phase "
             f"fitted to the steps at or below {opts.max_utilisation:.0%} utilisation."]
    if len(ok):
        excluded = settings[~settings["within_limits"]]
        keep = "keeps" if len(ok) == 1 else "keep"
        lines.append(f"{len(ok)} of them {keep} the disturbance small below that utilisation "
                     f"(creepage swing amplitude <= {opts.max_creepage_swing:.3g}, torque "
                     f"ripple <= {opts.max_torque_ripple_pct:.3g} % of the saturation "
                     "torque)" + (": excluded " + "; ".join(
                         f"{_name(r)} (swing {r['creepage_swing_max']:.3g}, ripple "
                         f"{r['torque_ripple_pct_max']:.3g} %)"
                         for _, r in excluded.iterrows()) if len(excluded) else "") + ".")
    else:
        lines.append("No setting keeps the disturbance within the limits (creepage swing "
                     f"<= {opts.max_creepage_swing:.3g}, torque ripple <= "
                     f"{opts.max_torque_ripple_pct:.3g} %): the recommended one is the most "
                     "accurate regardless, and its disturbance must be accepted or the "
                     "limits relaxed.")
        doc["within_limits"] = False
    lines.insert(0, f"Recommended: {_name(best)}.")
    lines.append(
        f"Why {_name(best)}: its RMS mu-from-phase error is "
        f"{best['rms_error_pct']:.2f} % (largest {best['max_error_pct']:.2f} %), mu determined "
        f"in {int(best['n_determined'])} of {int(best['n_points'])} points (elsewhere the "
        f"error is that of the lower bound), sensitivity dphi/du "
        f"{best['dphi_du_mean']:.3g} deg per % utilisation in {BAND[0]:.0%}-{BAND[1]:.0%}, "
        f"the truth inside the 95 % interval (or above the lower bound) in "
        f"{int(best['n_covered'])} of {int(best['n_points'])}, "
        f"median phase standard error {best['phase_se_median_deg']:.3g} deg; it adds a "
        f"creepage swing of at most {best['creepage_swing_max']:.3g} and a torque ripple of "
        f"at most {best['torque_ripple_pct_max']:.3g} % of the saturation torque.")
    if len(ranked) > 1:
        nxt = ranked.iloc[1]
        lines.append(f"Next best: {_name(nxt)} ({nxt['rms_error_pct']:.2f} % RMS, swing "
                     f"{nxt['creepage_swing_max']:.3g}, ripple "
                     f"{nxt['torque_ripple_pct_max']:.3g} %).")
    bias = settings["bias_pct"].to_numpy(float)
    if np.isfinite(bias).any():
        lines.append(f"Where mu is determined its mean signed error is {np.nanmin(bias):+.1f} "
                     f"to {np.nanmax(bias):+.1f} % across the settings, against the available "
                     "adhesion (the peak of the twin's creep curve at the operating speed). "
                     "A fit with constant friction estimates the friction at the slip "
                     "velocity of its highest step, which lies above that peak where friction "
                     "falls with slip.")
    bad = summary[~summary["covered"]]
    if len(bad):
        lines.append(f"{len(bad)} of {len(summary)} points have the true mu outside the 95 % "
                     "interval or below the reported lower bound (see the points table): "
                     "there the phase model does not describe the measurement.")
    lines.append("The recommendation holds for the base rig" + (
        " at this noise level" if noise_keys(spec) else " at its configured sensor noise")
        + "; a train needs its own sweep (base = its config).")
    doc["reasoning"] = " ".join(lines)
    return doc
