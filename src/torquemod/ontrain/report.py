"""Figures and the HTML report of an on-board run.

Every plot function draws on a given ``ax`` and returns it, or, without one, on a new
:class:`matplotlib.figure.Figure` (not pyplot: nothing is shown or kept) and returns its
Axes.
"""

from __future__ import annotations

import math
from html import escape
from pathlib import Path

import numpy as np

from torquemod.report.html import CSS, definition_list, figure_html, table

#: legends below the axes, outside the data (the figures' axes then share one width, so
#: positions line up from figure to figure)
_LEGEND = {"loc": "upper center", "bbox_to_anchor": (0.5, -0.2), "fontsize": 7, "ncols": 3,
           "frameon": False}


def _axes(ax, figsize=(10.0, 4.0)):
    if ax is not None:
        return ax
    from matplotlib.figure import Figure
    return Figure(figsize=figsize, layout="constrained").subplots()


def _step(ax, seg, column, **kw):
    """A value per stretch drawn as a horizontal line over it; a gap where it is NaN."""
    first = True
    for _, s in seg.iterrows():
        v = s[column]
        if v is None or not math.isfinite(v):
            continue
        ax.plot([s.start_m, s.end_m], [v, v], **(kw if first else {**kw, "label": None}))
        first = False


def _changes(ax, result):
    for i, c in enumerate(result.changes_m):
        ax.axvline(c, color="0.35", ls=":", lw=0.8,
                   label="detected friction change" if i == 0 else None)


def plot_mu(result, *, ax=None):
    """Plot mu along the track.

    mu where the estimator determined it (points with their 95 % interval), the lower bound
    of each segment between detected friction changes (step line), the utilised adhesion CoA
    of each window; the simulated truth when the run has one.

    Parameters
    ----------
    result : OnboardResult
        One axle's result.
    ax : matplotlib.axes.Axes or None
        Axes to draw in; None: a new figure's.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn in (position [m] against adhesion [-]).
    """
    ax = _axes(ax)
    t = result.track
    seg = result.along_track()
    x = t["position_m"].to_numpy(dtype=float)
    ax.plot(x, t["coa"], color="0.6", lw=0.6, label="CoA per window (utilised adhesion)")
    _step(ax, seg, "mu_lower_bound", color="C1", lw=2.2,
          label="lower bound per segment (μ is above it)")
    given = t["mu"].notna().to_numpy()
    if given.any():
        mu = t["mu"].to_numpy(dtype=float)[given]
        lo = t["mu_low_95"].to_numpy(dtype=float)[given]
        hi = t["mu_high_95"].to_numpy(dtype=float)[given]
        ax.errorbar(x[given], mu, yerr=[np.clip(mu - lo, 0, None), np.clip(hi - mu, 0, None)],
                    fmt="o", color="C0", ms=3.5, lw=0.8, capsize=0,
                    label="μ where determined (bar: 95 % interval)")
        _step(ax, seg, "mu", color="C0", lw=1.4, ls="--", label="μ per segment (median)")
    if result.truth is not None:
        tr = result.truth
        ax.plot(tr["position_m"], tr["mu"], "k--", lw=1.0, label="truth: friction μ")
        ax.plot(tr["position_m"], tr["adhesion_peak"], "k:", lw=1.0,
                label="truth: available adhesion")
    _changes(ax, result)
    ax.set_ylim(bottom=0)
    ax.set_xlabel("position [m]")
    ax.set_ylabel("coefficient [-]")
    ax.grid(True, alpha=0.3)
    ax.legend(**_LEGEND)
    return ax


