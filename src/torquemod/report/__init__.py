"""Figures and the self-contained HTML report of a processed and analysed experiment.

:func:`write_report` writes, into a folder (the results folder being assembled by
:mod:`torquemod.results.folder`)::

    figures/fig1_signals.{png,svg}       the paper's Figure 2 (one cycle, raw and filtered)
    figures/fig2_creep_curve.{png,svg}   the paper's Figure 3 (creep curve, Polach fit)
    figures/fig3_phase.{png,svg}         the paper's Figure 4 (phase vs DC torque % Ts)
    figures/fig4_mu_from_phase.{png,svg} phase vs utilised adhesion with the fitted C/k(CoA)
    report.html                         summary, figures, Tables 1-2, fit, warnings, provenance
    report.pdf                          the same on A4 (only with the ``pdf`` option)

Everything is drawn from the objects in memory
(:class:`~torquemod.processing.pipeline.ProcessResult`,
:class:`~torquemod.analysis.result.Analysis`); nothing is read from the folder.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from torquemod._util.fsutil import write_atomic
from torquemod.errors import OptionError
from torquemod.io.config import check_option_types, coerce_options
from torquemod.processing.figures import signals_figure
from torquemod.processing.provenance import provenance
from torquemod.report.figures import (
    creep_curve_figure,
    figure_of,
    phase_figure,
    phase_fit_figure,
    save_figure,
)
from torquemod.report.html import iter_report
from torquemod.report.pdf import PDF_ENGINES, html_to_pdf

if TYPE_CHECKING:
    from torquemod.analysis.result import Analysis
    from torquemod.processing.pipeline import ProcessResult

__all__ = ["ReportOptions", "creep_curve_figure", "phase_figure", "phase_fit_figure",
           "signals_figure", "write_report"]


@dataclass(frozen=True)
class ReportOptions:
    """Options of the report.

    Attributes
    ----------
    step : int
        The step of the signals figure (the V-Track paper's Fig. 2: step 3). Default 3; the
        first available cycle is used, with a warning, if absent.
    cycle : int
        Its cycle. Default 1.
    coa_multiplier : float
        Length of the CoA error bars of the creep-curve figure (the paper's Fig. 3) in
        standard deviations [-]. Default 20 (the paper's).
    creepage_multiplier : float
        Length of its creepage error bars in standard deviations [-]. Default 5.
    formats : tuple of str
        Formats of the saved figures. Default ("png", "svg").
    dpi : int
        Resolution of the raster figures [dots per inch]. Default 150.
    title : str or None
        Title of the page; None: the experiment's name.
    pdf : str or None
        Engine of :func:`torquemod.report.pdf.html_to_pdf` to write ``report.pdf`` too;
        None: no PDF, and a stale one from an earlier report is removed.
    """

    step: int = 3
    cycle: int = 1
    coa_multiplier: float = 20.0
    creepage_multiplier: float = 5.0
    formats: tuple[str, ...] = ("png", "svg")
    dpi: int = 150
    title: str | None = None
    pdf: str | None = None  # "matplotlib" or "chromium": also report.pdf (report.pdf)

    def __post_init__(self) -> None:
        check_option_types(self, "report")
        if self.pdf is not None and self.pdf not in PDF_ENGINES:
            raise OptionError(f"report option pdf={self.pdf!r}: choose one of "
                              f"{', '.join(PDF_ENGINES)} (or None for no PDF)")

    @classmethod
    def coerce(cls, options) -> ReportOptions:
        return coerce_options(cls, options, "report")


def _png_bytes(fig, dpi: int) -> bytes:
    buf = io.BytesIO()
    figure_of(fig).savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def write_report(folder, result: ProcessResult, analysis: Analysis, *, options=None,
                 provenance_doc: dict | None = None) -> Path:
    """Write the figures and ``report.html`` of a result and its analysis into a folder.

    Not atomic: :mod:`torquemod.results.folder` passes the folder it is assembling.

    Parameters
    ----------
    folder : str or pathlib.Path
        The folder.
    result : ProcessResult
        The processing result.
    analysis : Analysis
        Its analysis.
    options : ReportOptions or dict or None
        The options; None: the defaults.
    provenance_doc : dict or None
        The provenance shown in the report; None: built from ``result``.

    Returns
    -------
    pathlib.Path
        The report.
    """
    opts = ReportOptions.coerce(options)
    folder = Path(folder)
    prov = provenance_doc if provenance_doc is not None else provenance(result)
    warnings = [*result.warnings, *analysis.warnings]
    fig_dir = folder / "figures"
    figures = []

    def add(fig, name, alt, caption):
        save_figure(fig, fig_dir / name, formats=opts.formats, dpi=opts.dpi)
        figures.append({"png": _png_bytes(fig, opts.dpi), "alt": alt, "caption": caption})

    pairs = sorted(result.traces)
    step, cycle = opts.step, opts.cycle
    if pairs and (step, cycle) not in result.traces:
        warnings.append(f"Figure 1: step {step} cycle {cycle} has no traces; "
                        f"showing step {pairs[0][0]} cycle {pairs[0][1]} instead")
        step, cycle = pairs[0]
    if pairs:
        add(signals_figure(result.traces[(step, cycle)], step=step, cycle=cycle),
            "fig1_signals", "Torque and wheel angular velocity signals",
            f"Figure 1 (the paper's Figure 2): (a) applied torque and (b) wheel angular "
            f"velocity, step {step}, "
            f"cycle {cycle}: raw (grey) and after the band-pass filter (colour, drawn about "
            "the mean); shaded: the window used for the phase.")
    else:
        warnings.append("Figure 1: no cycle traces; no signal figure")
    add(creep_curve_figure(analysis, coa_multiplier=opts.coa_multiplier,
                           creepage_multiplier=opts.creepage_multiplier),
        "fig2_creep_curve", "Creep curve with the fitted Polach model",
        f"Figure {len(figures) + 1} (the paper's Figure 3): measured creep curve (error "
        f"bars {opts.coa_multiplier:g}× the standard "
        f"deviation of CoA and {opts.creepage_multiplier:g}× that of the creepage over cycles) "
        "with the fitted Polach model (dashed).")
    add(phase_figure(analysis), "fig3_phase", "Phase difference against DC torque",
        f"Figure {len(figures) + 1} (the paper's Figure 4): phase difference between torque "
        f"and wheel angular velocity against {_ts_caption(analysis)} (error bars: standard "
        "deviation over cycles), with the rigid-wheel theory tan φ = C/k from the fitted "
        "curve's slope.")
    add(phase_fit_figure(analysis), "fig4_mu_from_phase",
        "Phase progression with the fit that gives mu",
        f"Figure {len(figures) + 1}: phase difference against the utilised adhesion (the "
        "drive's, from the "
        "torque), with the fit tan φ = C/k(CoA) over the Polach family that gives μ from "
        "the phase alone; labels: step (utilisation CoA/μ).")
    title = opts.title or f"torquemod report: {result.name}"
    pieces = iter_report(title=title, fit=analysis.to_dict(), steps=analysis.steps,
                         cycles=result.cycles, provenance=prov, figures=figures,
                         warnings=warnings)
    path = write_atomic(folder / "report.html", lambda fh: fh.writelines(pieces))
    if opts.pdf:
        html_to_pdf(path, folder / "report.pdf", engine=opts.pdf)
    else:  # a PDF of an earlier report would no longer match this one
        (folder / "report.pdf").unlink(missing_ok=True)
    return path


def _ts_caption(analysis: Analysis) -> str:
    """What Figure 3's abscissa is, in the words of its caption (the axis says the same)."""
    ts = analysis.saturation_torque_nm
    if not ts:
        return ("the DC torque in N·m (the saturation torque is not known: neither fit "
                "determines μ)")
    source = {"forces": "μ from the forces", "phase": "μ from the phase"}.get(
        analysis.saturation_torque_source, "μ")
    return (f"the DC torque as a percentage of the saturation torque Ts = μ·N·Rw = {ts:.1f} "
            f"N·m ({source})")
