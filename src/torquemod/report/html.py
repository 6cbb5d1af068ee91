"""Self-contained HTML report: inline CSS, figures as base64 PNG, every text escaped.

No external resources (stylesheets, scripts, fonts, images) are referenced, so the file reads
the same offline. :func:`render_report` is a pure function from the loaded results to a string;
:func:`iter_report` gives the same text in pieces, the per-cycle details one cycle at a time.
"""

from __future__ import annotations

import base64
import json
import math
from html import escape

from torquemod._util.jsonutil import iter_json_list

__all__ = ["iter_report", "render_report", "table"]

CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;margin:2em auto;
max-width:min(1300px,96vw);padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em;border-bottom:2px solid #444}h2{font-size:1.25em;margin-top:1.8em;
border-bottom:1px solid #bbb}table{border-collapse:collapse;margin:.6em 0;font-size:.85em}
th,td{border:1px solid #bbb;padding:.25em .45em;text-align:right;white-space:nowrap}
th{white-space:normal;vertical-align:bottom}
td.l{white-space:normal;overflow-wrap:break-word;max-width:40em}
.scroll{overflow-x:auto;max-width:100%}th{background:#eee}
td.l,th.l{text-align:left}caption{caption-side:top;text-align:left;font-weight:bold;
padding:.3em 0}figure{margin:1em 0}figure img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.9em;color:#444}.warn{background:#fff4e0;border-left:4px solid #e0a000;
padding:.4em .8em}.ok{color:#176317}.bad{color:#a00000}pre{background:#f6f6f6;padding:.6em;
overflow-x:auto;font-size:.8em}dl.kv{display:grid;grid-template-columns:minmax(12em,max-content)
minmax(0,1fr);gap:.2em 1em}dl.kv dt{font-weight:bold;max-width:32em}
dl.kv dd{margin:0;overflow-wrap:anywhere}
@media print{
@page{size:A4;margin:14mm 12mm 16mm}
body{max-width:none;margin:0;padding:0;font-size:9.5pt;line-height:1.3}
h1{font-size:15pt}h2{font-size:12pt;margin-top:1.2em;break-after:avoid}
h1,h2,h3,caption{break-after:avoid}
.scroll{overflow:visible}
table{width:100%;font-size:6.5pt;margin:.3em 0}thead{display:table-header-group}
th,td{padding:.15em .25em;min-width:0}th{white-space:normal;overflow-wrap:normal}
td{white-space:nowrap}td.l{white-space:normal;overflow-wrap:break-word}
tr,figure,dl.kv>*{break-inside:avoid}
figure{margin:.5em 0}figure img{max-width:100%;max-height:118mm;width:auto;height:auto;
display:block;margin:0 auto}
figcaption{font-size:8pt}
dl.kv{grid-template-columns:34% 1fr}
pre{white-space:pre-wrap;overflow-wrap:anywhere;font-size:6.5pt;overflow:visible}
details>:not(summary){display:none}details>summary{list-style:none;color:#555;font-size:8pt}
details>summary::after{content:" (folded in the HTML report; not printed)"}
.warn{break-inside:avoid}
}
"""


def fmt(value, digits: int = 4) -> str:
    """A number as text with a given number of significant figures.

    Parameters
    ----------
    value : object
        The value: a number, a bool, None or anything else (as ``str``).
    digits : int
        Significant figures [-]. Default 4.

    Returns
    -------
    str
        The text; None and NaN as an em dash, bools as yes/no.

    Examples
    --------
    >>> fmt(0.123456), fmt(None), fmt(True)
    ('0.1235', '—', 'yes')
    """
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return "—" if not math.isfinite(value) else f"{value:.{digits}g}"
    return str(value)


def table(headers, rows, *, caption: str | None = None, left: int = 0) -> str:
    """An escaped HTML table.

    Parameters
    ----------
    headers : sequence of str
        The column headers.
    rows : iterable of sequence
        The rows (values formatted by :func:`fmt`).
    caption : str or None
        The caption. Default None.
    left : int
        The first ``left`` columns are left-aligned. Default 0.

    Returns
    -------
    str
        The ``<table>``.
    """
    out = ['<div class="scroll"><table>']
    if caption:
        out.append(f"<caption>{escape(caption)}</caption>")
    cls = [' class="l"' if i < left else "" for i in range(len(headers))]
    out.append("<thead><tr>" + "".join(f"<th{c}>{_breakable(str(h))}</th>"
                                       for c, h in zip(cls, headers, strict=True))
               + "</tr></thead><tbody>")
    for row in rows:
        out.append("<tr>" + "".join(f"<td{c}>{escape(v if isinstance(v, str) else fmt(v))}</td>"
                                    for c, v in zip(cls, row, strict=True)) + "</tr>")
    out.append("</tbody></table></div>")
    return "\n".join(out)


def _breakable(text: str) -> str:
    """Escaped header text that may wrap after a dot or an underscore too (parameter names
    like ``modulation.frequency_hz`` have no spaces)."""
    return escape(text).replace(".", ".<wbr>").replace("_", "_<wbr>")


def figure_html(png: bytes, alt: str, caption: str) -> str:
    """A PNG image embedded as an HTML figure with its caption.

    Parameters
    ----------
    png : bytes
        The image.
    alt : str
        Its alternative text.
    caption : str
        Its caption.

    Returns
    -------
    str
        A ``<figure>`` with the image as a data URI.
    """
    data = base64.b64encode(png).decode("ascii")
    return (f'<figure><img alt="{escape(alt)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{escape(caption)}</figcaption></figure>")


def definition_list(pairs) -> str:
    """Key-value pairs as an HTML definition list.

    Parameters
    ----------
    pairs : iterable of tuple
        (key, value); values other than text are formatted by :func:`fmt`.

    Returns
    -------
    str
        A ``<dl>``.
    """
    return '<dl class="kv">' + "".join(
        f"<dt>{escape(str(k))}</dt><dd>{escape(v if isinstance(v, str) else fmt(v))}</dd>"
        for k, v in pairs) + "</dl>"


def _pm(value, err, digits=4) -> str:
    if value is None:
        return "—"
    # no-break spaces: a value and its error never split across lines
    return (f"{fmt(value, digits)}\u00a0±\u00a0{fmt(err, 2)}" if err is not None
            else fmt(value, digits))


def render_report(*, title: str, fit: dict, steps, cycles, provenance: dict,
                  figures: list[dict], warnings: list[str]) -> str:
    """HTML text of the report: :func:`iter_report`'s pieces joined.

    Parameters
    ----------
    title, fit, steps, cycles, provenance, figures, warnings
        As for :func:`iter_report`.

    Returns
    -------
    str
        The page.
    """
    return "".join(iter_report(title=title, fit=fit, steps=steps, cycles=cycles,
                               provenance=provenance, figures=figures, warnings=warnings))


_CYCLES = object()  # where iter_report puts the per-cycle details


def iter_report(*, title: str, fit: dict, steps, cycles, provenance: dict,
                figures: list[dict], warnings: list[str]):
    """HTML text of the report in pieces, the per-cycle details (``provenance["cycles"]``,
    any sequence of dicts) encoded one cycle at a time.

    Parameters
    ----------
    title : str
        The page's title.
    fit : dict
        The fit.json document.
    steps : pandas.DataFrame
        The extended steps.csv.
    cycles : pandas.DataFrame or None
        The cycles.csv.
    provenance : dict
        The provenance record.
    figures : list of dict
        With ``png`` (bytes), ``alt`` and ``caption``.
    warnings : list of str
        Plain strings.

    Yields
    ------
    str
        Consecutive pieces of the page.
    """
    exp = provenance.get("experiment", {})
    theory = fit.get("theory") or {}
    onset = fit.get("onset") or {}
    if fit.get("fit_skipped"):
        mu_text = f"no force fit: {fit['fit_skipped']}"
    elif fit.get("mu_determined"):
        mu_text = _pm(fit.get("mu"), fit.get("mu_stderr"))
    else:
        mu_text = f"not determined by the points (μ ≥ {fmt(fit.get('mu_lower_bound'))})"
    lo, hi = fit.get("mu_from_phase_interval_95") or [None, None]
    if fit.get("mu_from_phase_determined"):
        phase_text = f"{fmt(fit.get('mu_from_phase'))} (95 % interval {fmt(lo)} – {fmt(hi)})"
    elif lo is not None:
        phase_text = f"not determined by the steps (μ ≥ {fmt(lo)})"
    else:
        phase_text = "not estimated (see the warnings)"
    summary = definition_list([
        ("Coefficient of friction μ from the forces (Polach fit of CoA against creepage)",
         mu_text),
        ("Coefficient of friction μ from the phase (fit of tan φ = C/k(CoA), no forces used)",
         phase_text),
        ("Maximum CoA of the fitted curve", fmt(fit.get("curve_peak_coa"))),
        ("Saturation torque Ts = μ·N·Rw [N·m]", _ts_text(fit)),
        ("Saturation onset", _onset_text(onset)),
        ("Theory check",
         f"{theory.get('mode', '—')} constant C = {fmt(_scalar(theory.get('constant')))}; "
         f"RMS difference {fmt(theory.get('rms_difference_deg'), 3)}°, "
         f"max |difference| {fmt(theory.get('max_abs_difference_deg'), 3)}°"),
        ("Fit converged", _converged_text(fit)),
        ("Steps / cycles", f"{len(steps)} / {0 if cycles is None else len(cycles)}"),
        ("Manifest", str(exp.get("manifest", "—"))),
    ])

    s_cols = [("step", "Step"), ("dc_torque_nm", "DC applied torque [N·m]"),
              ("torque_pct_saturation", "DC torque [% Ts]"), ("creepage", "Creepage ξx [%]"),
              ("creepage_std", "std ξx [%]"), ("coa", "CoA [-]"), ("coa_std", "std CoA [-]"),
              ("phase_deg", "Phase φ [deg]"), ("phase_std_deg", "std φ [deg]"),
              ("phase_theory_deg", "Theory φ [deg]"), ("creep_coefficient", "dCoA/dξx [-]"),
              ("phase_fit_deg", "Phase fit φ [deg]"),
              ("utilisation_phase", "Utilisation CoA/μ (phase) [-]"),
              ("n_cycles", "Cycles")]
    s_cols = [(k, h) for k, h in s_cols if k in steps.columns]
    pct = {"creepage", "creepage_std"}  # in % as in Figure 3
    t1 = table([h for _, h in s_cols],
               [[_py(100 * r[k] if k in pct else r[k]) for k, _ in s_cols]
                for _, r in steps.iterrows()],
               caption="Table 1: DC torque steps and their creep-curve and phase results")
    t2 = _frequency_tables(cycles)

    names = list(fit.get("parameters", {}))
    tp = table(["Parameter", "Value", "Standard error"], _polach_rows(fit, names),
               caption="Polach fit parameters (lumped form; see the identifiability note)",
               left=1)
    corr = fit.get("correlation") or []
    tc = table(["", *names], [[n, *row] for n, row in zip(names, corr, strict=False)],
               caption="Parameter correlation matrix", left=1) if corr else ""
    fit_kv = definition_list([("Model", fit.get("model", "—")),
                  ("μ determined", _mu_determined_text(fit)),
                  ("χ² / dof / reduced χ²", f"{fmt(fit.get('chi2'))} / {fit.get('dof')} / "
                                             f"{fmt(fit.get('reduced_chi2'))}"),
                  ("Weighted by standard errors", fmt(fit.get("weighted"))),
                  ("Initial slope 2(kA+kS)s/π", fmt(fit.get("initial_slope"))),
                  ("Function evaluations", fmt(fit.get("nfev"))),
                  ("Identifiability", fit.get("identifiability", "—")),
                  ("Fit options", json.dumps(fit.get("fit_options", {}), sort_keys=True))])
    res = fit.get("residuals") or []
    tr = table(["Step", "Residual CoA (model − data)", "Weighted residual"],
               [[s, r, w] for s, r, w in zip(steps["step"].tolist() if "step" in steps else [],
                                             res, fit.get("weighted_residuals") or res,
                                             strict=False)],
               caption="Fit residuals")

    warn_html = ("".join(f'<p class="warn">{escape(w)}</p>' for w in warnings)
                 if warnings else '<p class="ok">No warnings.</p>')
    inputs = provenance.get("inputs") or []
    t_in = table(["File", "SHA-256", "Step", "Cycle"],
                 [[str(i.get("file")), str(i.get("sha256")), _py(i.get("step")),
                   _py(i.get("cycle"))] for i in inputs], caption="Input files", left=2)
    prov_small = {k: v for k, v in provenance.items() if k not in ("inputs", "cycles")}
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{escape(title)}</title><style>{CSS}</style></head><body>",
        f"<h1>{escape(title)}</h1>",
        f"<p>torquemod {escape(str(fit.get('torquemod_version', '')))}, fit created "
        f"{escape(str(fit.get('created_utc', '')))}; processing by torquemod "
        f"{escape(str(provenance.get('torquemod_version', '')))} at "
        f"{escape(str(provenance.get('created_utc', '')))}.</p>",
        "<h2>Summary</h2>", summary,
        "<h2>Figures</h2>", *[figure_html(f["png"], f["alt"], f["caption"]) for f in figures],
        "<h2>Tables</h2>", t1, t2,
        "<h2>Polach fit</h2>", fit_kv, tp, tc, tr,
        "<h2>Theory check and saturation onset</h2>",
        definition_list([("Mode", theory.get("mode", "—")), ("Formula", theory.get("formula", "—")),
             ("C", fmt(_scalar(theory.get("constant")))),
             ("C standard error", fmt(theory.get("constant_stderr"))),
             ("RMS difference [deg]", fmt(theory.get("rms_difference_deg"))),
             ("Max |difference| [deg]", fmt(theory.get("max_abs_difference_deg"))),
             ]),
        "<h2>Warnings</h2>", warn_html,
        "<h2>Provenance</h2>", t_in,
        "<details><summary>provenance.json (without inputs and cycles)</summary><pre>"
        + escape(json.dumps(prov_small, indent=2, default=str)) + "</pre></details>",
        _CYCLES,
        "</body></html>",
    ]
    for k, part in enumerate(parts):
        if k:
            yield "\n"
        if part is _CYCLES:  # escape() maps characters one by one: piecewise is the same
            yield "<details><summary>Per-cycle details</summary><pre>"
            for piece in iter_json_list(provenance.get("cycles", []), indent=1, level=0,
                                        default=str):
                yield escape(piece)
            yield "</pre></details>"
        else:
            yield part
    yield "\n"


def _frequency_tables(cycles) -> str:
    """Table 2 per step (mean and spread of the FFT peak frequencies over the step's cycles),
    the per-cycle values folded away below it."""
    if cycles is None or cycles.empty:
        return "<p>Table 2: no cycles.</p>"
    cols = [("torque_peak_hz", "Peak frequency torque [Hz]"),
            ("wheel_peak_hz", "Peak frequency wheel angular velocity [Hz]"),
            ("modulation_hz", "Common modulation frequency [Hz]")]
    cols = [(k, h) for k, h in cols if k in cycles.columns]
    g = cycles.groupby("step")
    rows = []
    for step, grp in g:
        row = [_py(step), str(len(grp))]
        for k, _ in cols:
            v = grp[k].to_numpy(dtype=float)
            spread = float(v.max() - v.min()) if v.size > 1 else None
            row.append(f"{fmt(float(v.mean()), 6)}" + (f" (± {fmt(spread / 2, 2)})"
                                                       if spread else ""))
        rows.append(row)
    t2 = table(["Step", "Cycles", *[h for _, h in cols]], rows,
               caption="Table 2: modulation frequencies from the FFT, mean over each step's "
                       "cycles (± half their range); per cycle below")
    per_cycle = table(["Step", "Cycle", *[h for _, h in cols]],
                      [[_py(r["step"]), _py(r["cycle"]), *[_py(r[k], 6) for k, _ in cols]]
                       for _, r in cycles.iterrows()])
    return (t2 + "<details><summary>Modulation frequencies per cycle</summary>" + per_cycle
            + "</details>")


def _mu_determined_text(fit: dict) -> str:
    if fit.get("mu_determined"):
        return "yes"
    return (f"no: the points give only μ ≥ {fmt(fit.get('mu_lower_bound'))}; the kA, kS "
            "values below are those of one curve among many that fit")


def _ts_text(fit: dict) -> str:
    """Ts with the μ it comes from: the one Ts of Table 1's % Ts and Figure 3's axis."""
    ts = fit.get("saturation_torque_nm")
    if ts is None:
        return "not known: neither fit determines μ (Table 1 and Figure 3 use N·m)"
    source = {"forces": "μ from the forces", "phase": "μ from the phase"}.get(
        fit.get("saturation_torque_source"), "μ")
    return (f"{_pm(ts, fit.get('saturation_torque_stderr_nm'))} (from {source}; the 100 % of "
            "Table 1's % Ts and of Figure 3's axis)")


def _polach_rows(fit: dict, names: list[str]) -> list[list]:
    """Rows of the Polach parameter table. An undetermined μ is never printed as a value
    with a standard error: its row gives the profile-likelihood range or the lower bound."""
    rows = []
    stderr = fit.get("stderr") or {}
    for n in names:
        if n == "mu" and not fit.get("mu_determined"):
            lo, hi = fit.get("mu_interval_95") or [None, None]
            bound = fmt(fit.get("mu_lower_bound"))
            text = (f"not determined: 95 % range {fmt(lo)} – {fmt(hi)}, μ ≥ {bound}"
                    if lo is not None and hi is not None else f"not determined: μ ≥ {bound}")
            rows.append([n, text, "—"])
        else:
            rows.append([n, fit["parameters"][n], stderr.get(n)])
    return rows


def _onset_text(onset: dict) -> str:
    """The onset step and its criterion, said once."""
    desc = str(onset.get("description") or "")
    rule = desc.partition(" (criterion: ")[2]
    where = f"step {onset['step']}" if onset.get("step") is not None else "not detected"
    return f"{where} (criterion: {rule}" if rule else where


def _converged_text(fit: dict) -> str:
    """'yes' only when the optimiser converged and the fitted curve rises monotonically up to
    its maximum; otherwise what is wrong, in words (no optimiser status text)."""
    if fit.get("fit_skipped"):
        return "no fit (skipped)"
    if fit.get("curve_monotone") is False:
        return f"no: {fit.get('curve_problem') or 'the fitted curve is not a creep curve'}"
    if fit.get("converged"):
        return "yes"
    return "no: the optimiser stopped before converging; the fitted values are unreliable"


def _scalar(c):
    if isinstance(c, list):
        vals = [v for v in c if v is not None]
        return sum(vals) / len(vals) if vals else None
    return c


def _py(v, digits: int = 4):
    """Numpy scalar to a Python one, then to text via :func:`fmt`."""
    if v is None:
        return "—"
    if hasattr(v, "item"):
        v = v.item()
    return fmt(v, digits)