def phase_limits(phase_deg, *, margin: float = 0.15) -> tuple[float, float]:
    """The axis limits holding the body of the phases.

    Parameters
    ----------
    phase_deg : array_like
        Phases [deg]; NaN ignored.
    margin : float
        Widening on each side, as a share of the 1st-99th percentile range [-]. Default 0.15.

    Returns
    -------
    tuple of float
        (low, high) [deg]; (-1, 1) without finite phases.

    Examples
    --------
    >>> phase_limits([10.0, 20.0], margin=0.0)
    (10.1, 19.9)
    """
    p = np.asarray(phase_deg, dtype=float)
    p = p[np.isfinite(p)]
    if not p.size:
        return -1.0, 1.0
    lo, hi = np.percentile(p, [1, 99])
    pad = margin * max(hi - lo, 1.0)
    return float(lo - pad), float(hi + pad)


def clipped_phases(result) -> tuple[int, int]:
    """How many windows' phases lie beyond :func:`phase_limits`, and how many of those stepped.

    Parameters
    ----------
    result : OnboardResult
        One axle's result.

    Returns
    -------
    clipped : int
        Windows whose phase lies beyond the limits.
    stepped : int
        How many of them had a torque step inside (``dc_step_ratio`` above the estimator's
        limit; 0 when the track does not carry that diagnostic).
    """
    t = result.track
    lo, hi = phase_limits(t["phase_deg"])
    out = ((t["phase_deg"] < lo) | (t["phase_deg"] > hi)).to_numpy()
    stepped = 0
    if "dc_step_ratio" in t:
        stepped = int((t["dc_step_ratio"].to_numpy()[out]
                       > result.config.max_dc_step_ratio).sum())
    return int(out.sum()), stepped


def plot_phase(result, *, ax=None):
    """Plot the lag of the axle speed behind the torque per window, with +-2 standard errors.

    The axis is scaled to the body of the data (:func:`phase_limits`); windows beyond it are
    marked at its edge.

    Parameters
    ----------
    result : OnboardResult
        One axle's result.
    ax : matplotlib.axes.Axes or None
        Axes to draw in; None: a new figure's.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn in (position [m] against phase [deg]).
    """
    ax = _axes(ax)
    t = result.track
    x = t["position_m"].to_numpy(dtype=float)
    p = t["phase_deg"].to_numpy(dtype=float)
    se = t["phase_se_deg"].to_numpy(dtype=float)
    lo, hi = phase_limits(p)
    ax.fill_between(x, p - 2 * se, p + 2 * se, color="C2", alpha=0.3, lw=0,
                    label="±2 standard errors")
    ax.plot(x, p, "C2", lw=0.8, label="phase lag per window")
    above, below = p > hi, p < lo
    n, stepped = clipped_phases(result)
    if n:
        why = f", {stepped} with a torque step inside" if stepped else ""
        ax.plot(x[above], np.full(above.sum(), hi), "^", color="C3", ms=5, clip_on=False,
                label=f"{n} windows off the scale{why}")
        ax.plot(x[below], np.full(below.sum(), lo), "v", color="C3", ms=5, clip_on=False)
    _changes(ax, result)
    ax.set_ylim(lo, hi)
    ax.set_xlabel("position [m]")
    ax.set_ylabel("phase lag [deg]")
    ax.grid(True, alpha=0.3)
    ax.legend(**_LEGEND)
    return ax


