"""Matplotlib helpers that know nothing of friction: a new Figure or the given Axes, the Figure
of what a plot function returned, saving a Figure as PNG and SVG. The object-oriented API only
(no pyplot, no display, no global state), so they work headless.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.figure import Figure

__all__ = ["figure_axes", "figure_of", "legend_width_in", "place_axes", "save_figure"]


def figure_of(drawn) -> Figure:
    """The Figure of what a plot function returned: an Axes, a sequence or array of Axes,
    or a Figure itself."""
    if isinstance(drawn, list | tuple | np.ndarray):
        drawn = np.asarray(drawn, dtype=object).ravel()[0]
    return drawn.figure


def figure_axes(ax, n: int = 1, *, figsize=(7.0, 5.0), layout: str | None = "constrained"):
    """(Figure, axes): a new Figure with ``n`` stacked axes when ``ax`` is None, else the
    given Axes (or sequence of Axes) and their Figure. ``layout`` is the new Figure's layout
    engine; None leaves the axes where :func:`place_axes` puts them."""
    if ax is None:
        fig = Figure(figsize=figsize, layout=layout)
        axes = fig.subplots(n, 1, sharex=True) if n > 1 else fig.subplots()
        return fig, axes
    first = ax[0] if isinstance(ax, list | tuple | np.ndarray) else ax
    return first.figure, ax


def save_figure(fig, base: Path, *, formats=("png", "svg"), dpi: int = 150
                ) -> list[Path]:
    """Save ``fig`` (a Figure, or the Axes a plot function returned) as ``base.<fmt>`` for
    each format; returns the paths."""
    fig = figure_of(fig)
    base = Path(base)
    base.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    # SVG text stays text (searchable, selectable), not glyph outlines
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        for fmt in formats:
            path = base.with_suffix(f".{fmt}")
            fig.savefig(path, format=fmt, dpi=dpi)
            paths.append(path)
    return paths


def place_axes(fig, *, rows: int = 1, cols: int = 1, left: float = 0.8, right: float = 0.2,
               top: float = 0.4, bottom: float = 0.6, wspace: float = 0.75,
               hspace: float = 0.8) -> None:
    """Place the grid of a Figure without a layout engine, its margins and gaps in inches.

    A layout engine (constrained layout) measures every axis's tick labels and draws the
    figure twice when it is saved; fixed margins cost nothing and suit figures whose text
    has a known size.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The Figure (made without a layout engine).
    rows, cols : int
        The grid's rows and columns [-].
    left, right, top, bottom : float
        Margins [in].
    wspace, hspace : float
        Gaps between the columns and between the rows [in].
    """
    width, height = fig.get_size_inches()
    aw = max((width - left - right - (cols - 1) * wspace) / cols, 0.1)
    ah = max((height - top - bottom - (rows - 1) * hspace) / rows, 0.1)
    fig.subplots_adjust(left=left / width, right=1 - right / width, bottom=bottom / height,
                        top=1 - top / height, wspace=wspace / aw, hspace=hspace / ah)


def legend_width_in(legend) -> float:
    """The width of a legend as it will be drawn [in] (its text laid out once)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    fig = legend.figure
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    return legend.get_window_extent(canvas.get_renderer()).width / fig.dpi
