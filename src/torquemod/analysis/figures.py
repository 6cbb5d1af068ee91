"""The analysis' figures: the V-Track paper's Figures 3 and 4 (the creep curve with its fit, the
phase against the creepage) and the fit of the friction to the phase, drawn from an
:class:`~torquemod.analysis.result.Analysis`. :mod:`torquemod.report.figures` gathers them.
"""

from __future__ import annotations

import numpy as np

from torquemod._util.mpl import figure_axes
from torquemod.analysis.creep import phase_from_constant_deg

__all__ = ["creep_curve_figure", "phase_figure", "phase_fit_figure"]


def _value_pm(value: float, err: float | None) -> str:
    """``value ± err`` with the error to two significant figures and the value to the same
    decimals (at least three): 0.3001 ± 0.00022, never 0.300 ± 0.000."""
    if not err or not np.isfinite(err):
        return f"{value:.3f}"
    decimals = max(3, 1 - int(np.floor(np.log10(abs(err)))))
    return f"{value:.{decimals}f} ± {err:.{decimals}f}"


def _curve_xi(polach, xi_max, speed):
    grid = np.linspace(0.0, xi_max, 400)
    return grid, np.asarray(polach.curve(grid, speed), dtype=float)


def creep_curve_figure(ana, *, ax=None, coa_multiplier: float = 20.0,
                       creepage_multiplier: float = 5.0):
    """Figure 3 of the V-Track paper [1]_: the measured creep curve and the fitted Polach curve.

    CoA against longitudinal creepage [%] with error bars of ``coa_multiplier`` x std(CoA)
    and ``creepage_multiplier`` x std(creepage) over cycles (stated in the legend), and the
    fitted Polach curve [2]_ (dashed).

    Parameters
    ----------
    ana : Analysis
        The analysis.
    ax : matplotlib.axes.Axes or None
        Axes to draw in; None: a new figure's.
    coa_multiplier : float
        Length of the CoA error bars in standard deviations [-]. Default 20 (as the paper).
    creepage_multiplier : float
        Length of the creepage error bars in standard deviations [-]. Default 5.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn in.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Fig. 3.
    .. [2] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000.
    """
    _fig, ax = figure_axes(ax)
    steps = ana.steps
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
    if ana.polach is not None:
        grid, curve = _curve_xi(ana.polach, 1.3 * float(np.nanmax(np.abs(xi))), ana.speed_m_s)
        if ana.mu is not None:
            label = f"Polach fit, μ = {_value_pm(ana.mu, ana.mu_stderr)}"
        else:
            label = f"Polach fit (μ not determined, μ ≥ {ana.mu_lower_bound or 0:.3f})"
        ax.plot(100 * grid, curve, "k--", lw=1.4, label=label)
        if ana.mu is not None:
            ax.axhline(ana.mu, color="0.5", lw=0.8, ls=":", label="μ")
    ax.set_xlabel("Longitudinal creepage ξx [%]")
    ax.set_ylabel("Coefficient of adhesion CoA [-]")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    return ax