def plot_utilisation(result, *, ax=None):
    """Plot how much of the adhesion the axle used along the track.

    CoA/mu where mu is determined, else CoA over the lower bound of its segment (an upper
    limit of the utilisation, as the adhesion is at least that bound); the simulated truth,
    CoA over the available adhesion (:func:`torquemod.io.truth.adhesion_utilisation`); the
    ``low_adhesion`` and ``slip`` flags.

    Parameters
    ----------
    result : OnboardResult
        One axle's result.
    ax : matplotlib.axes.Axes or None
        Axes to draw in; None: a new figure's.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn in (position [m] against utilisation [-]).
    """
    ax = _axes(ax)
    t = result.track
    x = t["position_m"].to_numpy(dtype=float)
    seg = result.along_track()
    bound = np.full(len(t), np.nan)
    for _, s in seg.iterrows():
        inside = (x >= s.start_m) & (x <= s.end_m)
        bound[inside] = s.mu_lower_bound
    given = t["mu"].notna().to_numpy()
    with np.errstate(all="ignore"):
        over_bound = np.where(~given & (bound > 0), t["coa"].to_numpy(dtype=float) / bound,
                              np.nan)
    ax.plot(x, over_bound, color="C1", lw=0.8,
            label="CoA / lower bound of its segment (upper limit)")
    if given.any():
        ax.plot(x[given], t["utilisation"].to_numpy(dtype=float)[given], "o", color="C0",
                ms=3, label="CoA / μ where μ is determined")
    if result.truth is not None:
        from torquemod.io.truth import adhesion_utilisation
        tr = result.truth
        ax.plot(tr["position_m"], adhesion_utilisation(tr["coa"], tr["adhesion_peak"]), "k--",
                lw=0.8, label="truth: CoA / available adhesion")
    low = t["low_adhesion"].to_numpy(dtype=bool)
    slip = t["slip"].to_numpy(dtype=bool)
    ax.plot(x[low], np.full(low.sum(), 1.08), "|", color="C3", ms=8,
            label=f"low_adhesion ({100 * low.mean():.1f} % of windows)")
    ax.plot(x[slip], np.full(slip.sum(), 1.14), "|", color="k", ms=8,
            label=f"slip ({100 * slip.mean():.1f} %)")
    _changes(ax, result)
    ax.set_ylim(0, 1.2)
    ax.set_xlabel("position [m]")
    ax.set_ylabel("utilisation [-]")
    ax.grid(True, alpha=0.3)
    ax.legend(**_LEGEND)
    return ax


#: file name, plot function, alt text, caption (the report's figures)
FIGURES = (
    ("mu_along_track.png", plot_mu, "Friction along the track",
     "Friction along the track. Points: μ where the estimator determined it, with its 95 % "
     "interval; orange steps: the lower bound of each segment between detected friction "
     "changes (95th percentile of its windows' bounds: the friction is above it); dashed "
     "blue steps: the segment's median μ; grey: the adhesion each window used (CoA); dotted "
     "verticals: detected friction changes."),
    ("phase_along_track.png", plot_phase, "Phase lag along the track",
     "Phase lag of the axle speed behind the modulated torque per window (band: ±2 "
     "standard errors), scaled to the body of the data; triangles at the edge mark windows "
     "off the scale."),
    ("utilisation_along_track.png", plot_utilisation, "Utilisation of the adhesion",
     "How much of the adhesion the axle used: CoA/μ where μ is determined; elsewhere CoA "
     "over its segment's lower bound, an upper limit of the utilisation. Ticks at the top: "
     "windows flagged low_adhesion (red) and slip (black)."),
)


def write_figures(folder: Path, result) -> list[dict]:
    """Save the report's figures (:data:`FIGURES`) as PNG in a folder.

    Parameters
    ----------
    folder : pathlib.Path
        Where the PNG files go.
    result : OnboardResult
        One axle's result.

    Returns
    -------
    list of dict
        One per figure, for the report: ``png`` (bytes), ``alt`` and ``caption``.
    """
    import io
    out = []
    for name, fn, alt, caption in FIGURES:
        ax = fn(result)
        buf = io.BytesIO()
        ax.figure.savefig(buf, format="png", dpi=110)
        png = buf.getvalue()
        (folder / name).write_bytes(png)
        if fn is plot_phase:
            n, stepped = clipped_phases(result)
            if n:
                caption += (f" {n} windows lie off the scale"
                            + (f", {stepped} of them with a torque step inside the window "
                               "(the step, not the modulation, dominates their phase)"
                               if stepped else "") + ".")
        if fn is plot_utilisation and result.truth is not None:
            caption += " Dashed: the simulated truth, CoA over the available adhesion."
        if fn is plot_mu and result.truth is not None:
            caption += " Black: the simulated truth (dashed friction, dotted available adhesion)."
        out.append({"png": png, "alt": alt, "caption": caption, "file": name})
    return out


