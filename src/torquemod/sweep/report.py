"""The sweep's figures (``OUT/figures/*.png``) and its self-contained ``report.html``: the
recommendation with its reasoning, the modulation settings compared, the figures, one row per
point, the per-step table and the provenance (version, the sweep file).

The page reuses :mod:`torquemod.report.html` (style, escaped tables, inline images); the
figures are :mod:`torquemod.sweep.figurejobs`' jobs, drawn here or by the caller's ``draw``
(the sweep's workers, side by side).
"""

from __future__ import annotations

import os
from html import escape
from pathlib import Path

import pandas as pd

from torquemod._util.fsutil import write_atomic
from torquemod._version import __version__
from torquemod.report.html import CSS, figure_html, table
from torquemod.sweep.conditions import CONDITION_COLUMN
from torquemod.sweep.figurejobs import (  # noqa: F401  (the report's figures, here as before)
    PNG_COMPRESS_LEVEL,
    creep_curves,
    draw_png,
    figure_jobs,
    make_figures,
    png_bytes,
)
from torquemod.sweep.spec import SweepSpec
from torquemod.sweep.summary import agreement, point_summary, recommend

__all__ = ["creep_curves", "make_figures", "reasoning_html", "recommend", "save_png",
           "write_report"]

#: rows of the per-step table shown in the page (all are in sweep.parquet)
MAX_TABLE_ROWS = 2000
_STEP_COLUMNS = ("point_index", "seed", "step", "dc_torque_nm", "utilisation", "slipped",
                 "slipped_twin", "coa",
                 "creepage", "phase_deg", "phase_se_deg", "phase_theory_deg",
                 "phase_simulated_deg", "creep_coefficient", "creepage_swing",
                 "torque_ripple_pct", "mu_true", "mu_forces", "mu_phase",
                 "mu_phase_lo",
                 "mu_phase_hi")


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
                 summary: pd.DataFrame | None = None, draw=None) -> Path:
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
    draw : callable or None
        ``draw(jobs)``: the PNG bytes (or None) of each
        :class:`~torquemod.sweep.figurejobs.FigureJob`, in their order (the sweep's
        workers draw them side by side). Default None: drawn here, one after another.

    Returns
    -------
    pathlib.Path
        The report.
    """
    out = Path(out)
    summary = point_summary(tab, spec) if summary is None else summary
    jobs = figure_jobs(tab, spec, rec, summary=summary)
    pngs = draw(jobs) if draw is not None else [draw_png(job) for job in jobs]
    figs = []
    for job, png in zip(jobs, pngs, strict=True):
        if png is not None:
            save_png(png, out / "figures" / f"{job.stem}.png")
            figs.append((job.stem, png, job.caption))
    page = render(tab, spec, rec, figs, status=status, failures=failures, wall_s=wall_s,
                  summary=summary)
    return write_atomic(out / "report.html", lambda fh: fh.write(page))

