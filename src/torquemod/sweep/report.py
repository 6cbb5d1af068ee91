"""The sweep's figures (``OUT/figures/*.png``) and its self-contained ``report.html``: the
recommendation with its reasoning, the modulation settings compared, the figures, one row per
point, the per-step table and the provenance (version, the sweep file).

The page reuses :mod:`torquemod.report.html` (style, escaped tables, inline images).
"""

from __future__ import annotations

import io
import os
from html import escape
from pathlib import Path

import numpy as np
import pandas as pd

from torquemod._util.fsutil import write_atomic
from torquemod._version import __version__
from torquemod.report.figures import figure_of
from torquemod.report.html import CSS, figure_html, table
from torquemod.sweep import figures as F
from torquemod.sweep.conditions import CONDITION_COLUMN, condition_labels
from torquemod.sweep.spec import SweepSpec
from torquemod.sweep.summary import BAND, agreement, point_summary, recommend, setting_table

__all__ = ["make_figures", "reasoning_html", "recommend", "save_png", "write_report"]

#: rows of the per-step table shown in the page (all are in sweep.parquet)
MAX_TABLE_ROWS = 2000
_STEP_COLUMNS = ("point_index", "seed", "step", "dc_torque_nm", "utilisation", "slipped",
                 "slipped_twin", "coa",
                 "creepage", "phase_deg", "phase_se_deg", "phase_theory_deg",
                 "phase_simulated_deg", "creep_coefficient", "creepage_swing",
                 "torque_ripple_pct", "mu_true", "mu_forces", "mu_phase",
                 "mu_phase_lo",
                 "mu_phase_hi")


#: zlib level of the report's PNGs: 1 instead of Pillow's 6 saves 16 % of the encoding CPU
#: (1.37 -> 1.14 CPU-s for the example sweep's six figures) for 8 % larger files
PNG_COMPRESS_LEVEL = 1


def _png(fig) -> bytes:
    buf = io.BytesIO()
    figure_of(fig).savefig(buf, format="png", dpi=110,
                           pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL})
    return buf.getvalue()


def save_png(png: bytes, path: Path) -> Path:
    """Write PNG bytes to a file (beside it first, then renamed into place).

    Each figure is drawn once, for the page and the file alike.

    Parameters
    ----------
    png : bytes
        The image.
    path : pathlib.Path
        The file.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(png)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def _frequencies(values, at_most: int = 6) -> list:
    """The swept frequencies to compare the conditions at: all of them, or the ``at_most``
    nearest (in ratio) to the paper's 2 Hz, in ascending order."""
    values = sorted(dict.fromkeys(float(v) for v in values))
    if len(values) > at_most:
        values = sorted(sorted(values, key=lambda f: abs(np.log(f / 2.0)))[:at_most])
    return values


