"""Matplotlib helpers that know nothing of friction: a new Figure or the given Axes, the Figure
of what a plot function returned, saving a Figure as PNG and SVG. The object-oriented API only
(no pyplot, no display, no global state), so they work headless.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.figure import Figure

__all__ = ["figure_axes", "figure_of", "save_figure"]


def figure_of(drawn) -> Figure:
    """The Figure of what a plot function returned: an Axes, a sequence or array of Axes,
    or a Figure itself."""
    if isinstance(drawn, list | tuple | np.ndarray):
        drawn = np.asarray(drawn, dtype=object).ravel()[0]
    return drawn.figure


def figure_axes(ax, n: int = 1, *, figsize=(7.0, 5.0)):
    """(Figure, axes): a new Figure with ``n`` stacked axes when ``ax`` is None, else the
    given Axes (or sequence of Axes) and their Figure."""
    if ax is None:
        fig = Figure(figsize=figsize, layout="constrained")
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
