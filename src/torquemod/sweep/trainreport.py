"""A train sweep's summary, recommendation, figures and report (the table: one row per
point and friction segment, :mod:`torquemod.sweep.trainpoint`).

The recommendation (:func:`recommend_train`) is computed from the table: per modulation
setting (frequency x amplitude), pooled over every point and segment (conditions, probe
depths, seeds, ...), the rows with mu, the rows whose mu is within ``max_mu_error`` of the
truth, the coverage of the 95 % intervals where mu is given, and the disturbance: the twin's
creepage swing (largest over the periods of a constant demand) and its torque ripple
relative to the DC torque (the median over those periods, pooled as the median of the
segments' medians: at the probe's lowest level on low-friction rail the ripple is many
times its typical value, whatever the setting). A setting qualifies when its coverage
reaches ``min_coverage``, at least half of its mu rows are within ``max_mu_error`` (the
pooled median error within it) and its disturbance stays within the limits; among those,
the most rows with mu within the error bound per window of the run wins (ties: the smaller
ripple, then swing). When none qualifies the report says why and names the best anyway.
"""

from __future__ import annotations

import io
import math
from html import escape
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from torquemod._util.fsutil import write_atomic
from torquemod._version import __version__
from torquemod.report.figures import figure_of
from torquemod.report.html import CSS, figure_html, table
from torquemod.sweep.report import reasoning_html, save_png
from torquemod.sweep.spec import SweepSpec
from torquemod.sweep.trainpoint import BANDS, band_name

__all__ = ["condition_table", "make_train_figures", "noise_keys", "recommend_train",
           "setting_summary", "write_train_report"]

SETTING = ("modulation_frequency_nominal_hz", "modulation_amplitude_nm")
#: the derived column a swept probe key is plotted against
_X_COLUMN = {"controller.probe_levels": "probe_depth", "controller.probe_depth": "probe_depth"}


def _pool(g: pd.DataFrame) -> dict:
    """Pooled figures of a group of (point, segment) rows."""
    n_win, n_mu = int(g["n_windows"].sum()), int(g["n_mu"].sum())
    n_ok, n_cov = int(g["n_mu_within_error"].sum()), int(g["n_mu_covered"].sum())
    n_lb = g["n_lower_bound"].to_numpy(float)
    lb_bad = g["lower_bound_above_truth_share"].fillna(0).to_numpy(float)
    med = g["mu_error_median"].to_numpy(float)
    w = g["n_mu"].to_numpy(float)
    return {"n_points": int(g["point_id"].nunique()), "n_windows": n_win, "n_mu": n_mu,
            "mu_given_share": n_mu / n_win if n_win else math.nan,
            "n_mu_within_error": n_ok,
            "good_share": n_ok / n_win if n_win else math.nan,
            "within_error_share": n_ok / n_mu if n_mu else math.nan,
            "mu_error_median_mean": float(np.sum(np.nan_to_num(med) * w) / w.sum())
            if w.sum() else math.nan,
            "coverage_95": n_cov / n_mu if n_mu else math.nan,
            "lower_bound_above_truth_share": float(np.sum(lb_bad * n_lb) / n_lb.sum())
            if n_lb.sum() else math.nan,
            "creepage_swing_max": float(g["creepage_swing_max"].max()),
            "torque_ripple_pct_max": float(g["torque_ripple_pct_max"].max()),
            "torque_ripple_pct_median": float(g["torque_ripple_pct_median"].median())}


def setting_summary(table: pd.DataFrame, spec: SweepSpec) -> pd.DataFrame:
    """One row per modulation setting: the pooled figures and whether it qualifies.

    Parameters
    ----------
    table : pandas.DataFrame
        The train sweep table (one row per point and friction segment).
    spec : SweepSpec
        The sweep's specification.

    Returns
    -------
    pandas.DataFrame
        Points, windows, rows with mu, shares within ``max_mu_error`` [-], coverage [-],
        creepage swing [-] and torque ripple [%], and ``qualifies``.
    """
    opts = spec.recommend
    rows = []
    for (f, a), g in table.groupby(list(SETTING), sort=True):
        row = {"modulation_frequency_nominal_hz": float(f), "modulation_amplitude_nm": float(a),
               **_pool(g)}
        row["within_limits"] = bool(row["creepage_swing_max"] <= opts.max_creepage_swing
                                    and row["torque_ripple_pct_median"]
                                    <= opts.max_torque_ripple_dc_pct)
        row["accurate"] = bool(row["n_mu"] > 0 and row["coverage_95"] >= opts.min_coverage
                               and row["within_error_share"] >= 0.5)
        row["qualifies"] = row["within_limits"] and row["accurate"]
        rows.append(row)
    return pd.DataFrame(rows)


