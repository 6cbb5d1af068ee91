"""The chain's figure: the V-Track paper's Figure 2 of one cycle (torque and wheel speed, raw
and filtered), drawn from a :class:`~torquemod.processing.pipeline.ProcessResult`'s traces.
:mod:`torquemod.report.figures` gathers it with the analysis' figures.
"""

from __future__ import annotations

import numpy as np

from torquemod._util.mpl import figure_axes
from torquemod.errors import InputError

__all__ = ["signals_figure"]


def signals_figure(traces: dict, *, step: int = 3, cycle: int = 1, ax=None):
    """Figure 2 of the V-Track paper [1]_ for one cycle: torque and wheel speed, raw and filtered.

    (a) Applied torque [N*m], (b) wheel angular velocity [rad/s], raw and after the
    band-pass (the filtered signal drawn about the mean of the resampled one so both share an
    axis); the phase window is shaded.

    Parameters
    ----------
    traces : dict
        The cycle's named arrays (``ProcessResult.traces[(step, cycle)]``).
    step : int
        The step, for the title. Default 3.
    cycle : int
        The cycle, for the title. Default 1.
    ax : matplotlib.axes.Axes or array of two Axes or None
        A pair of Axes (panels (a) and (b)), or one Axes (one panel: the wheel speed on its
        twin y axis, one title); None: a new two-panel figure.

    Returns
    -------
    matplotlib.axes.Axes or ndarray of Axes
        ``ax`` as given, or the new figure's two Axes.

    Raises
    ------
    InputError
        No traces for that step and cycle.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Fig. 2.
    """
    if "t_raw_s" not in traces:
        raise InputError(f"no traces for step {step} cycle {cycle}")

    def get(name):
        return np.asarray(traces[name], dtype=float) if name in traces else None

    single = ax is not None and not isinstance(ax, list | tuple | np.ndarray)
    if single:
        axes = [ax, ax.twinx()]
        ax.set_title(f"Step {step}, cycle {cycle} (wheel speed: right axis)", loc="left",
                     fontsize=10)
    else:
        _fig, axes = figure_axes(ax, 2, figsize=(9.5, 6.0))
    rows = (("torque", "nm", "Applied torque [N·m]", "(a)", "C0"),
            ("wheel_speed", "rad_s", "Wheel angular velocity [rad/s]", "(b)", "C2"))
    t_raw, t_s, win = get("t_raw_s"), get("t_s"), get("phase_window_s")
    for a, (name, unit, label, tag, colour) in zip(axes, rows, strict=True):
        raw = get(f"{name}_raw_{unit}")
        a.plot(t_raw, raw, color="0.65", lw=0.6, label=f"{name.replace('_', ' ')} raw")
        filt, res = get(f"{name}_filtered_{unit}"), get(f"{name}_resampled_{unit}")
        if filt is not None and t_s is not None:
            offset = float(np.mean(res)) if res is not None else float(np.mean(raw))
            a.plot(t_s[: filt.size], filt + offset, color=colour, lw=1.6,
                   label=f"{name.replace('_', ' ')} band-pass filtered (+ mean)")
        if win is not None and win.size == 2:
            a.axvspan(win[0], win[1], color="C1", alpha=0.12,
                      label="phase window" if a is axes[0] else None)
            # the torque's peaks in the window on both panels: the wheel speed's lag shows
            for k, t_peak in enumerate(_peaks_in(t_s, get("torque_filtered_nm"), win)):
                a.axvline(t_peak, color="C0", ls=":", lw=0.9,
                          label="torque peaks" if a is axes[0] and k == 0 else None)
        a.set_ylabel(label)
        if not single:  # one Axes and its twin share a single title, drawn below
            a.set_title(f"{tag} step {step}, cycle {cycle}", loc="left", fontsize=10)
        a.grid(True, alpha=0.3)
        if ax is None:  # beside the panel, not over the peaks
            a.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    if ax is not None:
        handles = [h for a in axes for h in a.get_legend_handles_labels()[0]]
        labels = [lab for a in axes for lab in a.get_legend_handles_labels()[1]]
        for a in axes:  # head room: the legend sits above the traces, not on them
            lo, hi = a.get_ylim()
            a.set_ylim(lo, hi + (0.55 if single else 0.4) * (hi - lo))
        # on the twin when there is one: it is drawn last, so nothing covers the legend
        axes[-1 if single else 0].legend(handles, labels, loc="upper left", fontsize=7,
                                         ncol=2)
    axes[-1].set_xlabel("Time from cycle start [s]")
    return axes if ax is None else ax


def _peaks_in(t, x, window) -> np.ndarray:
    """Times [s] of the local maxima of ``x`` inside ``window`` (empty when unknown)."""
    if t is None or x is None:
        return np.empty(0)
    t = t[: x.size]
    inner = (x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])
    tp = t[1:-1][inner]
    return tp[(tp >= window[0]) & (tp <= window[1])]