def phase_figure(ana, *, ax=None):
    """Figure 4 of the V-Track paper [1]_: the phase against the DC torque.

    Measured phase difference [deg] (bars: std over cycles) against the DC torque as % of
    the saturation torque ``Ts = mu*N*Rw`` (N*m when mu is undetermined), with the
    rigid-wheel theory ``atan(C/k)`` (Eq. 1) along the fitted curve and at each step; the
    onset step is marked.

    Parameters
    ----------
    ana : Analysis
        The analysis.
    ax : matplotlib.axes.Axes or None
        Axes to draw in; None: a new figure's.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn in.

    References
    ----------
    .. [1] "Experimental Validation of the Torque-Modulation-Based Method for Train-Borne
       Coefficient of Friction Measurement" (TU Delft, V-Track rig), Eq. (1) and Fig. 4.
    """
    _fig, ax = figure_axes(ax)
    steps = ana.steps
    ts = ana.saturation_torque_nm
    dc = np.asarray(steps["dc_torque_nm"], dtype=float)
    x = 100 * dc / ts if ts else dc
    phase = np.asarray(steps["phase_deg"], dtype=float)
    err = np.nan_to_num(np.asarray(steps.get("phase_std_deg", np.zeros_like(phase)), float))
    ax.errorbar(x, phase, yerr=err, fmt="o", color="C0", capsize=3,
                label="measured (bars: 1× std over cycles)")
    ax.plot(x, np.asarray(steps["phase_theory_deg"], float), "s", mfc="none", color="C3",
            label="theory at the steps")
    constants = np.asarray(ana.theory.constant, dtype=float)
    constants = constants[np.isfinite(constants)]
    c = float(np.mean(constants)) if constants.size else np.nan
    if ana.polach is not None and np.isfinite(c):
        # beyond the data only when the fit determines mu (the curve's tail is then trusted)
        span = 3.0 if ana.mu_determined else 1.3
        xi_max = span * float(np.nanmax(np.abs(np.asarray(steps["creepage"], float))))
        grid, curve = _curve_xi(ana.polach, xi_max, ana.speed_m_s)
        grid, curve = grid[1:], curve[1:]
        k = np.asarray(ana.polach.slope(grid, ana.speed_m_s), dtype=float)
        torque = curve * ana.normal_load_n * ana.wheel_radius_m
        xc = 100 * torque / ts if ts else torque
        rising = np.concatenate([[True], np.diff(xc) > 0])  # stop at the curve's maximum
        stop = int(np.argmin(rising)) if not rising.all() else xc.size
        ax.plot(xc[:stop], phase_from_constant_deg(c, k[:stop]), "k--", lw=1.2,
                label=f"theory tan φ = C/k, C = {c:.3g}")
    for s, xx, y in zip(steps["step"], x, phase, strict=True):
        ax.annotate(str(int(s)), (xx, y), textcoords="offset points", xytext=(5, 5),
                    fontsize=8)
    if ana.onset.step is not None:
        at = np.flatnonzero(np.asarray(steps["step"]) == ana.onset.step)
        if at.size:
            ax.axvline(x[at[0]], color="C1", lw=1.0, ls="-.",
                       label=f"saturation onset (step {ana.onset.step})")
    ax.set_xlabel(_ts_axis_label(ana))
    ax.set_ylabel("Phase difference φ [deg]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    return ax


def _ts_axis_label(ana) -> str:
    """Figure 4's abscissa: % of the analysis' one Ts (named with its mu), else N·m."""
    ts = ana.saturation_torque_nm
    if not ts:
        return "DC torque [N·m] (Ts unknown: μ not determined)"
    source = {"forces": "μ from the forces", "phase": "μ from the phase"}.get(
        getattr(ana, "saturation_torque_source", None), "μ")
    return f"DC torque [% of Ts = {ts:.1f} N·m, {source}]"


def phase_fit_figure(ana, *, ax=None):
    """The phase progression against the utilised adhesion, with mu from the phase.

    Measured phase per fitted step (bars: 2 standard errors), the fitted
    ``tan(phi) = C/k(CoA)`` curve (:func:`torquemod.analysis.phasefit.fit_mu_from_phase`),
    its mu with the 95 % interval (or lower bound) and the force fit's mu; each step is
    labelled with its utilisation CoA/mu.

    Parameters
    ----------
    ana : Analysis
        The analysis.
    ax : matplotlib.axes.Axes or None
        Axes to draw in; None: a new figure's.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn in (CoA [-] against phase [deg]).
    """
    _fig, ax = figure_axes(ax)
    pts, use = ana.points, ana.used
    table = ana.steps.set_index("step").reindex(pts.step)
    coa = np.asarray(table["coa_torque"], float) if "coa_torque" in table else pts.coa
    if not np.all(np.isfinite(coa[use])):
        coa = pts.coa
    se = np.asarray(table["phase_se_deg"], float) if "phase_se_deg" in table \
        else pts.phase_std_deg
    coa, phase_deg, phase_se_deg, steps = coa[use], pts.phase_deg[use], se[use], pts.step[use]
    pfit, mu_forces = ana.phase_fit, ana.mu
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
    return ax
