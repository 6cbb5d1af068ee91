"""Figures of a rig sweep (matplotlib; every function takes ``ax=`` and returns it, or draws
on a new Figure (not pyplot) and returns its Axes (several panels: an array of them), as
:mod:`torquemod.report.figures` does; never ``plt.show``).

The sweep is drawn per *condition* (:mod:`torquemod.sweep.conditions`: one distinct
combination of the swept parameters other than the modulation setting):

* :func:`phase_panels_figure` -- the phase against utilisation, one panel per condition and
  one curve per modulation frequency (the paper's Fig. 4 per condition), or one panel per
  frequency and one curve per condition (the conditions compared at each frequency); lines
  the large-signal theory, dotted the rigid-wheel small-signal model of the paper's Eq. (1),
  ``tan(phi) = Omega*J*V/(R^2*N*k)``, markers the processing chain, crosses where the wheel
  slipped,
* :func:`creep_curves_figure` -- each condition's adhesion-creepage curve at its operating
  speed with its peak (the available adhesion) and the operating points of the steps,
* :func:`sensitivity_figure` -- ``dphi/du`` in the 50-80 % band against the frequency, one
  series per condition,
* :func:`mu_error_figure` -- the mu-from-phase error per condition, the modulation settings
  side by side (markers only: the conditions are categories),
* :func:`disturbance_figure` -- creepage swing and torque ripple of each modulation setting.
"""

from __future__ import annotations

import textwrap

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter, NullFormatter

from torquemod._util.mpl import figure_axes, legend_width_in, place_axes
from torquemod.analysis.creep import phase_from_constant_deg
from torquemod.sweep.conditions import CONDITION_COLUMN
from torquemod.sweep.summary import BAND, slipped_mask

__all__ = ["creep_curves_figure", "disturbance_figure", "mu_error_figure",
           "phase_panels_figure", "sensitivity_figure", "slipped_mask", "small_signal_deg"]

FREQ = "modulation_frequency_nominal_hz"
AMP = "modulation_amplitude_nm"
_MARKERS = "osD^vPXh*p"
_LINES = ("-", "--", "-.", ":")
#: marker of a step where the wheel slipped
SLIP_MARKER = "x"


def _cmap_colour(i: int, n: int):
    if n <= 10:
        return f"C{i % 10}"
    from matplotlib import colormaps
    return colormaps["tab20"](i % 20)


def small_signal_deg(df: pd.DataFrame) -> np.ndarray:
    """Phase of the rigid-wheel small-signal model at each row's creep coefficient.

    Eq. (1) of [1]_, ``tan(phi) = Omega*J*V/(R^2*N*k)`` (its constant
    ``Omega*J*V/(R^2*N)`` is the table's ``theory_constant``).

    Parameters
    ----------
    df : pandas.DataFrame
        Rows with ``theory_constant`` [-] and ``creep_coefficient`` [-].

    Returns
    -------
    ndarray
        Phase [deg].

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1).
    """
    return phase_from_constant_deg(df["theory_constant"].to_numpy(float),
                                   df["creep_coefficient"].to_numpy(float))


def _label_value(key: str, value) -> str:
    if key == FREQ:
        return f"{value:.3g} Hz"
    if key == AMP:
        return f"{value:.3g} N*m"
    return str(value) or "all points"


def _panel_grid(n: int, ax, *, width=5.0, height=3.6, cols_max=2):
    """``(fig, axes)``: ``n`` panels in up to ``cols_max`` columns (unused ones hidden), or
    the given Axes (one or a sequence)."""
    if ax is not None:
        axes = list(np.atleast_1d(ax))
        return axes[0].figure, axes
    cols = max(1, min(n, cols_max))
    rows = int(np.ceil(n / cols))
    fig = Figure(figsize=(width * cols, height * rows + 0.9))
    axes = list(np.atleast_1d(fig.subplots(rows, cols, squeeze=False).ravel()))
    for extra in axes[n:]:
        extra.set_visible(False)
    return fig, axes[:n]


#: height of a row of a figure legend at 7 pt, markers up to 11 pt included [in]
_LEGEND_ROW_IN = 0.2