def condition_table(table: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """Pooled figures per value of some columns.

    Parameters
    ----------
    table : pandas.DataFrame
        The train sweep table (one row per point and friction segment).
    by : list of str
        The columns grouped by (e.g. a swept key and the condition).

    Returns
    -------
    pandas.DataFrame
        One row per group with its pooled figures.
    """
    rows = []
    for key, g in table.groupby(by, sort=True):
        key = key if isinstance(key, tuple) else (key,)
        rows.append({**dict(zip(by, key, strict=True)), **_pool(g)})
    return pd.DataFrame(rows)


def _name(r) -> str:
    return (f"{r['modulation_frequency_nominal_hz']:.4g} Hz, "
            f"{r['modulation_amplitude_nm']:.4g} N*m")


def _pct(x) -> str:
    return "-" if x is None or not np.isfinite(x) else f"{100 * x:.1f} %"


def noise_keys(spec: SweepSpec) -> list[str]:
    """The swept keys that set the train's noise level (``sensors.*``).

    Parameters
    ----------
    spec : SweepSpec
        The sweep's specification.

    Returns
    -------
    list of str
        The keys, in the sweep's order.
    """
    return [k for k in spec.swept if k.startswith("sensors.")]


def recommend_train(table: pd.DataFrame, spec: SweepSpec) -> dict:
    """The modulation setting for the train, and the reasoning (module docstring).

    Parameters
    ----------
    table : pandas.DataFrame
        The train sweep table (one row per point and friction segment).
    spec : SweepSpec
        The sweep's specification.

    Returns
    -------
    dict
        JSON-ready: ``setting``, ``reasoning``, ``settings``, ``limits``. When the sweep
        varies the sensors' noise (:func:`noise_keys`), one recommendation per noise level in
        ``by_noise`` (``noise``, ``setting``, ``reasoning``, ``settings``); the top level then
        holds the first level's, and the reasoning all of them.
    """
    keys = noise_keys(spec)
    if not keys or table.empty:
        return _recommend_one(table, spec)
    groups = []
    for value, g in _hashable(table).groupby(keys, sort=True):
        value = value if isinstance(value, tuple) else (value,)
        noise = dict(zip(keys, (v.item() if hasattr(v, "item") else v for v in value),
                         strict=True))
        groups.append({"noise": noise, **_recommend_one(table.loc[g.index], spec)})
    doc = {k: groups[0].get(k) for k in ("limits", "settings", "setting")}
    doc["by_noise"] = groups
    doc["reasoning"] = " ".join(
        "At " + ", ".join(f"{k} = {v}" for k, v in grp["noise"].items()) + ": "
        + grp["reasoning"] for grp in groups)
    return doc


def _recommend_one(table: pd.DataFrame, spec: SweepSpec) -> dict:
    opts = spec.recommend
    settings = setting_summary(table, spec)
    limits = {"max_creepage_swing": opts.max_creepage_swing,
              "max_torque_ripple_dc_pct": opts.max_torque_ripple_dc_pct,
              "max_mu_error": opts.max_mu_error, "min_coverage": opts.min_coverage}
    doc = {"limits": limits, "settings": settings.to_dict(orient="records"), "setting": None}
    ranked = settings.assign(_r=-settings["torque_ripple_pct_median"]).sort_values(
        ["qualifies", "good_share", "_r", "creepage_swing_max"],
        ascending=[False, False, False, True], ignore_index=True).drop(columns="_r")
    others = [k for k in spec.swept if k not in ("test.modulation_frequency_hz",
                                                 "test.modulation_amplitude_nm",
                                                 *noise_keys(spec))]
    varying = others + (["seed"] if len(spec.seeds) > 1 else [])
    lines = [f"Compared {len(settings)} modulation setting(s) on the train run, each pooled "
             f"over its points and friction segments" + (
                 f" (varying {', '.join(varying)})" if varying else "") + ". A mu row counts "
             f"when mu is given and within {opts.max_mu_error:.0%} of the truth; a setting "
             f"qualifies when its 95 % intervals hold the truth in at least "
             f"{opts.min_coverage:.0%} of its mu rows, its median error is within "
             f"{opts.max_mu_error:.0%} and its disturbance stays small (creepage swing <= "
             f"{opts.max_creepage_swing:.3g} at most, torque ripple <= "
             f"{opts.max_torque_ripple_dc_pct:.3g} % of the DC torque in the median)."]
    if not len(ranked):
        doc["reasoning"] = "No point finished."
        return doc
    best = ranked.iloc[0]
    if not best["qualifies"]:
        doc["qualifies"] = False
        why = []
        if not settings["accurate"].any():
            why.append("no setting gave mu rows with the required coverage and accuracy"
                       + (" (no mu at all: the on-board estimator withheld it in every window;"
                          " probe deeper or longer)" if settings["n_mu"].sum() == 0 else ""))
        if not settings["within_limits"].any():
            why.append("no setting keeps the disturbance within the limits")
        lines.append("None qualifies: " + "; ".join(why or ["the accurate settings add too "
                                                           "much disturbance"])
                     + ". The best of them regardless:")
    if len(settings) < 2:
        lines.append("The sweep varies no modulation setting, so there is nothing to choose "
                     "between; sweep test.modulation_frequency_hz and/or "
                     "test.modulation_amplitude_nm.")
    doc["setting"] = {k: float(best[k]) for k in SETTING}
    lines.insert(0, f"Recommended: {_name(best)}" + (
        "." if best["qualifies"] else " (none qualifies: the best regardless)."))
    lines.append(
        f"{_name(best)}: mu given in {_pct(best['mu_given_share'])} of "
        f"{int(best['n_windows'])} windows, within {opts.max_mu_error:.0%} in "
        f"{_pct(best['good_share'])} (of the mu rows {_pct(best['within_error_share'])}; mean "
        f"of the segments' median errors {_pct(best['mu_error_median_mean'])}), 95 % coverage "
        f"{_pct(best['coverage_95'])}, lower bound above the truth in "
        f"{_pct(best['lower_bound_above_truth_share'])} of the rows without mu; it adds a "
        f"creepage swing of at most {best['creepage_swing_max']:.3g} and a torque ripple of "
        f"{best['torque_ripple_pct_median']:.3g} % of the DC torque in the median (at most "
        f"{best['torque_ripple_pct_max']:.3g} %, at the probe's lowest level).")
    if len(ranked) > 1:
        nxt = ranked.iloc[1]
        lines.append(f"Next: {_name(nxt)} (mu within {opts.max_mu_error:.0%} in "
                     f"{_pct(nxt['good_share'])} of windows, coverage "
                     f"{_pct(nxt['coverage_95'])}, ripple {nxt['torque_ripple_pct_median']:.3g}"
                     f" % (median), swing {nxt['creepage_swing_max']:.3g}"
                     + ("" if nxt["qualifies"] else "; does not qualify") + ").")
    lines.append("mu true is the twin's friction at the window's position (truth.parquet); "
                 "the recommendation holds for this vehicle, track and sensor noise.")
    doc["reasoning"] = " ".join(lines)
    return doc


# ---------------------------------------------------------------------------- figures

def _hashable(table: pd.DataFrame) -> pd.DataFrame:
    """List-valued parameter columns (probe levels) as text, so that they group."""
    out = table.copy()
    for c in out.columns:
        if out[c].map(lambda v: isinstance(v, list | tuple | np.ndarray)).any():
            out[c] = out[c].map(lambda v: str(list(v)) if isinstance(
                v, list | tuple | np.ndarray) else v)
    return out


def mu_figure(table: pd.DataFrame, x: str) -> Figure:
    """mu's availability, error and coverage against a swept key.

    Share of windows with mu, the mean of the segments' median |mu/mu_true - 1| and the
    coverage of the 95 % interval against ``x``, one line per friction condition, pooled over
    every other parameter and seed.

    Parameters
    ----------
    table : pandas.DataFrame
        The train sweep table (one row per point and friction segment).
    x : str
        The column on the x axis.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    agg = condition_table(table, [x, "condition"])
    fig = Figure(figsize=(6.5, 7.0), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    numeric = pd.api.types.is_numeric_dtype(agg[x])
    cats = list(dict.fromkeys(agg[x].astype(str)))
    for j, (cond, g) in enumerate(agg.groupby("condition", sort=False)):
        xs = g[x].to_numpy(float) if numeric else [cats.index(str(v)) for v in g[x]]
        kw = {"color": f"C{j % 10}", "marker": "o", "label": str(cond)}
        axes[0].plot(xs, 100 * g["mu_given_share"], **kw)
        axes[1].plot(xs, 100 * g["mu_error_median_mean"], **kw)
        axes[2].plot(xs, 100 * g["coverage_95"], **kw)
    axes[0].set_ylabel("windows with mu [%]")
    axes[1].set_ylabel("median |mu/mu true - 1| [%]")
    axes[2].set_ylabel("95 % coverage [%]")
    axes[2].axhline(90, color="k", ls="--", lw=0.8)
    axes[1].axhline(10, color="k", ls="--", lw=0.8)
    if not numeric:
        axes[2].set_xticks(range(len(cats)), cats, fontsize=7)
    axes[2].set_xlabel(x.split(".", 1)[-1])
    for a in axes:
        a.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7)
    axes[0].set_title(f"on-board mu against {x} (per condition; dashed: targets)", fontsize=9)
    return fig


def band_figure(table: pd.DataFrame, curve: str | None) -> Figure:
    """Per friction condition the median phase and creep coefficient in each utilisation band.

    Phase (top) and creep coefficient (bottom, markers; the twin's truth dashed), one colour
    per value of ``curve`` (pooled over the rest).

    Parameters
    ----------
    table : pandas.DataFrame
        The train sweep table (one row per point and friction segment).
    curve : str or None
        The column whose values get one colour each; None: one curve.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    conds = list(dict.fromkeys(table["condition"]))
    fig = Figure(figsize=(3.2 * len(conds) + 1, 6.0), layout="constrained")
    axes = np.asarray(fig.subplots(2, len(conds), squeeze=False))
    centres = 100 * np.array([0.5 * (a + b) for a, b in BANDS])
    names = [band_name(b) for b in BANDS]
    groups = [(None, table)] if curve is None else list(table.groupby(curve, sort=True))
    for i, cond in enumerate(conds):
        for j, (value, g) in enumerate(groups):
            g = g[g["condition"] == cond]
            color = f"C{j % 10}"
            label = None if value is None else f"{curve.split('.', 1)[-1]} = {value}"
            axes[0, i].plot(centres, [g[f"phase_deg_{n}"].median() for n in names], "o-",
                            color=color, label=label)
            axes[1, i].plot(centres, [g[f"creep_coefficient_{n}"].median() for n in names],
                            "o", color=color, label=label)
            axes[1, i].plot(centres, [g[f"creep_coefficient_true_{n}"].median()
                                      for n in names], "--", color=color)
        axes[0, i].set_title(str(cond), fontsize=9)
        axes[1, i].set_xlabel("utilisation (truth) [%]")
        for a in axes[:, i]:
            a.grid(True, alpha=0.3)
    axes[0, 0].set_ylabel("phase lag [deg]")
    axes[1, 0].set_ylabel("creep coefficient [-]")
    if curve is not None:
        axes[0, 0].legend(fontsize=7)
    # what markers and dashes are in the creep-coefficient row
    axes[1, 0].plot([], [], "o", color="0.3", label="on-board estimate (median)")
    axes[1, 0].plot([], [], "--", color="0.3", label="twin's truth (median)")
    axes[1, 0].legend(fontsize=7)
    return fig


def make_train_figures(table: pd.DataFrame, spec: SweepSpec, rec: dict):
    """Every figure of a train sweep.

    Parameters
    ----------
    table : pandas.DataFrame
        The train sweep table (one row per point and friction segment).
    spec : SweepSpec
        The sweep's specification.
    rec : dict
        The recommendation (:func:`recommend_train`).

    Returns
    -------
    list of tuple
        ``(file stem, matplotlib Figure, caption)``.
    """
    from torquemod.sweep.figures import disturbance_figure
    tab = _hashable(table)
    out = []
    xs = []
    for key in spec.swept:
        col = _X_COLUMN.get(key, key)
        if col in tab and tab[col].nunique() > 1 and col not in xs:
            xs.append(col)
    for col in xs:
        out.append((f"mu_vs_{col.replace('.', '_')}", mu_figure(tab, col),
                    f"Windows with mu, the mean of the segments' median error of mu and the "
                    f"coverage of its 95 % interval against {col}, one line per friction "
                    "condition, pooled over the other parameters and seeds."))
    # the phase depends on the frequency first: its family when swept
    curve = ("test.modulation_frequency_hz" if "test.modulation_frequency_hz" in xs
             else next((c for c in xs if c != "condition"), None))
    out.append(("phase_by_condition", band_figure(tab, curve),
                "Median phase lag and creep coefficient of the steady windows in each "
                "utilisation band (0-30, 30-50, 50-70, 70-85, 85-100 % of the available "
                "adhesion, by the twin's truth), per friction condition; dashed: the twin's "
                "true creep coefficient." + (f" One colour per {curve}." if curve else "")))
    settings = setting_summary(table, spec)
    if len(settings):
        lim = {"max_creepage_swing": spec.recommend.max_creepage_swing,
               "max_torque_ripple_pct": spec.recommend.max_torque_ripple_dc_pct}
        settings = settings.assign(torque_ripple_pct_max=settings["torque_ripple_pct_median"])
        out.append(("disturbance", disturbance_figure(settings, lim,
                                                       ripple_label="ripple, median [% of DC]",
                                                       title="disturbance added by the "
                                                       "modulation (swing: largest; ripple: "
                                                       "median; dashed: limits)"),
                    "Disturbance each modulation setting adds on the train: the largest "
                    "creepage swing amplitude and the median torque ripple relative to the DC "
                    "torque over the periods of a constant demand (dashed: limits)."))
    return [(stem, figure_of(drawn), caption) for stem, drawn, caption in out]


# ----------------------------------------------------------------------------- report

_ROW_COLUMNS = ("point_index", "seed", "segment", "condition", "modulation_frequency_hz",
                "modulation_amplitude_nm", "probe_depth", "n_windows", "mu_given_share",
                "mu_error_median", "coverage_95", "lower_bound_above_truth_share",
                "low_adhesion_share_u50", "creepage_swing_max", "torque_ripple_pct_max")


def _png(fig) -> bytes:
    buf = io.BytesIO()
    figure_of(fig).savefig(buf, format="png", dpi=110)
    return buf.getvalue()


def _settings_html(rec: dict) -> str:
    head = ["f [Hz]", "A [N*m]", "points", "windows", "mu given", "mu within error",
            "coverage 95 %", "LB > truth", "swing max", "ripple median [% DC]",
            "ripple max [% DC]", "qualifies"]
    body = [[r["modulation_frequency_nominal_hz"], r["modulation_amplitude_nm"],
             r["n_points"], r["n_windows"], _pct(r["mu_given_share"]), _pct(r["good_share"]),
             _pct(r["coverage_95"]), _pct(r["lower_bound_above_truth_share"]),
             r["creepage_swing_max"], r["torque_ripple_pct_median"],
             r["torque_ripple_pct_max"], bool(r["qualifies"])]
            for r in rec.get("settings") or []]
    return table(head, body, caption="Modulation settings compared") if body else ""


def render_train(tab: pd.DataFrame, spec: SweepSpec, rec: dict, figs, *, failures=None,
                 wall_s: float | None = None) -> str:
    """The train sweep's report page as a string.

    Parameters
    ----------
    tab : pandas.DataFrame
        The train sweep table.
    spec : SweepSpec
        The sweep's specification.
    rec : dict
        The recommendation (:func:`recommend_train`).
    figs : list of tuple
        ``(file stem, PNG bytes, caption)`` of each figure.
    failures : pandas.DataFrame or None
        The points that failed. Default None.
    wall_s : float or None
        Wall time of the sweep [s]. Default None.

    Returns
    -------
    str
        The HTML page.
    """
    n_fail = 0 if failures is None else len(failures)
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{escape(spec.name)}"
             f" — torquemod sweep</title><style>{CSS}</style></head><body>",
             f"<h1>Sweep {escape(spec.name)} (train)</h1>"]
    if spec.description:
        parts.append(f"<p>{escape(spec.description)}</p>")
    parts.append(f"<p>{len(spec.points)} points, seeds {escape(str(list(spec.seeds)))}; "
                 f"{tab['point_id'].nunique()} finished, {n_fail} failed"
                 + (f"; this run took {wall_s:.1f} s" if wall_s is not None else "")
                 + f"; torquemod {escape(__version__)}. Each point: the train twin, the "
                 "on-board estimator, and its windows against the twin's truth per friction "
                 "segment.</p>")
    parts.append("<h2>Recommendation</h2>")
    for grp in rec.get("by_noise") or [rec]:
        if "noise" in grp:
            parts.append("<h3>" + escape(", ".join(f"{k} = {v}" for k, v in
                                                    grp["noise"].items())) + "</h3>")
        cls = "warn" if grp.get("qualifies") is False or grp.get("setting") is None else ""
        parts += [reasoning_html(grp.get("reasoning", ""), cls), _settings_html(grp)]
    parts.append("<h2>Figures</h2>")
    parts += [figure_html(png, stem, caption) for stem, png, caption in figs]
    if failures is not None and len(failures):
        parts.append("<h2>Failed points</h2>")
        parts.append(table(["#", "parameters", "seed", "message"],
                           [[int(r.point_index), r.params, int(r.seed), r.message]
                            for r in failures.itertuples()], left=4))
    keys = [k for k in spec.swept if k in tab]
    cols = ["point_index", *keys, *(c for c in _ROW_COLUMNS[1:] if c in tab)]
    shown = _hashable(tab).head(2000)
    parts.append("<h2>Points and segments</h2><p>Every column is in <code>sweep.parquet"
                 "</code>; a selection:</p>")
    parts.append(table(cols, [[r[c] for c in cols]
                              for _, r in shown.iterrows()], left=1 + len(keys)))
    parts.append(f"<h2>Provenance</h2><p>torquemod {escape(__version__)}; base: "
                 f"{escape(str(spec.base) if spec.base else 'the default train run')}.</p>"
                 f"<pre>{escape(spec.text)}</pre></body></html>")
    return "\n".join(p for p in parts if p)


def write_train_report(out: str | Path, tab: pd.DataFrame, spec: SweepSpec, rec: dict, *,
                       status=None, failures=None, wall_s: float | None = None) -> Path:
    """Draw the figures into ``out/figures`` and write ``out/report.html``.

    Parameters
    ----------
    out : str or pathlib.Path
        The sweep's results folder.
    tab : pandas.DataFrame
        The train sweep table.
    spec : SweepSpec
        The sweep's specification.
    rec : dict
        The recommendation (:func:`recommend_train`).
    status : object
        Accepted for the callers' convenience; not shown. Default None.
    failures : pandas.DataFrame or None
        The points that failed. Default None.
    wall_s : float or None
        Wall time of the sweep [s]. Default None.

    Returns
    -------
    pathlib.Path
        The report.
    """
    out = Path(out)
    figs = []
    for stem, fig, caption in make_train_figures(tab, spec, rec):
        png = _png(fig)
        save_png(png, out / "figures" / f"{stem}.png")
        figs.append((stem, png, caption))
    page = render_train(tab, spec, rec, figs, failures=failures, wall_s=wall_s)
    return write_atomic(out / "report.html", lambda fh: fh.write(page))
