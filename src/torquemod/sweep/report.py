"""The sweep's figures (``OUT/figures/*.png``) and its self-contained ``report.html``: the
recommendation with its reasoning, the modulation settings compared, the figures, one row per
point, the per-step table and the provenance (version, the sweep file).

The page reuses :mod:`torquemod.report.html` (style, escaped tables, inline images).
"""

from __future__ import annotations

import io
from html import escape
from pathlib import Path

import pandas as pd

from .._version import __version__
from ..fsutil import write_atomic
from ..report.figures import figure_of, save_figure
from ..report.html import CSS, _img, table
from . import figures as F
from .spec import CONDITION_KEY, SweepSpec
from .summary import BAND, agreement, point_summary, recommend, setting_table

__all__ = ["make_figures", "recommend", "write_report"]

#: rows of the per-step table shown in the page (all are in sweep.parquet)
MAX_TABLE_ROWS = 2000
_STEP_COLUMNS = ("point_index", "seed", "step", "dc_torque_nm", "utilisation", "coa",
                 "creepage", "phase_deg", "phase_se_deg", "phase_theory_deg",
                 "phase_simulated_deg", "creep_coefficient", "creepage_swing",
                 "torque_ripple_pct", "mu_true", "mu_friction", "mu_forces", "mu_phase",
                 "mu_phase_lo",
                 "mu_phase_hi")


def _png(fig) -> bytes:
    buf = io.BytesIO()
    figure_of(fig).savefig(buf, format="png", dpi=110)
    return buf.getvalue()


def make_figures(tab: pd.DataFrame, spec: SweepSpec, rec: dict) -> list[tuple[str, object, str]]:
    """``(file stem, Figure, caption)`` of every figure of the sweep."""
    summary = point_summary(tab, spec)
    swept = [k for k in spec.swept if k in tab]
    out = []
    if CONDITION_KEY in swept and len(swept) > 1:
        curve = ("modulation.frequency_hz" if "modulation.frequency_hz" in swept
                 else next(k for k in swept if k != CONDITION_KEY))
        out.append(("phase_by_condition", F.phase_panels_figure(tab, CONDITION_KEY, curve,
                                                               swept),
                    f"Phase lag against utilisation for each friction condition, one curve "
                    f"per {curve} (the paper's Fig. 4 per condition): lines large-signal "
                    "theory, markers the processing chain with 95 % bars."))
    for key in swept or ["modulation.frequency_hz"]:
        if key not in tab:
            continue
        name = key.replace(".", "_")
        out.append((f"phase_family_{name}", F.phase_family_figure(tab, key, swept),
                    f"Phase against utilisation by {key}, the other swept parameters at "
                    "their first values."))
        if summary[key].nunique() > 1:
            out.append((f"sensitivity_{name}", F.sensitivity_figure(summary, key, swept),
                        f"Sensitivity dphi/du over {BAND[0]:.0%}-{BAND[1]:.0%} utilisation "
                        f"against {key}."))
            out.append((f"mu_error_{name}", F.mu_error_figure(summary, key, swept),
                        f"mu from the phase (steps up to {spec.recommend.max_utilisation:.0%} "
                        f"utilisation) relative to the true mu, against {key}."))
    settings = setting_table(summary, spec)
    if len(settings):
        out.append(("disturbance", F.disturbance_figure(settings, rec.get("limits", {
            "max_creepage_swing": spec.recommend.max_creepage_swing,
            "max_torque_ripple_pct": spec.recommend.max_torque_ripple_pct})),
            "Disturbance the modulation adds (largest creepage swing amplitude and torque "
            "ripple below the utilisation limit) per modulation setting."))
    return out


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
    keys = [k for k in spec.swept if k in summary]
    head = ["#", *keys, "seed", "peak CoA", "friction", "mu phase", "95 % lo", "95 % hi",
            "error [%]",
            "covered", "dphi/du [deg/%]", "swing", "ripple [%]", "twin-theory [deg]",
            "slip at step"]
    body = [[int(r["point_index"]), *[str(r[k]) for k in keys], int(r["seed"]), r["mu_true"],
             r.get("mu_friction", r["mu_true"]), r["mu_phase"], r["mu_phase_lo"],
             r["mu_phase_hi"], r["effective_error_pct"],
             bool(r["covered"]), r["dphi_du_theory"], r["creepage_swing_max"],
             r["torque_ripple_pct_max"],
             r["twin_minus_theory_max_deg"],
             "—" if r["slipped_at_step"] is None or pd.isna(r["slipped_at_step"])
             else int(r["slipped_at_step"])] for _, r in summary.iterrows()]
    return table(head, body, caption="One row per point (peak CoA: the twin's available "
                 "adhesion; friction: its friction coefficient at the slip velocity of the "
                 "highest step the fit used, Polach Eq. 9, the truth for mu from the phase; "
                 "error: of mu from the phase, or of its lower bound when not determined)",
                 left=1 + len(keys))


def render(tab: pd.DataFrame, spec: SweepSpec, rec: dict, figs, *, status=None,
           failures=None, wall_s: float | None = None) -> str:
    """The report page as a string."""
    summary = point_summary(tab, spec)
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
        parts.append(f"<p class='{cls}'>{escape(grp.get('reasoning', ''))}</p>")
        parts.append(_settings_html(grp))
    parts.append("<h2>Figures</h2>")
    for stem, png, caption in figs:
        parts.append(_img(png, stem, caption))
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
                 f"utilisation = DC torque / creep-curve peak torque; mu true = peak CoA of "
                 f"the twin's creep curve.</p><pre>{escape(spec.text)}</pre>")
    parts.append("</body></html>")
    return "\n".join(p for p in parts if p)


def write_report(out: str | Path, tab: pd.DataFrame, spec: SweepSpec, rec: dict, *,
                 status=None, failures=None, wall_s: float | None = None) -> Path:
    """Draw the figures into ``out/figures`` and write ``out/report.html`` (atomically);
    return the report's path."""
    out = Path(out)
    figs = []
    for stem, fig, caption in make_figures(tab, spec, rec):
        save_figure(fig, out / "figures" / stem, formats=("png",), dpi=110)
        figs.append((stem, _png(fig), caption))
    page = render(tab, spec, rec, figs, status=status, failures=failures, wall_s=wall_s)
    return write_atomic(out / "report.html", lambda fh: fh.write(page))