def creep_curves(tab: pd.DataFrame, spec: SweepSpec) -> dict:
    """Per condition the twin's longitudinal adhesion-creepage curve at the operating speed.

    ``F_x/N`` of the Polach model [1]_. Conditions whose curves are the same (they differ
    only in noise, say) share one entry, named after the first and listing all their labels.

    Parameters
    ----------
    tab : pandas.DataFrame
        The sweep table (``sweep.parquet``) with its ``condition`` labels.
    spec : SweepSpec
        The sweep's specification.

    Returns
    -------
    dict
        ``name -> (creepage [-], F_x/N [-], creepage at the peak [-], peak F_x/N [-],
        labels)``.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (1)-(9).
    """
    from torquemod.analysis.contact.polach import creep_force
    from torquemod.sweep.evaluate import point_config, tasks
    from torquemod.twins.vtrack.theory import creep_curve_peak
    by_id = {t.point_id: t for t in tasks(spec)}
    groups: dict = {}
    for label, g in tab.groupby(CONDITION_COLUMN, sort=False):
        task = by_id.get(g["point_id"].iloc[0])
        if task is None:
            continue
        rig = point_config(task)[0].rig
        key = (rig.contact, rig.speed_m_s, rig.normal_load_n, rig.wheel_radius_m)
        entry = groups.setdefault(key, {"rig": rig, "labels": [], "xi_max": 0.0})
        entry["labels"].append(label)
        xi = g["creepage_true"].to_numpy(float)
        if np.isfinite(xi).any():
            entry["xi_max"] = max(entry["xi_max"], float(np.nanmax(np.abs(xi))))
    out = {}
    for entry in groups.values():
        rig, labels = entry["rig"], entry["labels"]
        xi_peak, t_peak = creep_curve_peak(rig)
        xi = np.geomspace(1e-5, max(2.0 * xi_peak, 1.5 * entry["xi_max"]), 400)
        fx, _ = creep_force(xi, rig.contact.lateral_creepage, normal_load_n=rig.normal_load_n,
                            speed_m_s=rig.speed_m_s, **rig.contact.polach_kwargs())
        name = labels[0] if len(labels) == 1 else (
            f"{labels[0]} (and {len(labels) - 1} more with this curve)")
        out[name] = (xi, fx / rig.normal_load_n, xi_peak,
                     t_peak / (rig.wheel_radius_m * rig.normal_load_n), labels)
    return out


def make_figures(tab: pd.DataFrame, spec: SweepSpec, rec: dict, *,
                 summary: pd.DataFrame | None = None) -> list[tuple[str, object, str]]:
    """Every figure of the sweep.

    Parameters
    ----------
    tab : pandas.DataFrame
        The sweep table (``sweep.parquet``) with its ``condition`` labels.
    spec : SweepSpec
        The sweep's specification.
    rec : dict
        The recommendation (:func:`torquemod.sweep.summary.recommend`).
    summary : pandas.DataFrame or None
        :func:`~torquemod.sweep.summary.point_summary` of ``tab`` when the caller has it.
        Default None (computed here).

    Returns
    -------
    list of tuple
        ``(file stem, matplotlib Figure, caption)``.
    """
    summary = point_summary(tab, spec) if summary is None else summary
    tab = tab.assign(**{CONDITION_COLUMN: condition_labels(tab, spec.swept)})
    conds = list(dict.fromkeys(tab[CONDITION_COLUMN]))
    amp, seed = tab[F.AMP].iloc[0], tab["seed"].iloc[0]
    ref = tab[(tab[F.AMP] == amp) & (tab["seed"] == seed)]
    at = (f" at the modulation amplitude {amp:.3g} N*m" if tab[F.AMP].nunique() > 1 else "") \
        + (f", seed {seed}" if tab["seed"].nunique() > 1 else "")
    lines = ("lines: large-signal theory; dotted: the rigid-wheel small-signal model of the "
             "paper's Eq. (1), tan φ = ΩJV/(R²Nk), at each step's creep coefficient; "
             "markers: twin + processing chain with 95 % bars; crosses: steps where the "
             "wheel slipped (on the theory's curve where the twin slipped, at the top of the "
             "panel where the theory has no periodic state either).")
    freqs = sorted(dict.fromkeys(ref[F.FREQ]))
    out = [("phase_by_condition",
            F.phase_panels_figure(ref, title="phase vs utilisation per condition" + at),
            f"Phase lag against utilisation, one panel per condition ({len(conds)}), one "
            f"colour per modulation frequency ({', '.join(f'{f:.3g}' for f in freqs)} Hz)"
            f"{at} (the paper's Fig. 4 per condition). {lines}")]
    if len(conds) > 1:
        shown = _frequencies(ref[F.FREQ])
        out.append(("phase_by_frequency",
                    F.phase_panels_figure(ref[ref[F.FREQ].isin(shown)], panel=F.FREQ,
                                          curve=CONDITION_COLUMN, panels=shown,
                                          title="the conditions compared" + at),
                    "The conditions compared at each modulation frequency "
                    f"({', '.join(f'{f:.3g}' for f in shown)} Hz){at}: phase lag against "
                    f"utilisation, one colour per condition. {lines}"))
    curves = creep_curves(ref, spec)
    if curves:
        names = {lab: name for name, c in curves.items() for lab in c[4]}
        drawn = tab.assign(**{CONDITION_COLUMN: tab[CONDITION_COLUMN].map(names)})
        out.append(("creep_curves",
                    F.creep_curves_figure({k: c[:4] for k, c in curves.items()},
                                          drawn[(drawn[F.AMP] == amp)
                                                & (drawn["seed"] == seed)]),
                    "The twin's adhesion-creepage curve of each condition at its operating "
                    "speed (Polach 2005), its peak -- the available adhesion, the true μ "
                    "against which μ from the phase is judged -- and the steady operating "
                    "points of the torque steps" + (", with the chain's measured points "
                                                    "per modulation frequency"
                                                    if spec.mode == "full" else "") + "."))
    if summary[F.FREQ].nunique() > 1 or len(conds) > 1:
        out.append(("sensitivity", F.sensitivity_figure(summary),
                    f"Sensitivity dφ/du of the phase to the utilisation over "
                    f"{BAND[0]:.0%}-{BAND[1]:.0%}, per condition" + (
                        " against the modulation frequency" if summary[F.FREQ].nunique() > 1
                        else "") + "."))
    out.append(("mu_error", F.mu_error_figure(summary),
                f"μ from the phase (steps up to {spec.recommend.max_utilisation:.0%} "
                "utilisation) relative to the available adhesion (the creep curve's peak), "
                "per condition and modulation setting."))
    settings = setting_table(summary, spec)
    if len(settings):
        out.append(("disturbance", F.disturbance_figure(settings, rec.get("limits", {
            "max_creepage_swing": spec.recommend.max_creepage_swing,
            "max_torque_ripple_pct": spec.recommend.max_torque_ripple_pct})),
            "Disturbance the modulation adds (largest creepage swing amplitude and torque "
            "ripple below the utilisation limit) per modulation setting."))
    return [(stem, figure_of(drawn), caption) for stem, drawn, caption in out]


