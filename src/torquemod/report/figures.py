"""Figures of the V-Track paper for a processed experiment (the paper's Figures 2-4 and the
phase fit; the report numbers them 1-4).

Every function takes the in-memory results (a cycle's traces, an
:class:`~torquemod.analysis.result.Analysis`), draws on a given ``ax`` and returns it
(matplotlib's and pandas' convention: a notebook cell shows the figure once), or without one
on a new :class:`matplotlib.figure.Figure` built with the object-oriented API (no pyplot, no
display, no global state) and returns its Axes (``ax.figure`` is the Figure);
:func:`save_figure` writes it as PNG and SVG with the Agg/SVG canvases, so this works
headless.
"""

from torquemod._util.mpl import figure_of, save_figure
from torquemod.analysis.figures import creep_curve_figure, phase_figure, phase_fit_figure
from torquemod.processing.figures import signals_figure

__all__ = ["creep_curve_figure", "figure_of", "phase_figure", "phase_fit_figure",
           "save_figure", "signals_figure"]
