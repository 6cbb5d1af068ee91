"""Figures of a sweep (matplotlib; every function takes ``ax=`` and returns it, or draws on
a new Figure (not pyplot) and returns its Axes, as :mod:`torquemod.report.figures` does;
never ``plt.show``).

* :func:`phase_family_figure` -- phase against utilisation, one curve per value of a swept
  parameter, the other swept parameters at their reference values (the paper's Fig. 4 as a
  family),
* :func:`phase_panels_figure` -- one such family per value of another parameter (Fig. 4 per
  friction condition),
* :func:`sensitivity_figure` -- ``dphi/du`` in the 50-80 % band against a parameter,
* :func:`mu_error_figure` -- the mu-from-phase error against a parameter,
* :func:`disturbance_figure` -- creepage swing and torque ripple of each modulation setting.

The reference value of a swept parameter is its value at the sweep's first point.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from ..report.figures import _axes
from .summary import BAND

__all__ = ["disturbance_figure", "mu_error_figure", "phase_family_figure",
           "phase_panels_figure", "reference_slice", "sensitivity_figure"]


def _is_numeric(values) -> bool:
    return all(isinstance(v, int | float | np.integer | np.floating)
               and not isinstance(v, bool) for v in values)


def _positions(values) -> tuple[np.ndarray, list | None]:
    """x positions of ``values``: themselves when numeric, else category indices (and
    the category labels)."""
    values = list(values)
    if _is_numeric(values):
        return np.asarray(values, float), None
    cats = list(dict.fromkeys(str(v) for v in values))
    return np.array([cats.index(str(v)) for v in values], float), cats


def _label(key: str) -> str:
    return key.split(".", 1)[-1]


def reference_slice(df: pd.DataFrame, keys, swept, *, seed=None) -> pd.DataFrame:
    """Rows of ``df`` where every swept parameter not in ``keys`` has its reference value
    (that of the first row) and the seed is the first seed (or ``seed``)."""
    if df.empty:
        return df
    first = df.iloc[0]
    mask = pd.Series(True, index=df.index)
    for k in swept:
        if k in keys or k not in df:
            continue
        mask &= df[k].astype(str) == str(first[k])
    if "seed" in df:
        mask &= df["seed"] == (first["seed"] if seed is None else seed)
    return df[mask]


def _fixed_text(df: pd.DataFrame, keys, swept) -> str:
    first = df.iloc[0] if len(df) else None
    parts = [f"{_label(k)} = {first[k]}" for k in swept if k not in keys and first is not None
             and k in df]
    return ", ".join(parts)


def _draw_family(ax, sub: pd.DataFrame, param: str) -> None:
    for j, (value, g) in enumerate(sub.groupby(param, sort=False)):
        g = g[~g["slipped"].astype(bool)].sort_values("utilisation")
        color = f"C{j % 10}"
        ax.plot(100 * g["utilisation"], g["phase_theory_deg"], "-", color=color,
                label=f"{_label(param)} = {value}")
        if g["phase_deg"].notna().any():
            ax.errorbar(100 * g["utilisation"], g["phase_deg"],
                        yerr=1.96 * g["phase_se_deg"].fillna(0), fmt="o", ms=4, color=color,
                        capsize=2)
    ax.axvspan(100 * BAND[0], 100 * BAND[1], color="0.9", zorder=0,
               label=f"dphi/du band {100 * BAND[0]:.0f}-{100 * BAND[1]:.0f} %")
    # what the line and the markers are (colours: the parameter's values above)
    ax.plot([], [], "-", color="0.3", label="large-signal theory")
    if sub["phase_deg"].notna().any():
        ax.errorbar([], [], yerr=[], fmt="o", ms=4, color="0.3", capsize=2,
                    label="twin + chain (95 %)")
    ax.set_xlabel("utilisation CoA/mu [%]")
    ax.set_ylabel("phase lag [deg]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")


def phase_family_figure(table: pd.DataFrame, param: str, swept, *, ax=None):
    """Phase against utilisation for each value of ``param`` (lines: large-signal theory;
    markers with 95 % bars: the chain, full mode), the other swept parameters at their
    reference values; the band of the sensitivity shaded."""
    _fig, ax = _axes(ax)
    sub = reference_slice(table, (param,), swept)
    _draw_family(ax, sub, param)
    fixed = _fixed_text(sub, (param,), swept)
    ax.set_title(f"phase vs utilisation by {_label(param)}" + (f"\n({fixed})" if fixed else ""),
                 fontsize=9)
    return ax


def phase_panels_figure(table: pd.DataFrame, panel: str, curve: str, swept, *,
                        ax=None):
    """One panel per value of ``panel`` (e.g. the friction condition), in each the phase
    against utilisation for every value of ``curve`` (e.g. the modulation frequency)."""
    values = list(dict.fromkeys(table[panel].astype(str)))
    if ax is None:
        n = len(values)
        cols = min(n, 2)
        rows = int(np.ceil(n / cols))
        fig = Figure(figsize=(5.0 * cols, 3.8 * rows), layout="constrained")
        axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False).ravel())
        for extra in axes[n:]:
            extra.set_visible(False)
    else:
        axes = np.atleast_1d(ax)
        fig = axes[0].figure
    for a, value in zip(axes, values, strict=False):
        part = table[table[panel].astype(str) == value]
        sub = reference_slice(part, (panel, curve), swept)
        _draw_family(a, sub, curve)
        a.set_title(f"{_label(panel)} = {value}", fontsize=9)
    fixed = _fixed_text(reference_slice(table, (panel, curve), swept), (panel, curve), swept)
    if fixed:
        fig.suptitle(f"phase vs utilisation ({fixed})", fontsize=10)
    return axes if ax is None else ax


_MARKERS = "osD^vPXh*p"
_LINES = ("-", "--", ":", "-.")


def _series(summary: pd.DataFrame, param: str, swept):
    """The summary split over the other swept parameters: ``[(group, colour, style index)]``
    (colour by the first other parameter, style by the rest) and the legend proxies."""
    from matplotlib.lines import Line2D
    others = [k for k in swept if k != param and k in summary]
    if not others:
        return [(summary, "C0", 0)], []

    def rest(values) -> str:
        return ", ".join(f"{_label(k)}={v}" for k, v in zip(others[1:], values, strict=True))

    firsts = list(dict.fromkeys(str(v) for v in summary[others[0]]))
    rests = list(dict.fromkeys(rest(r) for r in summary[others[1:]].itertuples(index=False)))
    out = []
    for key, g in summary.groupby(others, sort=False):
        key = key if isinstance(key, tuple) else (key,)
        out.append((g, f"C{firsts.index(str(key[0])) % 10}", rests.index(rest(key[1:]))))
    proxies = [Line2D([], [], color=f"C{i % 10}", lw=2, label=f"{_label(others[0])}={v}")
               for i, v in enumerate(firsts)]
    if len(rests) > 1:
        proxies += [Line2D([], [], color="0.35", ls=_LINES[i % len(_LINES)],
                           marker=_MARKERS[i % len(_MARKERS)], label=r)
                    for i, r in enumerate(rests)]
    return out, proxies


def _x_axis(ax, summary, param):
    x, cats = _positions(summary[param])
    if cats is not None:
        ax.set_xticks(range(len(cats)), cats)
    ax.set_xlabel(_label(param))
    return dict(zip(summary.index, x, strict=True))


def sensitivity_figure(summary: pd.DataFrame, param: str, swept, *, ax=None):
    """The slope dphi/du of the phase over the 50-80 % utilisation band [deg per %] against
    ``param``: large-signal theory (lines) and the chain (markers, full mode)."""
    _fig, ax = _axes(ax)
    xs = _x_axis(ax, summary, param)
    series, proxies = _series(summary, param, swept)
    for g, color, k in series:
        g = g.sort_values(param) if _is_numeric(g[param]) else g
        x = [xs[i] for i in g.index]
        ax.plot(x, g["dphi_du_theory"], ls=_LINES[k % len(_LINES)], color=color)
        if g["dphi_du_chain"].notna().any():
            ax.plot(x, g["dphi_du_chain"], _MARKERS[k % len(_MARKERS)], color=color, ms=4)
    ax.set_ylabel(f"dphi/du, {BAND[0]:.0%}-{BAND[1]:.0%} [deg per %]")
    ax.set_title(f"sensitivity of the phase to utilisation vs {_label(param)}\n(lines: "
                 "theory, markers: chain)", fontsize=9)
    ax.grid(True, alpha=0.3)
    if proxies:
        ax.legend(handles=proxies, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return ax


def mu_error_figure(summary: pd.DataFrame, param: str, swept, *, ax=None):
    """mu from the phase (steps below the utilisation limit) relative to the true mu [%]
    against ``param``: filled markers with the 95 % interval where mu is determined, open
    markers at the lower bound where it is not (series side by side)."""
    from matplotlib.lines import Line2D
    _fig, ax = _axes(ax)
    xs = _x_axis(ax, summary, param)
    series, proxies = _series(summary, param, swept)
    span = np.ptp(list(xs.values())) if _is_numeric(summary[param]) else len(set(xs.values()))
    step = 0.6 * (span or 1.0) / max(len(set(xs.values())), 1) / max(len(series), 1)
    for j, (g, color, k) in enumerate(series):
        x = np.array([xs[i] for i in g.index]) + step * (j - (len(series) - 1) / 2)
        det = g["mu_phase_determined"].astype(bool).to_numpy()
        y = g["mu_phase_error_pct"].to_numpy(float)
        lo = g["mu_phase_lo_error_pct"].to_numpy(float)
        hi = g["mu_phase_hi_error_pct"].to_numpy(float)
        m = _MARKERS[k % len(_MARKERS)]
        if det.any():
            ax.errorbar(x[det], y[det], yerr=[y[det] - lo[det], hi[det] - y[det]], fmt=m,
                        color=color, capsize=2, ms=4)
        if (~det).any():
            ax.plot(x[~det], lo[~det], m, mfc="none", color=color, ms=6)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_ylabel("mu from phase / true mu - 1 [%]")
    ax.set_title(f"mu-from-phase error vs {_label(param)} \n(filled: determined, 95 %; "
                 "open: lower bound)", fontsize=9)
    ax.grid(True, alpha=0.3)
    proxies.append(Line2D([], [], color="0.35", marker="o", mfc="none", ls="",
                          label="lower bound (mu not determined)"))
    # outside the axes: inside, it covered markers of the example sweep (issue 12 audit)
    ax.legend(handles=proxies, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return ax


def disturbance_figure(settings: pd.DataFrame, limits: dict, *, ax=None,
                       ripple_label: str = "torque ripple [% of Ts]",
                       title: str = "disturbance added by the modulation (largest below the "
                                    "utilisation limit; dashed: limits)"):
    """Per modulation setting the largest creepage swing amplitude and torque ripple [% of
    the saturation torque] below the utilisation limit, with the limits dashed."""
    _fig, axes = _axes(ax, 2, figsize=(7.0, 5.5))
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
    return axes if ax is None else ax