def reasoning_html(text: str, cls: str = "") -> str:
    """The recommendation's reasoning as an HTML paragraph, its answer in bold.

    Parameters
    ----------
    text : str
        The reasoning; its first sentence ``Recommended: ...`` is the answer.
    cls : str
        The paragraph's CSS class. Default "".

    Returns
    -------
    str
        A ``<p>`` element, text escaped.

    Examples
    --------
    >>> reasoning_html("Recommended: 2 Hz. Because.")
    "<p class=''><b>Recommended: 2 Hz.</b> Because.</p>"
    """
    head, sep, rest = text.partition(". ")
    if head.startswith("Recommended:") and sep:
        return f"<p class='{cls}'><b>{escape(head)}.</b> {escape(rest)}</p>"
    if head.startswith("Recommended:") and text.endswith("."):
        return f"<p class='{cls}'><b>{escape(text)}</b></p>"
    return f"<p class='{cls}'>{escape(text)}</p>"


def _settings_html(rec: dict) -> str:
    rows = rec.get("settings") or []
    if not rows:
        return ""
    head = ["f [Hz]", "A [N*m]", "points", "mu determined", "truth covered", "RMS error [%]",
            "max error [%]", "bias [%]", "dphi/du [deg/%]", "phase SE [deg]",
            "creepage swing", "torque ripple [%]", "within limits"]
    body = [[r["modulation_frequency_nominal_hz"], r["modulation_amplitude_nm"], r["n_points"],
             r["n_determined"], r["n_covered"], r["rms_error_pct"], r["max_error_pct"],
             r["bias_pct"], r["dphi_du_mean"],
             r["phase_se_median_deg"], r["creepage_swing_max"], r["torque_ripple_pct_max"],
             bool(r["within_limits"])] for r in rows]
    return table(head, body, caption="Modulation settings compared")