def segment_estimates(track, segments: list[dict]) -> list[dict]:
    """Each truth segment with the estimate over the track's rows inside it.

    Uses the along-track rules of :mod:`torquemod.ontrain.alongtrack`.

    Parameters
    ----------
    track : pandas.DataFrame
        The track (``track.parquet`` columns).
    segments : list of dict
        The truth's segments (:func:`torquemod.io.truth.segment_summary`), with ``start_m``
        and ``end_m`` [m].

    Returns
    -------
    list of dict
        Each segment with ``mu_estimate`` [-] (median where mu is determined, else None),
        ``mu_lower_bound`` [-] (95th percentile of the bounds where it is not; None when mu is
        determined everywhere) and ``mu_given_share`` [-].
    """
    from torquemod.ontrain.alongtrack import summarise
    out = []
    for seg in segments:
        part = track[(track.position_m >= seg["start_m"]) & (track.position_m <= seg["end_m"])]
        s = summarise(part)
        out.append({**seg, "mu_estimate": s["mu"] if math.isfinite(s["mu"]) else None,
                    "mu_lower_bound": s["mu_lower_bound"]
                    if math.isfinite(s["mu_lower_bound"]) else None,
                    "mu_given_share": s["mu_given_share"]})
    return out


def headline(result) -> list[str]:
    """The run and its summary in a few lines of text.

    Parameters
    ----------
    result : OnboardResult
        One axle's result.

    Returns
    -------
    list of str
        The lines.
    """
    s = result.summary()
    v = result.run.vehicle
    lines = [f"Run {result.run.manifest_path}, axle {result.axle}: wheel radius "
             f"{v.wheel_radius_m} m, axle load {v.normal_load_n:.0f} N, inertia "
             f"{v.inertia_kg_m2} kg m²; modulation {result.run.modulation_frequency_hz} Hz, "
             f"{result.run.modulation_amplitude_nm} N m.",
             f"{s['windows']} windows over {s['length_m']:.0f} m, measurable (the torque "
             "modulated, the train rolling forward) in "
             f"{100 * s.get('measurable_share', 1.0):.0f} %; μ determined in "
             f"{100 * s['mu_given_share']:.0f} % of them (elsewhere a lower bound: the data "
             "fix μ only where the axle works near saturation); "
             f"{len(result.changes_m)} friction changes detected; low adhesion flagged in "
             f"{100 * s['low_adhesion_share']:.1f} %, slip in {100 * s['slip_share']:.1f} %."]
    return lines


_STRETCH_HEADERS = (("start_m", "from [m]"), ("end_m", "to [m]"), ("windows", "windows"),
                    ("condition", "condition (guess)"), ("mu", "μ (median)"),
                    ("mu_low_95", "μ 95 % low"), ("mu_high_95", "μ 95 % high"),
                    ("mu_given_share", "μ given [%]"), ("mu_lower_bound", "lower bound"),
                    ("low_adhesion_share", "low_adhesion [%]"),
                    ("coa_reached", "CoA reached"), ("probe_depth", "probe depth [%]"))


def along_track_html(seg, caption: str | None = None) -> str:
    """The along-track table (:func:`torquemod.ontrain.alongtrack.along_track`) as HTML.

    Parameters
    ----------
    seg : pandas.DataFrame
        The table.
    caption : str or None
        The table's caption. Default None.

    Returns
    -------
    str
        An HTML ``<table>``.
    """
    rows = []
    for _, s in seg.iterrows():
        row = []
        for key, _label in _STRETCH_HEADERS:
            v = s[key]
            if key in ("start_m", "end_m"):
                row.append(f"{v:.0f}")
            elif key == "windows":
                row.append(int(v))
            elif key == "condition":
                row.append(str(v))
            elif key in ("mu_given_share", "low_adhesion_share", "probe_depth"):
                row.append("—" if not math.isfinite(v) else f"{100 * v:.0f}")
            else:
                row.append("—" if not math.isfinite(v) else f"{v:.3f}")
        rows.append(row)
    return ('<div class="wrap">' + table([h for _, h in _STRETCH_HEADERS], rows,
                                         caption=caption, left=0) + "</div>")


