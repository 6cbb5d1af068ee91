"""Figures of the V-Track paper for a processed experiment (Figures 2, 3 and 4).

Every function returns a :class:`matplotlib.figure.Figure` built with the object-oriented API
(no pyplot, no display, no global state); :func:`save_figure` writes it as PNG and SVG with the
Agg/SVG canvases, so this works headless.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..creep import phase_from_constant_deg
from ..errors import InputError
from ..fit import polach_coa, polach_slope

__all__ = ["available_cycles", "creep_curve_figure", "phase_figure", "phase_fit_figure",
           "save_figure", "signals_figure"]

TRACE_NAMES = ("t_raw_s", "torque_raw_nm", "wheel_speed_raw_rad_s", "t_s",
               "torque_resampled_nm", "wheel_speed_resampled_rad_s", "torque_filtered_nm",
               "wheel_speed_filtered_rad_s", "phase_window_s")


def available_cycles(traces) -> list[tuple[int, int]]:
    """Sorted ``(step, cycle)`` pairs present in a ``traces.npz`` mapping."""
    pairs = set()
    for key in traces:
        head, _, _ = str(key).partition("__")
        if head.startswith("s") and "c" in head:
            s, _, c = head[1:].partition("c")
            if s.isdigit() and c.isdigit():
                pairs.add((int(s), int(c)))
    return sorted(pairs)


def signals_figure(traces, *, step: int = 3, cycle: int = 1) -> Figure:
    """Paper Figure 2: (a) applied torque [N m], (b) wheel angular velocity [rad/s] of one
    cycle, raw and after the band-pass (the filtered signal is drawn about the mean of the
    resampled one so both share an axis); the phase window is shaded."""
    key = f"s{step}c{cycle}__"
    if key + "t_raw_s" not in traces:
        raise InputError(f"no traces for step {step} cycle {cycle}; available: "
                         f"{available_cycles(traces)}")

    def get(name):
        return np.asarray(traces[key + name], dtype=float) if key + name in traces else None

    fig = Figure(figsize=(8.0, 6.0), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    rows = (("torque", "nm", "Applied torque [N·m]", "(a)"),
            ("wheel_speed", "rad_s", "Wheel angular velocity [rad/s]", "(b)"))
    t_raw, t_s, win = get("t_raw_s"), get("t_s"), get("phase_window_s")
    for ax, (name, unit, label, tag) in zip(axes, rows, strict=True):
        raw = get(f"{name}_raw_{unit}")
        ax.plot(t_raw, raw, color="0.65", lw=0.6, label="raw")
        filt, res = get(f"{name}_filtered_{unit}"), get(f"{name}_resampled_{unit}")
        if filt is not None and t_s is not None:
            offset = float(np.mean(res)) if res is not None else float(np.mean(raw))
            ax.plot(t_s[: filt.size], filt + offset, color="C0", lw=1.6,
                    label="band-pass filtered (+ mean)")
        if win is not None and win.size == 2:
            ax.axvspan(win[0], win[1], color="C1", alpha=0.12, label="phase window")
        ax.set_ylabel(label)
        ax.set_title(f"{tag} step {step}, cycle {cycle}", loc="left", fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("Time from cycle start [s]")
    return fig


def _theta(fit_doc: dict):
    th = (fit_doc.get("theta_internal") or {}).get("values")
    return None if th is None else np.asarray(th, dtype=float)


def _curve_xi(theta, xi_max, speed):
    grid = np.linspace(0.0, xi_max, 400)
    return grid, polach_coa(grid, theta, speed_m_s=speed if len(theta) == 5 else None)


def creep_curve_figure(steps, fit_doc: dict | None = None, *, coa_multiplier: float = 20.0,
                       creepage_multiplier: float = 5.0, speed_m_s: float | None = None
                       ) -> Figure:
    """Paper Figure 3: CoA against longitudinal creepage [%] with error bars of
    ``coa_multiplier`` x std(CoA) and ``creepage_multiplier`` x std(creepage) over cycles
    (stated in the legend), and the fitted Polach curve (dashed) from ``fit.json``."""
    fig = Figure(figsize=(7.0, 5.0), layout="constrained")
    ax = fig.subplots()
    xi = np.asarray(steps["creepage"], dtype=float)
    coa = np.asarray(steps["coa"], dtype=float)
    xerr = creepage_multiplier * np.asarray(steps.get("creepage_std", np.zeros_like(xi)), float)
    yerr = coa_multiplier * np.asarray(steps.get("coa_std", np.zeros_like(xi)), float)
    ax.errorbar(100 * xi, coa, xerr=100 * np.nan_to_num(xerr), yerr=np.nan_to_num(yerr),
                fmt="o", color="C0", ms=6, capsize=3,
                label=f"measured (bars: {coa_multiplier:g}× std CoA, "
                      f"{creepage_multiplier:g}× std creepage)")
    for s, x, y in zip(steps["step"], xi, coa, strict=True):
        ax.annotate(str(int(s)), (100 * x, y), textcoords="offset points", xytext=(5, -12),
                    fontsize=8)
    theta = _theta(fit_doc or {})
    if theta is not None:
        grid, curve = _curve_xi(theta, 1.3 * float(np.nanmax(np.abs(xi))), speed_m_s)
        mu = fit_doc.get("mu")
        if mu is not None:
            label = f"Polach fit, μ = {mu:.3f} ± {fit_doc.get('mu_stderr') or 0:.3f}"
        else:
            label = f"Polach fit (μ not determined, μ ≥ {fit_doc.get('mu_lower_bound', 0):.3f})"
        ax.plot(100 * grid, curve, "k--", lw=1.4, label=label)
        if mu is not None:
            ax.axhline(mu, color="0.5", lw=0.8, ls=":", label="μ")
    ax.set_xlabel("Longitudinal creepage ξx [%]")
    ax.set_ylabel("Coefficient of adhesion CoA [-]")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    return fig


def phase_figure(steps, fit_doc: dict | None = None, *, speed_m_s: float | None = None
                 ) -> Figure:
    """Paper Figure 4: measured phase difference [deg] (bars: std over cycles) against the DC
    torque as % of the saturation torque ``Ts = mu*N*Rw`` (N·m when mu is undetermined), with
    the rigid-wheel theory ``atan(C/k)`` along the fitted curve and at each step."""
    fit_doc = fit_doc or {}
    fig = Figure(figsize=(7.0, 5.0), layout="constrained")
    ax = fig.subplots()
    ts = fit_doc.get("saturation_torque_nm")
    dc = np.asarray(steps["dc_torque_nm"], dtype=float)
    x = 100 * dc / ts if ts else dc
    phase = np.asarray(steps["phase_deg"], dtype=float)
    err = np.nan_to_num(np.asarray(steps.get("phase_std_deg", np.zeros_like(phase)), float))
    ax.errorbar(x, phase, yerr=err, fmt="o", color="C0", capsize=3,
                label="measured (bars: 1× std over cycles)")
    if "phase_theory_deg" in steps:
        ax.plot(x, np.asarray(steps["phase_theory_deg"], float), "s", mfc="none", color="C3",
                label="theory at the steps")
    theta = _theta(fit_doc)
    c = (fit_doc.get("theory") or {}).get("constant")
    n_load, radius = fit_doc.get("normal_load_n"), fit_doc.get("wheel_radius_m")
    if theta is not None and c is not None and n_load and radius:
        c = float(np.nanmean(np.asarray(c, dtype=float)))
        # beyond the data only when the fit determines mu (the curve's tail is then trusted)
        span = 3.0 if fit_doc.get("mu_determined") else 1.3
        xi_max = span * float(np.nanmax(np.abs(np.asarray(steps["creepage"], float))))
        grid, curve = _curve_xi(theta, xi_max, speed_m_s)
        grid, curve = grid[1:], curve[1:]
        speed = speed_m_s if len(theta) == 5 else None
        k = polach_slope(grid, theta, speed_m_s=speed)
        torque = curve * float(n_load) * float(radius)
        xc = 100 * torque / ts if ts else torque
        rising = np.concatenate([[True], np.diff(xc) > 0])  # stop at the curve's maximum
        stop = int(np.argmin(rising)) if not rising.all() else xc.size
        ax.plot(xc[:stop], phase_from_constant_deg(c, k[:stop]), "k--", lw=1.2,
                label=f"theory tan φ = C/k, C = {c:.3g}")
    for s, xx, y in zip(steps["step"], x, phase, strict=True):
        ax.annotate(str(int(s)), (xx, y), textcoords="offset points", xytext=(5, 5),
                    fontsize=8)
    ax.set_xlabel("DC torque [% of Ts]" if ts else "DC torque [N·m] (Ts undetermined)")
    ax.set_ylabel("Phase difference φ [deg]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    return fig


def phase_fit_figure(coa, phase_deg, phase_se_deg, steps, pfit=None, *,
                     mu_forces: float | None = None, ax=None):
    """The phase progression against the utilised adhesion CoA [-] (mu from the phase, issue
    8): measured phase per step (bars: 2 standard errors), the fitted ``tan phi = C/k(CoA)``
    curve of ``pfit`` (:func:`torquemod.phasefit.fit_mu_from_phase`), its mu with the 95 %
    interval (or lower bound) and the force fit's mu when given; each step is labelled with
    its utilisation CoA/mu. Draws on ``ax`` when given; returns the Figure."""
    if ax is None:
        fig = Figure(figsize=(7.0, 5.0), layout="constrained")
        ax = fig.subplots()
    else:
        fig = ax.figure
    coa = np.asarray(coa, dtype=float)
    phase = np.asarray(phase_deg, dtype=float)
    ax.errorbar(coa, phase, yerr=2 * np.nan_to_num(np.asarray(phase_se_deg, float)), fmt="o",
                color="C0", capsize=3, label="measured (bars: 2 standard errors)")
    mu = getattr(pfit, "mu", None) if pfit is not None and pfit.mu_determined else None
    if pfit is not None:
        top = mu if mu else 1.15 * float(np.nanmax(coa))
        grid = np.linspace(0.0, 0.995 * top, 300)[1:]
        with np.errstate(all="ignore"):
            curve = np.asarray(pfit.phase_curve(grid), float)
        ax.plot(grid, curve, "k--", lw=1.2,
                label=f"fit tan φ = C/k(CoA), C = {float(np.mean(pfit.constant)):.3g}")
        lo, hi = pfit.mu_interval_95
        if mu:
            ax.axvline(mu, color="C3", lw=1.0, label=f"μ from the phase = {mu:.3f}")
            if lo is not None and hi is not None:
                ax.axvspan(lo, hi, color="C3", alpha=0.12, label="its 95 % interval")
        elif lo is not None:
            ax.axvline(lo, color="C3", lw=1.0, ls=":", label=f"μ ≥ {lo:.3f} (not determined)")
    if mu_forces:
        ax.axvline(mu_forces, color="C2", lw=1.0, ls="--",
                   label=f"μ from the forces = {mu_forces:.3f}")
    for s, x, y in zip(steps, coa, phase, strict=True):
        text = f"{int(s)}" + (f" ({100 * x / mu:.0f} %)" if mu else "")
        ax.annotate(text, (x, y), textcoords="offset points", xytext=(5, 5), fontsize=8)
    ax.set_xlabel("Utilised adhesion CoA [-] (label: step (CoA/μ))")
    ax.set_ylabel("Phase difference φ [deg]")
    ax.set_xlim(left=0)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    return fig


def save_figure(fig: Figure, base: Path, *, formats=("png", "svg"), dpi: int = 150
                ) -> list[Path]:
    """Save ``fig`` as ``base.<fmt>`` for each format; returns the paths."""
    base = Path(base)
    base.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    for fmt in formats:
        path = base.with_suffix(f".{fmt}")
        fig.savefig(path, format=fmt, dpi=dpi)
        paths.append(path)
    return paths