def _points_html(summary: pd.DataFrame, spec: SweepSpec) -> str:
    head = ["#", "condition", "f [Hz]", "A [N*m]", "seed", "true μ", "μ phase", "95 % lo",
            "95 % hi", "error [%]", "covered", "dφ/du [deg/%]", "swing", "ripple [%]",
            "twin−theory [deg]", "slip at step"]
    body = [[int(r["point_index"]), r[CONDITION_COLUMN] or "—",
             r["modulation_frequency_nominal_hz"], r["modulation_amplitude_nm"],
             int(r["seed"]), r["mu_true"], r["mu_phase"], r["mu_phase_lo"],
             r["mu_phase_hi"], r["effective_error_pct"],
             bool(r["covered"]), r["dphi_du_theory"], r["creepage_swing_max"],
             r["torque_ripple_pct_max"],
             r["twin_minus_theory_max_deg"],
             "—" if r["slipped_at_step"] is None or pd.isna(r["slipped_at_step"])
             else int(r["slipped_at_step"])] for _, r in summary.iterrows()]
    return table(head, body, caption="One row per point (true μ: the available adhesion, "
                 "the peak of the twin's adhesion-creepage curve at the operating speed; "
                 "error: of μ from the phase against it, or of its lower bound when μ is "
                 "not determined)", left=2)


def render(tab: pd.DataFrame, spec: SweepSpec, rec: dict, figs, *, status=None,
           failures=None, wall_s: float | None = None,
           summary: pd.DataFrame | None = None) -> str:
    """The sweep's report page as a string.

    Parameters
    ----------
    tab : pandas.DataFrame
        The sweep table (``sweep.parquet``) with its ``condition`` labels.
    spec : SweepSpec
        The sweep's specification.
    rec : dict
        The recommendation (:func:`torquemod.sweep.summary.recommend`).
    figs : list of tuple
        ``(file stem, PNG bytes, caption)`` of each figure.
    status : object
        Accepted for the callers' convenience; not shown. Default None.
    failures : pandas.DataFrame or None
        The points that failed (``point_index``, ``params``, ``seed``, ``message``).
        Default None.
    wall_s : float or None
        Wall time of the sweep [s]. Default None.
    summary : pandas.DataFrame or None
        :func:`~torquemod.sweep.summary.point_summary` of ``tab`` when the caller has it.
        Default None (computed here).

    Returns
    -------
    str
        The HTML page.
    """
    summary = point_summary(tab, spec) if summary is None else summary
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>"
             f"{escape(spec.name)} — torquemod sweep</title><style>{CSS}</style></head><body>",
             f"<h1>Sweep {escape(spec.name)}</h1>"]
    if spec.description:
        parts.append(f"<p>{escape(spec.description)}</p>")
    n_fail = 0 if failures is None else len(failures)
    parts.append(f"<p>{len(spec.points)} points, mode <b>{escape(spec.mode)}</b>, seeds "
                 f"{escape(str(list(spec.seeds)))}; {summary.shape[0]} finished, {n_fail} "
                 f"failed" + (f"; this run took {wall_s:.1f} s" if wall_s is not None else "")
                 + f"; torquemod {escape(__version__)}.</p>")
    agr = agreement(tab)
    if agr["twin_minus_theory_max_deg"] is not None:
        parts.append(
            f"<p>Twin against the large-signal theory over {agr['n_steps']} steps below slip: "
            f"|phase difference| median {agr['twin_minus_theory_median_deg']:.3g} deg, largest "
            f"{agr['twin_minus_theory_max_deg']:.3g} deg (the theory has a constant normal load "
            "and no speed wobble: with the rig's disturbances switched off the two agree to "
            "about 0.002 deg). The chain's phase differs from the theory by "
            f"{agr['chain_z_median']:.2f} of its standard errors (median; largest "
            f"{agr['chain_z_max']:.2f}).</p>")
    parts.append("<h2>Recommendation</h2>")
    for grp in rec.get("by_noise") or [rec]:
        if "noise" in grp:
            parts.append("<h3>" + escape(", ".join(f"{k} = {v}" for k, v in
                                                    grp["noise"].items())) + "</h3>")
        cls = ("warn" if grp.get("within_limits") is False or grp.get("setting") is None
               else "")
        parts.append(reasoning_html(grp.get("reasoning", ""), cls))
        parts.append(_settings_html(grp))
    parts.append("<h2>Figures</h2>")
    for stem, png, caption in figs:
        parts.append(figure_html(png, stem, caption))
    parts.append("<h2>Points</h2>")
    parts.append(_points_html(summary, spec))
    if failures is not None and len(failures):
        parts.append("<h2>Failed points</h2>")
        parts.append(table(["#", "parameters", "seed", "message"],
                           [[int(r.point_index), r.params, int(r.seed), r.message]
                            for r in failures.itertuples()], left=4))
    cols = [c for c in _STEP_COLUMNS if c in tab]
    shown = tab.head(MAX_TABLE_ROWS)
    parts.append("<h2>Table</h2><p>Every column of every step is in <code>sweep.parquet"
                 "</code>; a selection" + (f" (the first {MAX_TABLE_ROWS} of {len(tab)} rows)"
                                           if len(tab) > MAX_TABLE_ROWS else "")
                 + ":</p><details><summary>per-step table</summary>")
    parts.append(table(cols, [[r[c] for c in cols] for _, r in shown.iterrows()]))
    parts.append("</details><h2>Provenance</h2>")
    parts.append(f"<p>torquemod {escape(__version__)}; base config: "
                 f"{escape(str(spec.base) if spec.base else 'the V-Track default')}; "
                 "utilisation = DC torque / creep-curve peak torque; true μ = the "
                 "available adhesion, the peak of the twin's adhesion-creepage curve F_x/N "
                 "at the operating speed (T_peak/(R·N)), against which μ from the phase is "
                 "judged everywhere in this report.</p><pre>{escape(spec.text)}</pre>")
    parts.append("</body></html>")
    return "\n".join(p for p in parts if p)