def _panel_legend(fig, axes, ax, handles: list, title: str = "") -> None:
    """The figure legend below the panels (up to four columns) and the title above them;
    on a figure of :func:`_panel_grid` (``ax`` None) the panels are placed with fixed
    margins that leave room for both (no layout engine: the figure is drawn once)."""
    ncol = min(len(handles), 4)
    height = fig.get_size_inches()[1]
    fig.legend(handles=handles, loc="lower center", bbox_to_anchor=(0.5, 0.04 / height),
               ncol=ncol, fontsize=7, frameon=False, borderaxespad=0.0)
    if title:
        fig.suptitle(title, fontsize=10, y=1 - 0.08 / height, va="top")
    if ax is None:
        rows, cols = axes[0].get_subplotspec().get_gridspec().get_geometry()
        legend_rows = -(-len(handles) // max(ncol, 1))
        place_axes(fig, rows=rows, cols=cols, left=0.7, right=0.15,
                   top=0.55 if title else 0.35, bottom=0.62 + legend_rows * _LEGEND_ROW_IN,
                   wspace=0.7, hspace=0.75)


def _drawn(axes, ax):
    """What a figure function returns: the ``ax`` it was given, else the new Figure's Axes
    (an array when it holds several panels, one Axes otherwise)."""
    if ax is not None:
        return ax
    axes = np.asarray(axes, dtype=object).ravel()
    return axes[0] if axes.size == 1 else axes


#: the columns a progression draws (:func:`_draw_progression`)
_PROGRESSION_COLUMNS = ("utilisation", "phase_theory_deg", "phase_deg", "phase_se_deg",
                        "theory_constant", "creep_coefficient")


def _progression_columns(table: pd.DataFrame) -> dict:
    """The columns of ``table`` that progressions draw, as float arrays taken once (a
    progression then selects its rows by position), with ``theory_slipped`` (the theory's
    ``slipped``) and ``slipped`` (:func:`slipped_mask`) as bool arrays."""
    cols = {k: table[k].to_numpy(float) for k in _PROGRESSION_COLUMNS if k in table}
    cols["theory_slipped"] = table["slipped"].eq(True).to_numpy()
    cols["slipped"] = slipped_mask(table).to_numpy()
    return cols


def _ascending(values: np.ndarray) -> np.ndarray:
    """Positions of ``values`` in ascending order, NaN last (as ``DataFrame.sort_values``
    orders them: quicksort over the numbers)."""
    nan = np.isnan(values)
    idx = np.arange(values.size)
    return np.concatenate([idx[~nan][np.argsort(values[~nan], kind="quicksort")], idx[nan]])


def _draw_progression(ax, cols: dict, rows: np.ndarray, color, slot: int = 0) -> None:
    """One progression (the steps of one point, rows ``rows`` of the arrays ``cols`` of
    :func:`_progression_columns`): large-signal theory (line), Eq. (1) (dotted), the chain
    (markers, 95 % bars) and crosses at the steps where the wheel slipped: at the chain's
    phase, else on the theory's curve, else (the theory has no periodic state there
    either) near the top of the axes, in one of four rows by ``slot`` so that the crosses
    of several curves at one step stay apart."""
    rows = rows[_ascending(cols["utilisation"][rows])]
    theory = rows[~cols["theory_slipped"][rows]]
    u = 100 * cols["utilisation"][theory]
    ax.plot(u, cols["phase_theory_deg"][theory], "-", color=color, lw=1.4)
    if "theory_constant" in cols and "creep_coefficient" in cols:
        ax.plot(u, phase_from_constant_deg(cols["theory_constant"][theory],
                                           cols["creep_coefficient"][theory]),
                ":", color=color, lw=1.1)
    slip = cols["slipped"][rows]
    live = rows[~slip]
    phase = cols["phase_deg"][live]
    if (~np.isnan(phase)).any():
        se = cols["phase_se_deg"][live]
        ax.errorbar(100 * cols["utilisation"][live], phase,
                    yerr=1.96 * np.where(np.isnan(se), 0.0, se), fmt="o", ms=3.5,
                    color=color, capsize=2, ls="none")
    gone = rows[slip]
    if len(gone):
        y = cols["phase_deg"][gone]
        y = np.where(np.isfinite(y), y, cols["phase_theory_deg"][gone])
        on = np.isfinite(y)
        x = 100 * cols["utilisation"][gone]
        ax.plot(x[on], y[on], SLIP_MARKER, color=color, ms=8, mew=2)
        if (~on).any():
            ax.plot(x[~on], np.full(int((~on).sum()), 0.96 - 0.04 * (slot % 4)), SLIP_MARKER,
                    color=color,
                    ms=8, mew=2, transform=ax.get_xaxis_transform(), clip_on=False)


def _style_handles(table: pd.DataFrame) -> list:
    """Legend entries for what lines, dotted lines, markers and crosses are."""
    h = [Line2D([], [], color="0.3", lw=1.4, label="large-signal theory"),
         Line2D([], [], color="0.3", ls=":", lw=1.1,
                label="Eq. (1): tan φ = ΩJV/(R²Nk)")]
    if table["phase_deg"].notna().any():
        h.append(Line2D([], [], color="0.3", marker="o", ms=3.5, ls="",
                        label="twin + chain (95 %)"))
    if slipped_mask(table).any():
        h.append(Line2D([], [], color="0.3", marker=SLIP_MARKER, ms=8, mew=2, ls="",
                        label="wheel slipped (on the theory; at the top: no periodic state)"))
    h.append(Line2D([], [], color="0.85", lw=6,
                    label=f"dφ/du band {100 * BAND[0]:.0f}-{100 * BAND[1]:.0f} %"))
    return h


def phase_panels_figure(table: pd.DataFrame, *, panel: str = CONDITION_COLUMN,
                        curve: str = FREQ, panels=None, title: str = "", ax=None):
    """The phase against utilisation, one panel per value of a column.

    Parameters
    ----------
    table : pandas.DataFrame
        The rows to draw (one modulation amplitude and seed: the caller's selection), with a
        ``condition`` column.
    panel : str
        The column with one panel per value. Default the condition.
    curve : str
        The column with one colour per value. Default the modulation frequency.
    panels : sequence or None
        Selects and orders the panels. Default None (all).
    title : str
        The figure's title. Default "".
    ax : matplotlib.axes.Axes or None
        Axes to draw in; None: a new figure.

    Returns
    -------
    matplotlib.axes.Axes or ndarray of Axes
        ``ax`` as given, else the new figure's Axes (an array when it holds several panels).
    """
    values = list(dict.fromkeys(table[panel])) if panels is None else list(panels)
    curves = list(dict.fromkeys(table[curve]))
    fig, axes = _panel_grid(len(values), ax, **({"cols_max": 3, "width": 4.4}
                                                 if len(values) > 4 else {}))
    cols = _progression_columns(table)
    # the rows of each (panel, curve, point) by position, the points in table order
    groups = table.groupby([panel, curve, "point_id"], sort=False).indices
    for a, value in zip(axes, values, strict=False):
        for j, cv in enumerate(curves):
            for (p, c, _), rows in groups.items():
                if p == value and c == cv:
                    _draw_progression(a, cols, rows, _cmap_colour(j, len(curves)), slot=j)
        a.axvspan(100 * BAND[0], 100 * BAND[1], color="0.9", zorder=0)
        a.set_title(_label_value(panel, value), fontsize=9)
        a.set_xlabel("utilisation CoA/μ [%]")
        a.set_ylabel("phase lag [deg]")
        a.set_xlim(-3, 103)
        a.grid(True, alpha=0.3)
    handles = [Line2D([], [], color=_cmap_colour(j, len(curves)), lw=2,
                      label=_label_value(curve, cv)) for j, cv in enumerate(curves)]
    handles += _style_handles(table)
    _panel_legend(fig, axes, ax, handles, title)
    return _drawn(axes, ax)


def creep_curves_figure(curves: dict, table: pd.DataFrame, *, ax=None):
    """Per condition the adhesion-creepage curve, its peak and the steps' operating points.

    The longitudinal curve ``F_x/N`` at the operating speed [1]_, its peak -- the available
    adhesion, the true mu of the sweep -- and the steady operating points of the steps
    (``T_dc/(R*N)``); in full mode also the chain's measured points, coloured by modulation
    frequency.

    Parameters
    ----------
    curves : dict
        Condition label -> ``(creepage [-], F_x/N [-], peak creepage [-], peak [-])``.
    table : pandas.DataFrame
        The sweep table with a ``condition`` column.
    ax : matplotlib.axes.Axes or None
        Axes to draw in; None: a new figure.

    Returns
    -------
    matplotlib.axes.Axes or ndarray of Axes
        ``ax`` as given, else the new figure's Axes (an array when it holds several panels).

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
    """
    labels = list(curves)
    fig, axes = _panel_grid(len(labels), ax, height=3.2, cols_max=3, width=4.2)
    freqs = list(dict.fromkeys(table[FREQ])) if FREQ in table else []
    for a, label in zip(axes, labels, strict=False):
        xi, coa, xi_peak, peak = curves[label]
        a.plot(100 * xi, coa, "-", color="0.2", lw=1.4)
        a.plot(100 * xi_peak, peak, "*", color="C3", ms=11)
        a.annotate(f"μ = {peak:.3f}", (100 * xi_peak, peak), textcoords="offset points",
                   xytext=(-8, -14), ha="right", fontsize=7, color="C3")
        part = table[table[CONDITION_COLUMN] == label]
        left = 1e-3  # [%]
        if len(part):
            ref = part[part["point_id"] == part["point_id"].iloc[0]]
            ok = ref[~slipped_mask(ref) & (ref["creepage_true"] > 0)]
            if len(ok):
                left = max(left, 50 * float(ok["creepage_true"].min()))
            a.plot(100 * ok["creepage_true"], ok["utilisation"] * ok["mu_true"], "o",
                   mfc="white", mec="0.2", ms=5, zorder=3)
            for j, f in enumerate(freqs):
                meas = part[(part[FREQ] == f) & ~slipped_mask(part)]
                meas = meas[meas["creepage"] > 0] if "creepage" in meas else meas
                if "coa" in meas and meas["coa"].notna().any():
                    a.plot(100 * meas["creepage"], meas["coa"], ".",
                           color=_cmap_colour(j, len(freqs)), ms=5, zorder=4)
        a.set_title(label or "all points", fontsize=9)
        a.set_xscale("log")
        a.set_xlim(left, 100 * xi[-1])
        # plain numbers on the major ticks, none on the minor ones (they overlap when the
        # range is under a decade)
        a.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        a.xaxis.set_minor_formatter(NullFormatter())
        a.set_xlabel("creepage [%] (log)")
        a.set_ylabel("F_x / N [-]")
        a.set_ylim(bottom=0)
        a.grid(True, alpha=0.3)
    handles = [Line2D([], [], color="0.2", lw=1.4, label="creep curve at the speed"),
               Line2D([], [], color="C3", marker="*", ms=11, ls="",
                      label="peak: available adhesion (true μ)"),
               Line2D([], [], color="0.2", marker="o", mfc="white", ms=5, ls="",
                      label="steady operating points of the steps (creepage > 0)")]
    if "coa" in table and table["coa"].notna().any():
        handles += [Line2D([], [], color=_cmap_colour(j, len(freqs)), marker=".", ls="",
                           ms=7, label=f"chain at {f:.3g} Hz") for j, f in enumerate(freqs)]
    _panel_legend(fig, axes, ax, handles)
    return _drawn(axes, ax)


def _place_single(fig, legend=None, *, tick_lines: int = 1, left: float = 0.8,
                  hspace: float = 0.25) -> None:
    """Fixed margins of a figure of stacked axes with a title: room at the right for a
    legend beside the axes, at the bottom for ``tick_lines`` lines of 7 pt category labels
    (1: numeric ticks)."""
    rows = len([a for a in fig.axes if a.get_visible()])
    right = 0.25 + (legend_width_in(legend) if legend is not None else 0.0)
    place_axes(fig, rows=rows, left=left, right=right, top=0.35,
               bottom=0.55 + 0.11 * max(tick_lines - 1, 0), hspace=hspace)


def _lines(labels) -> int:
    return max([str(t).count("\n") + 1 for t in labels] or [1])


def _wrap(label: str, width: int = 22) -> str:
    return "\n".join(textwrap.wrap(label, width, break_long_words=False)) or "all points"


def sensitivity_figure(summary: pd.DataFrame, *, ax=None):
    """The slope dphi/du of the phase over the 50-80 % utilisation band [deg per %].

    Against the modulation frequency, one colour per condition and one line style per
    amplitude (large-signal theory: lines; chain: markers). With a single frequency the
    conditions are the x axis (categories: markers only).

    Parameters
    ----------
    summary : pandas.DataFrame
        The point summary (:func:`torquemod.sweep.summary.point_summary`).
    ax : matplotlib.axes.Axes or None
        Axes to draw in; None: a new figure.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn in.
    """
    new = ax is None
    fig, ax = figure_axes(ax, figsize=(7.5, 4.6), layout=None)
    conds = list(dict.fromkeys(summary[CONDITION_COLUMN]))
    ticks = None
    amps = list(dict.fromkeys(summary[AMP]))
    chain = summary["dphi_du_chain"].notna().any()
    handles = []
    if summary[FREQ].nunique() > 1:
        for i, c in enumerate(conds):
            col = _cmap_colour(i, len(conds))
            for k, a in enumerate(amps):
                g = summary[(summary[CONDITION_COLUMN] == c) & (summary[AMP] == a)]
                g = g.groupby(FREQ, sort=True)[["dphi_du_theory", "dphi_du_chain"]].mean()
                ax.plot(g.index, g["dphi_du_theory"], ls=_LINES[k % 4], color=col, lw=1.3)
                if chain:
                    ax.plot(g.index, g["dphi_du_chain"], _MARKERS[k % 10], color=col, ms=5)
            handles.append(Line2D([], [], color=col, lw=2, label=c or "all points"))
        ax.set_xlabel("modulation frequency [Hz]")
    else:
        x = np.arange(len(conds))
        for k, a in enumerate(amps):
            dx = 0.12 * (k - (len(amps) - 1) / 2)
            g = summary[summary[AMP] == a].groupby(CONDITION_COLUMN, sort=False)[
                ["dphi_du_theory", "dphi_du_chain"]].mean().reindex(conds)
            ax.plot(x + dx, g["dphi_du_theory"], "_", color=f"C{k}", ms=14, mew=2)
            if chain:
                ax.plot(x + dx, g["dphi_du_chain"], _MARKERS[k % 10], color=f"C{k}", ms=5)
        ticks = [_wrap(c) for c in conds]
        ax.set_xticks(x, ticks, fontsize=7)
        ax.set_xlabel("condition")
    if len(amps) > 1 or summary[FREQ].nunique() <= 1:
        handles += [Line2D([], [], color="0.35" if summary[FREQ].nunique() > 1 else f"C{k}",
                           ls=_LINES[k % 4], marker=_MARKERS[k % 10],
                           label=f"amplitude {a:.3g} N*m") for k, a in enumerate(amps)]
    what = "lines: theory" if summary[FREQ].nunique() > 1 else "bars: theory"
    ax.set_ylabel(f"dφ/du, {BAND[0]:.0%}-{BAND[1]:.0%} [deg per %]")
    ax.set_title(f"sensitivity of the phase to the utilisation ({what}"
                 + (", markers: chain)" if chain else ")"), fontsize=9)
    ax.grid(True, alpha=0.3)
    legend = (ax.legend(handles=handles, fontsize=7, loc="upper left",
                        bbox_to_anchor=(1.01, 1.0)) if handles else None)
    if new:
        _place_single(fig, legend, tick_lines=_lines(ticks or []))
    return ax


def mu_error_figure(summary: pd.DataFrame, *, ax=None):
    """mu from the phase relative to the true mu (the available adhesion) [%], per condition.

    The modulation settings side by side (colour: frequency, marker: amplitude): filled with
    the 95 % interval where mu is determined, open at the lower bound where it is not.

    Parameters
    ----------
    summary : pandas.DataFrame
        The point summary.
    ax : matplotlib.axes.Axes or None
        Axes to draw in; None: a new figure.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn in.
    """
    conds = list(dict.fromkeys(summary[CONDITION_COLUMN]))
    new = ax is None
    fig, ax = figure_axes(ax, figsize=(max(7.5, 1.3 * len(conds) + 3.0), 4.8), layout=None)
    freqs = sorted(dict.fromkeys(summary[FREQ]))
    amps = list(dict.fromkeys(summary[AMP]))
    settings = [(f, a) for f in freqs for a in amps
                if ((summary[FREQ] == f) & (summary[AMP] == a)).any()]
    width = 0.8 / max(len(settings), 1)
    x0 = {c: i for i, c in enumerate(conds)}
    for j, (f, a) in enumerate(settings):
        g = summary[(summary[FREQ] == f) & (summary[AMP] == a)]
        x = g[CONDITION_COLUMN].map(x0).to_numpy(float) + width * (j - (len(settings) - 1) / 2)
        det = g["mu_phase_determined"].astype(bool).to_numpy()
        y = g["mu_phase_error_pct"].to_numpy(float)
        lo = g["mu_phase_lo_error_pct"].to_numpy(float)
        hi = g["mu_phase_hi_error_pct"].to_numpy(float)
        col, m = _cmap_colour(freqs.index(f), len(freqs)), _MARKERS[amps.index(a) % 10]
        if det.any():
            ax.errorbar(x[det], y[det], yerr=[y[det] - lo[det], hi[det] - y[det]], fmt=m,
                        color=col, capsize=2, ms=5, ls="none")
        if (~det).any():
            ax.plot(x[~det], lo[~det], m, mfc="none", color=col, ms=7, ls="none")
    for i in range(1, len(conds)):
        ax.axvline(i - 0.5, color="0.85", lw=0.8)
    ax.axhline(0.0, color="k", lw=0.8)
    ticks = [_wrap(c) for c in conds]
    ax.set_xticks(range(len(conds)), ticks, fontsize=7)
    ax.set_xlim(-0.5, len(conds) - 0.5)
    ax.set_xlabel("condition")
    ax.set_ylabel("μ from phase / available adhesion − 1 [%]")
    ax.set_title("μ-from-phase error per condition (filled: determined, 95 %; open: lower "
                 "bound)", fontsize=9)
    ax.grid(True, axis="y", alpha=0.3)
    handles = [Line2D([], [], color=_cmap_colour(i, len(freqs)), marker="s", ls="",
                      label=f"{f:.3g} Hz") for i, f in enumerate(freqs)]
    if len(amps) > 1:
        handles += [Line2D([], [], color="0.35", marker=_MARKERS[k % 10], ls="",
                           label=f"{a:.3g} N*m") for k, a in enumerate(amps)]
    handles.append(Line2D([], [], color="0.35", marker="o", mfc="none", ls="",
                          label="lower bound (μ not determined)"))
    legend = ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    if new:
        _place_single(fig, legend, tick_lines=_lines(ticks))
    return ax


def disturbance_figure(settings: pd.DataFrame, limits: dict, *, ax=None,
                       ripple_label: str = "torque ripple [% of Ts]",
                       title: str = "disturbance added by the modulation (largest below the "
                                    "utilisation limit; dashed: limits)"):
    """Per modulation setting the largest creepage swing and torque ripple, with the limits.

    Below the utilisation limit; the limits dashed.

    Parameters
    ----------
    settings : pandas.DataFrame
        One row per setting (:func:`torquemod.sweep.summary.setting_table`).
    limits : dict
        The ``[recommend]`` limits.
    ax : matplotlib.axes.Axes or None
        Axes to draw in; None: a new figure.
    ripple_label : str
        Label of the ripple axis. Default "torque ripple [% of Ts]".
    title : str
        The figure's title.

    Returns
    -------
    matplotlib.axes.Axes or ndarray of Axes
        ``ax`` as given, else the new figure's Axes (an array when it holds several panels).
    """
    fig, axes = figure_axes(ax, 2, figsize=(7.0, 5.5), layout=None)
    label = [f"{f:.3g} Hz\n{a:.3g} N*m" for f, a in zip(
        settings["modulation_frequency_nominal_hz"], settings["modulation_amplitude_nm"],
        strict=True)]
    x = np.arange(len(label))
    axes[0].bar(x, settings["creepage_swing_max"], color="C0")
    axes[0].axhline(limits["max_creepage_swing"], color="k", ls="--", lw=0.8)
    axes[0].set_ylabel("creepage swing [-]")
    axes[1].bar(x, settings["torque_ripple_pct_max"], color="C1")
    axes[1].axhline(limits["max_torque_ripple_pct"], color="k", ls="--", lw=0.8)
    axes[1].set_ylabel(ripple_label)
    axes[1].set_xticks(x, label, fontsize=7)
    axes[0].set_title(title, fontsize=9)
    if ax is None:
        _place_single(fig, tick_lines=_lines(label), left=0.9, hspace=0.15)
    return _drawn(axes, ax)
