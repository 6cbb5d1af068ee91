"""Figures and the self-contained HTML report of a processed (and fitted) experiment.

:func:`write_report` writes, inside the results folder::

    figures/fig2_signals.{png,svg}      paper Figure 2 (one step and cycle, raw and filtered)
    figures/fig3_creep_curve.{png,svg}  paper Figure 3 (creep curve, error bars, Polach fit)
    figures/fig4_phase.{png,svg}        paper Figure 4 (phase vs DC torque % Ts, theory)
    figures/fig5_mu_from_phase.{png,svg} phase vs utilised adhesion with the fitted C/k(CoA)
    report.html                         summary, figures, Tables 1-2, fit, warnings, provenance

If ``fit.json`` is missing the fit stage (:func:`torquemod.analysis.fit_results_folder`) runs
first with ``options.fit_options``.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis import fit_results_folder, read_json
from ..config import coerce_options
from ..fsutil import write_atomic
from .figures import (
    available_cycles,
    creep_curve_figure,
    phase_figure,
    phase_fit_figure,
    save_figure,
    signals_figure,
)
from .html import render_report

__all__ = ["ReportOptions", "creep_curve_figure", "phase_figure", "signals_figure",
           "write_report"]


@dataclass(frozen=True)
class ReportOptions:
    """Report options. ``step``/``cycle`` choose Figure 2 (paper: step 3, cycle 1; the first
    available cycle is used, with a warning, if absent); ``coa_multiplier`` and
    ``creepage_multiplier`` scale the error bars of Figure 3 (paper: 20 and 5);
    ``formats`` of the saved figures; ``refit`` reruns the fit even if fit.json exists."""

    step: int = 3
    cycle: int = 1
    coa_multiplier: float = 20.0
    creepage_multiplier: float = 5.0
    formats: tuple[str, ...] = ("png", "svg")
    dpi: int = 150
    title: str | None = None
    refit: bool = False
    fit_options: object = None

    @classmethod
    def coerce(cls, options) -> ReportOptions:
        return coerce_options(cls, options, "report")


def _png_bytes(fig, dpi: int) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def write_report(results_dir, *, options=None) -> Path:
    """Write the figures and ``report.html`` for ``results_dir``; returns the report's path."""
    opts = ReportOptions.coerce(options)
    results_dir = Path(results_dir)
    if opts.refit or not (results_dir / "fit.json").is_file():
        fit_results_folder(results_dir, options=opts.fit_options)
    fit = read_json(results_dir / "fit.json")
    prov = read_json(results_dir / "provenance.json")
    steps = pd.read_csv(results_dir / "steps.csv")
    cycles_path = results_dir / "cycles.csv"
    cycles = pd.read_csv(cycles_path) if cycles_path.is_file() else None
    warnings = [*(prov.get("warnings") or []), *(fit.get("warnings") or [])]
    speeds = [c.get("speed_m_s") for c in prov.get("cycles") or [] if c.get("speed_m_s")]
    speed = float(np.mean(speeds)) if speeds else None

    fig_dir = results_dir / "figures"
    figures = []

    def add(fig, name, alt, caption):
        save_figure(fig, fig_dir / name, formats=opts.formats, dpi=opts.dpi)
        figures.append({"png": _png_bytes(fig, opts.dpi), "alt": alt, "caption": caption})

    traces_path = results_dir / "traces.npz"
    if traces_path.is_file():
        with np.load(traces_path) as npz:
            traces = {k: npz[k] for k in npz.files}
        pairs = available_cycles(traces)
        step, cycle = opts.step, opts.cycle
        if pairs and (step, cycle) not in pairs:
            warnings.append(f"Figure 2: step {step} cycle {cycle} has no traces; "
                            f"showing step {pairs[0][0]} cycle {pairs[0][1]} instead")
            step, cycle = pairs[0]
        if pairs:
            add(signals_figure(traces, step=step, cycle=cycle), "fig2_signals",
                "Torque and wheel angular velocity signals",
                f"Figure 2: (a) applied torque and (b) wheel angular velocity, step {step}, "
                f"cycle {cycle}: raw (grey) and after the band-pass filter (blue, drawn about "
                "the mean); shaded: the window used for the phase.")
        else:
            warnings.append("Figure 2: traces.npz holds no cycle traces")
    else:
        warnings.append("Figure 2: traces.npz not found; no signal figure")
    add(creep_curve_figure(steps, fit, coa_multiplier=opts.coa_multiplier,
                           creepage_multiplier=opts.creepage_multiplier, speed_m_s=speed),
        "fig3_creep_curve", "Creep curve with the fitted Polach model",
        f"Figure 3: measured creep curve (error bars {opts.coa_multiplier:g}× the standard "
        f"deviation of CoA and {opts.creepage_multiplier:g}× that of the creepage over cycles) "
        "with the fitted Polach model (dashed).")
    add(phase_figure(steps, fit, speed_m_s=speed), "fig4_phase",
        "Phase difference against DC torque",
        "Figure 4: phase difference between torque and wheel angular velocity against the DC "
        "torque as a percentage of the saturation torque (error bars: standard deviation over "
        "cycles), with the rigid-wheel theory tan φ = C/k from the fitted curve's slope.")

    pfig = _phase_fit_panel(steps, fit)
    if pfig is not None:
        add(pfig, "fig5_mu_from_phase", "Phase progression with the fit that gives mu",
            "Figure 5: phase difference against the utilised adhesion (the drive's, from the "
            "torque), with the fit tan φ = C/k(CoA) over the Polach family that gives μ from "
            "the phase alone; labels: step (utilisation CoA/μ).")

    title = opts.title or f"torquemod report: {prov.get('experiment', {}).get('manifest', '')}"
    text = render_report(title=title, fit=fit, steps=steps, cycles=cycles, provenance=prov,
                         figures=figures, warnings=warnings)
    out = results_dir / "report.html"
    write_atomic(out, lambda fh: fh.write(text))
    return out


def _phase_fit_panel(steps: pd.DataFrame, fit: dict):
    """Figure 5 from steps.csv: the phase fit is recomputed (deterministic) so that its curve
    can be drawn; None when it cannot run."""
    from ..analysis import _phase_fit, _slip_flags
    from ..creep import creep_points
    try:
        pts = creep_points(steps)
    except Exception:  # a damaged table is reported by the fit stage, not here
        return None
    slip = _slip_flags(steps)
    use = np.array([not slip.get(int(s), False) for s in pts.step], dtype=bool)
    theory = fit.get("theory") or {}
    constant = theory.get("constant") if theory.get("mode") == "rig" else None
    load, radius = fit.get("normal_load_n"), fit.get("wheel_radius_m")
    pfit, _ = _phase_fit(steps, pts, use, constant,
                         measured_c=(radius, load) if radius and load else None)
    coa = steps["coa_torque"] if "coa_torque" in steps else steps["coa"]
    coa = np.asarray(coa, dtype=float)
    if not np.all(np.isfinite(coa)):
        coa = pts.coa
    se = steps["phase_se_deg"] if "phase_se_deg" in steps else steps.get("phase_std_deg")
    return phase_fit_figure(coa[use], pts.phase_deg[use], np.asarray(se, float)[use],
                            pts.step[use], pfit, mu_forces=fit.get("mu"))