def _segments_table(result) -> str:
    tr = result.truth
    if tr is None:
        return ""
    from torquemod.io.truth import segment_summary
    rows = []
    for s in segment_estimates(result.track, segment_summary(tr)):
        rows.append([s["condition"], f"{s['start_m']:.0f}–{s['end_m']:.0f}", f"{s['mu']:.3f}",
                     f"{s['adhesion_peak']:.3f}",
                     "not determined" if s["mu_estimate"] is None else f"{s['mu_estimate']:.3f}",
                     "—" if s["mu_lower_bound"] is None else f"{s['mu_lower_bound']:.3f}",
                     f"{100 * s['mu_given_share']:.0f}"])
    return ("<h2>Against the simulated truth</h2>"
            + table(["condition", "span [m]", "friction μ", "available adhesion",
                     "μ estimated (median)", "lower bound", "windows with μ [%]"], rows,
                    left=1))


def segment_fits_html(result) -> str:
    """The per-segment fit (``segments.csv``) as HTML.

    The available adhesion where determined, else the best fit, its 95 % interval and the
    lower bound (:meth:`~torquemod.ontrain.OnboardResult.segment_table`).

    Parameters
    ----------
    result : OnboardResult
        One axle's result.

    Returns
    -------
    str
        An HTML table; empty when there are no segments.
    """
    segs = result.segment_table()
    if not len(segs):
        return ""

    def num(v):
        return "—" if not math.isfinite(v) else f"{v:.3f}"

    rows = [[int(r["segment"]), f"{r['start_m']:.0f}–{r['end_m']:.0f}", int(r["windows"]),
             num(r["coa_reached"]), num(r["adhesion_available"]),
             num(r["adhesion_available_best_fit"]),
             f"{num(r['adhesion_available_low_95'])}–"
             + ("open" if not math.isfinite(r["adhesion_available_high_95"])
                else num(r["adhesion_available_high_95"])),
             num(r["adhesion_available_lower_bound"]), "yes" if r["determined"] else "no",
             "—" if not math.isfinite(r["probe_depth_needed"])
             else f"{100 * r['probe_depth_needed']:.0f}"]
            for _, r in segs.iterrows()]
    return ('<div class="wrap">' + table(
        ["segment", "span [m]", "windows", "CoA reached", "available adhesion",
         "best fit", "95 % interval", "lower bound", "determined",
         "probe depth needed [%]"], rows,
        caption="Available adhesion per segment, fitted from all its windows once it ended "
                "(segments.csv)", left=0) + "</div>")


def _delay_sentence(result, s: dict) -> str:
    """What the report says about the torque-speed delay (declared and measured)."""
    v = result.run.vehicle
    declared = (f"declared: torque lag {1e3 * v.torque_lag_s:g} ms, torque delay "
                f"{1e3 * v.torque_delay_s:g} ms, speed delay {1e3 * v.speed_delay_s:g} ms, "
                f"vehicle damping {v.vehicle_damping_n_s_m:g} N*s/m")
    if not result.config.calibrate_delay:
        return f"Sensor dynamics {declared}; no delay measured (calibrate_delay = 0)."
    d = s.get("measured_delay_s", 0.0)
    if d == 0.0:
        return (f"Sensor dynamics {declared}; the run did not determine a further delay "
                "between torque and speed (none taken out).")
    return (f"Sensor dynamics {declared}; a further net delay of the torque behind the "
            f"speed of {1e3 * d:.2f} ms was measured from the run and taken out of the "
            "phase and creep coefficient.")