def write_report(out: str | Path, tab: pd.DataFrame, spec: SweepSpec, rec: dict, *,
                 status=None, failures=None, wall_s: float | None = None,
                 summary: pd.DataFrame | None = None) -> Path:
    """Draw the figures into ``out/figures`` and write ``out/report.html`` atomically.

    Parameters
    ----------
    out : str or pathlib.Path
        The sweep's results folder.
    tab : pandas.DataFrame
        The sweep table (``sweep.parquet``) with its ``condition`` labels.
    spec : SweepSpec
        The sweep's specification.
    rec : dict
        The recommendation (:func:`torquemod.sweep.summary.recommend`).
    status : object
        Accepted for the callers' convenience; not shown. Default None.
    failures : pandas.DataFrame or None
        The points that failed (``point_index``, ``params``, ``seed``, ``message``).
        Default None.
    wall_s : float or None
        Wall time of the sweep [s]. Default None.
    summary : pandas.DataFrame or None
        :func:`~torquemod.sweep.summary.point_summary` of ``tab`` when the caller has it.
        Default None (computed here once, for the figures and the page).

    Returns
    -------
    pathlib.Path
        The report.
    """
    out = Path(out)
    summary = point_summary(tab, spec) if summary is None else summary
    figs = []
    for stem, fig, caption in make_figures(tab, spec, rec, summary=summary):
        png = _png(fig)
        save_png(png, out / "figures" / f"{stem}.png")
        figs.append((stem, png, caption))
    page = render(tab, spec, rec, figs, status=status, failures=failures, wall_s=wall_s,
                  summary=summary)
    return write_atomic(out / "report.html", lambda fh: fh.write(page))