#: the on-board report's additions to the shared stylesheet: the along-track tables' headers
#: wrap (their numbers stay whole), so that the tables fit the page
_CSS = ".wrap th{white-space:normal;vertical-align:bottom}"


def _rules() -> str:
    from torquemod.ontrain.alongtrack import DRY_MIN, WET_MIN
    return (f"<p>Per stretch: μ is the median over the windows where the estimator "
            "determined it (with the medians of their 95 % interval ends); the lower bound "
            "is the 95th percentile of the other windows' bounds (CoA less two standard "
            "errors: the adhesion, and so the friction, is at least that); CoA reached is "
            "the 95th percentile of the windows' CoA and the probe depth that over μ. The "
            "condition guess names the service classes the available adhesion may lie in "
            f"between the lower bound and μ's upper interval end: dry from {DRY_MIN}, wet "
            f"from {WET_MIN}, low adhesion below (limits midway between the service ranges "
            "dry 0.3–0.4+, wet 0.15–0.22, leaf layers below 0.05–0.10; Lewis et al., "
            "Tribology International 185 (2023) 108529); “not probed” where the axle never "
            "worked hard enough to tell; “mixed” where a stretch holds different rails (its "
            "lower bound lies above μ's interval: a kilometre across a friction change).</p>")


def write_report(path: Path, result, meta: dict, figures: list[dict]) -> None:
    """Write the HTML report of one axle.

    The run, the summary, the friction along the track per segment and per kilometre, the
    figures, the notes and the settings.

    Parameters
    ----------
    path : pathlib.Path
        The HTML file to write.
    result : OnboardResult
        One axle's result.
    meta : dict
        The provenance (``onboard.json``'s content) shown in the report.
    figures : list of dict
        The figures (:func:`write_figures`).
    """
    s = result.summary()
    notes = "".join(f"<li>{escape(n)}</li>" for n in result.notes) or "<li>none</li>"
    warns = "".join(f'<p class="warn">{escape(w)}</p>' for w in result.warnings)
    imgs = "".join(figure_html(f["png"], f["alt"], f"Figure {i}: {f['caption']}")
                   for i, f in enumerate(figures, 1))
    head = "".join(f"<p>{escape(line)}</p>" for line in headline(result))
    others = [a for a in meta.get("axles", []) if a.get("axle") != result.axle]
    if others:
        head += ("<p>" + escape(f"This report shows axle {result.axle}; the run's other axles "
                                "are in " + ", ".join(a.get("track_file", "?") for a in others)
                                + " and their along_track_axle<N>.csv.") + "</p>")
    seg, km = result.along_track(), result.along_track("km")
    settings = definition_list(sorted(
        (k, ", ".join(str(x) for x in v) if isinstance(v, list) else v)
        for k, v in meta["onboard"].items()))
    body = f"""<!doctype html><html><head><meta charset="utf-8">
<title>torquemod on-board: {escape(result.run.manifest_path.name)}</title>
<style>{CSS}{_CSS}</style></head><body>
<h1>Friction along the run</h1>
{head}
{warns}
<p>{escape(_delay_sentence(result, s))}</p>
<h2>Along the track</h2>
{along_track_html(seg, "Per segment between detected friction changes (along_track.csv)")}
{along_track_html(km, "Per kilometre (along_track_km.csv)")}
{segment_fits_html(result)}
{_rules()}
{_segments_table(result)}
<h2>Figures</h2>{imgs}
<h2>Notes</h2><ul>{notes}</ul>
<h2>Settings</h2>{settings}
<p>torquemod {escape(meta['torquemod_version'])}, {escape(meta['created_utc'])}.</p>
</body></html>"""
    path.write_text(body, encoding="utf-8")
