"""The sweep report's figures as independent jobs: what each figure draws, from which rows,
and its caption, decided from the table without drawing anything; each job is drawn and
encoded as PNG on its own (:func:`draw_png`), here or as a Dask task on the sweep's
workers, so that the figures of one report are drawn side by side.

Nothing here imports matplotlib at module level: the command that only hands the jobs to its
workers never pays for it; a job imports the drawing code (:mod:`torquemod.sweep.figures`)
when it is drawn.
"""

from __future__ import annotations

import gc
import io
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from torquemod.sweep.conditions import CONDITION_COLUMN, condition_labels
from torquemod.sweep.spec import SweepSpec
from torquemod.sweep.summary import BAND, SETTING, point_summary, setting_table

__all__ = ["FigureJob", "creep_curves", "draw_png", "figure_jobs", "make_figures",
           "table_jobs"]

FREQ, AMP = SETTING

#: zlib level of the report's PNGs: 1 instead of Pillow's 6 saves 16 % of the encoding CPU
#: (1.37 -> 1.14 CPU-s for the example sweep's six figures) for 8 % larger files
PNG_COMPRESS_LEVEL = 1

#: rough CPU cost of each figure of the example sweep relative to the cheapest (drawn and
#: encoded; measured once): the dearest are handed out first when they are drawn in parallel
COST = {"creep_curves": 10.0, "phase_by_condition": 8.0, "phase_by_frequency": 4.0,
        "sensitivity": 2.0, "mu_error": 1.5, "disturbance": 1.0}


@dataclass(frozen=True)
class FigureJob:
    """One figure of the report, not yet drawn.

    Attributes
    ----------
    stem : str
        File stem (``figures/<stem>.png``).
    caption : str
        Its caption in the report.
    draw : callable
        A module-level function (so that the job pickles) drawing it on a new Figure and
        returning what the figure functions return (its Axes), or None when there is
        nothing to draw.
    args : tuple
        Positional arguments of ``draw`` (the rows it draws, ...).
    kwargs : dict
        Keyword arguments of ``draw``.
    """

    stem: str
    caption: str
    draw: Callable
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)

    @property
    def cost(self) -> float:
        """Rough relative CPU cost (:data:`COST`; 1 for a figure not listed)."""
        return COST.get(self.stem, 1.0)

    def figure(self):
        """Draw it: the Figure, or None when there is nothing to draw."""
        drawn = self.draw(*self.args, **self.kwargs)
        if drawn is None:
            return None
        from torquemod._util.mpl import figure_of
        return figure_of(drawn)


def png_bytes(fig) -> bytes:
    """A Figure as PNG bytes at the report's resolution (110 dpi) and zlib level
    (:data:`PNG_COMPRESS_LEVEL`).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.

    Returns
    -------
    bytes
        The PNG file's content.
    """
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL})
    return buf.getvalue()


def draw_png(job: FigureJob) -> bytes | None:
    """Draw one job and encode it (a Dask task, or called here).

    Python's cyclic garbage collector is paused meanwhile: a figure makes tens of thousands
    of small objects, which trigger full collections over everything the process holds
    (a worker: the twin, the chain, the fits), ~0.1 s each, several per figure; the
    figure's own cycles are collected once it is resumed.

    Parameters
    ----------
    job : FigureJob
        The figure.

    Returns
    -------
    bytes or None
        The PNG, or None when the job has nothing to draw.
    """
    paused = gc.isenabled()
    gc.disable()
    try:
        fig = job.figure()
        return None if fig is None else png_bytes(fig)
    finally:
        if paused:
            gc.enable()


def import_drawing() -> None:
    """Import what drawing a job needs (matplotlib's Agg canvas, the figure functions, the
    twin's theory of the creep curves): a worker runs it once it has no point left, so that
    its first figure does not wait for the imports."""
    import matplotlib.backends.backend_agg  # noqa: F401

    import torquemod.analysis.contact.polach
    import torquemod.sweep.evaluate
    import torquemod.sweep.figures
    import torquemod.twins.vtrack.theory  # noqa: F401


def _frequencies(values, at_most: int = 6) -> list:
    """The swept frequencies to compare the conditions at: all of them, or the ``at_most``
    nearest (in ratio) to the paper's 2 Hz, in ascending order."""
    values = sorted(dict.fromkeys(float(v) for v in values))
    if len(values) > at_most:
        values = sorted(sorted(values, key=lambda f: abs(np.log(f / 2.0)))[:at_most])
    return values


def creep_curves(tab: pd.DataFrame, spec: SweepSpec) -> dict:
    """Per condition the twin's longitudinal adhesion-creepage curve at the operating speed.

    ``F_x/N`` of the Polach model [1]_. Conditions whose curves are the same (they differ
    only in noise, say) share one entry, named after the first and listing all their labels.

    Parameters
    ----------
    tab : pandas.DataFrame
        The sweep table (``sweep.parquet``) with its ``condition`` labels.
    spec : SweepSpec
        The sweep's specification.

    Returns
    -------
    dict
        ``name -> (creepage [-], F_x/N [-], creepage at the peak [-], peak F_x/N [-],
        labels)``.

    References
    ----------
    .. [1] O. Polach, "Creep forces in simulations of traction vehicles running on adhesion
       limit", Wear 258 (2005) 992-1000, Eqs. (1)-(9).
    """
    from torquemod.analysis.contact.polach import creep_force
    from torquemod.sweep.evaluate import point_config, tasks
    from torquemod.twins.vtrack.theory import creep_curve_peak
    by_id = {t.point_id: t for t in tasks(spec)}
    groups: dict = {}
    for label, g in tab.groupby(CONDITION_COLUMN, sort=False):
        task = by_id.get(g["point_id"].iloc[0])
        if task is None:
            continue
        rig = point_config(task)[0].rig
        key = (rig.contact, rig.speed_m_s, rig.normal_load_n, rig.wheel_radius_m)
        entry = groups.setdefault(key, {"rig": rig, "labels": [], "xi_max": 0.0})
        entry["labels"].append(label)
        xi = g["creepage_true"].to_numpy(float)
        if np.isfinite(xi).any():
            entry["xi_max"] = max(entry["xi_max"], float(np.nanmax(np.abs(xi))))
    out = {}
    for entry in groups.values():
        rig, labels = entry["rig"], entry["labels"]
        xi_peak, t_peak = creep_curve_peak(rig)
        xi = np.geomspace(1e-5, max(2.0 * xi_peak, 1.5 * entry["xi_max"]), 400)
        fx, _ = creep_force(xi, rig.contact.lateral_creepage, normal_load_n=rig.normal_load_n,
                            speed_m_s=rig.speed_m_s, **rig.contact.polach_kwargs())
        name = labels[0] if len(labels) == 1 else (
            f"{labels[0]} (and {len(labels) - 1} more with this curve)")
        out[name] = (xi, fx / rig.normal_load_n, xi_peak,
                     t_peak / (rig.wheel_radius_m * rig.normal_load_n), labels)
    return out


# the jobs' drawing functions: module-level (a job pickles by reference to them), each
# importing the drawing code when it runs

def _phase_panels(table: pd.DataFrame, **kwargs):
    from torquemod.sweep.figures import phase_panels_figure
    return phase_panels_figure(table, **kwargs)


def _creep(ref: pd.DataFrame, spec: SweepSpec):
    """The creep-curve figure of the rows ``ref`` (one amplitude and seed), or None when no
    condition has a curve."""
    from torquemod.sweep.figures import creep_curves_figure
    curves = creep_curves(ref, spec)
    if not curves:
        return None
    names = {lab: name for name, c in curves.items() for lab in c[4]}
    drawn = ref.assign(**{CONDITION_COLUMN: ref[CONDITION_COLUMN].map(names)})
    return creep_curves_figure({k: c[:4] for k, c in curves.items()}, drawn)


def _sensitivity(summary: pd.DataFrame):
    from torquemod.sweep.figures import sensitivity_figure
    return sensitivity_figure(summary)


def _mu_error(summary: pd.DataFrame):
    from torquemod.sweep.figures import mu_error_figure
    return mu_error_figure(summary)


def _disturbance(settings: pd.DataFrame, limits: dict):
    from torquemod.sweep.figures import disturbance_figure
    return disturbance_figure(settings, limits)


def table_jobs(tab: pd.DataFrame, spec: SweepSpec) -> list[FigureJob]:
    """The report's figures drawn from the table alone (the phase against utilisation per
    condition and per frequency, the creep curves), in the report's order: they can be
    drawn while the point summary and the recommendation are worked out.

    Parameters
    ----------
    tab : pandas.DataFrame
        The sweep table (``sweep.parquet``).
    spec : SweepSpec
        The sweep's specification.

    Returns
    -------
    list of FigureJob
        The figures; the creep curves' job draws nothing (None) when no condition has a
        curve.
    """
    tab = tab.assign(**{CONDITION_COLUMN: condition_labels(tab, spec.swept)})
    conds = list(dict.fromkeys(tab[CONDITION_COLUMN]))
    amp, seed = tab[AMP].iloc[0], tab["seed"].iloc[0]
    ref = tab[(tab[AMP] == amp) & (tab["seed"] == seed)]
    at = (f" at the modulation amplitude {amp:.3g} N*m" if tab[AMP].nunique() > 1 else "") \
        + (f", seed {seed}" if tab["seed"].nunique() > 1 else "")
    lines = ("lines: large-signal theory; dotted: the rigid-wheel small-signal model of the "
             "paper's Eq. (1), tan φ = ΩJV/(R²Nk), at each step's creep coefficient; "
             "markers: twin + processing chain with 95 % bars; crosses: steps where the "
             "wheel slipped (on the theory's curve where the twin slipped, at the top of the "
             "panel where the theory has no periodic state either).")
    freqs = sorted(dict.fromkeys(ref[FREQ]))
    out = [FigureJob(
        "phase_by_condition",
        f"Phase lag against utilisation, one panel per condition ({len(conds)}), one "
        f"colour per modulation frequency ({', '.join(f'{f:.3g}' for f in freqs)} Hz)"
        f"{at} (the paper's Fig. 4 per condition). {lines}",
        _phase_panels, (ref,), {"title": "phase vs utilisation per condition" + at})]
    if len(conds) > 1:
        shown = _frequencies(ref[FREQ])
        out.append(FigureJob(
            "phase_by_frequency",
            "The conditions compared at each modulation frequency "
            f"({', '.join(f'{f:.3g}' for f in shown)} Hz){at}: phase lag against "
            f"utilisation, one colour per condition. {lines}",
            _phase_panels, (ref[ref[FREQ].isin(shown)],),
            {"panel": FREQ, "curve": CONDITION_COLUMN, "panels": shown,
             "title": "the conditions compared" + at}))
    out.append(FigureJob(
        "creep_curves",
        "The twin's adhesion-creepage curve of each condition at its operating "
        "speed (Polach 2005), its peak -- the available adhesion, the true μ "
        "against which μ from the phase is judged -- and the steady operating "
        "points of the torque steps" + (", with the chain's measured points per modulation "
                                        "frequency" if spec.mode == "full" else "") + ".",
        _creep, (ref, spec)))
    return out


def figure_jobs(tab: pd.DataFrame, spec: SweepSpec, rec: dict, *,
                summary: pd.DataFrame | None = None) -> list[FigureJob]:
    """Every figure of the sweep's report, in the report's order, not yet drawn: those of
    :func:`table_jobs`, then those of the point summary.

    Parameters
    ----------
    tab : pandas.DataFrame
        The sweep table (``sweep.parquet``).
    spec : SweepSpec
        The sweep's specification.
    rec : dict
        The recommendation (:func:`torquemod.sweep.summary.recommend`).
    summary : pandas.DataFrame or None
        :func:`~torquemod.sweep.summary.point_summary` of ``tab`` when the caller has it.
        Default None (computed here).

    Returns
    -------
    list of FigureJob
        The figures; the creep curves' job draws nothing (None) when no condition has a
        curve.
    """
    summary = point_summary(tab, spec) if summary is None else summary
    out = table_jobs(tab, spec)
    several = len(set(condition_labels(tab, spec.swept))) > 1
    if summary[FREQ].nunique() > 1 or several:
        out.append(FigureJob(
            "sensitivity",
            f"Sensitivity dφ/du of the phase to the utilisation over "
            f"{BAND[0]:.0%}-{BAND[1]:.0%}, per condition" + (
                " against the modulation frequency" if summary[FREQ].nunique() > 1
                else "") + ".",
            _sensitivity, (summary,)))
    out.append(FigureJob(
        "mu_error",
        f"μ from the phase (steps up to {spec.recommend.max_utilisation:.0%} "
        "utilisation) relative to the available adhesion (the creep curve's peak), "
        "per condition and modulation setting.",
        _mu_error, (summary,)))
    settings = setting_table(summary, spec)
    if len(settings):
        out.append(FigureJob(
            "disturbance",
            "Disturbance the modulation adds (largest creepage swing amplitude and torque "
            "ripple below the utilisation limit) per modulation setting.",
            _disturbance, (settings, rec.get("limits", {
                "max_creepage_swing": spec.recommend.max_creepage_swing,
                "max_torque_ripple_pct": spec.recommend.max_torque_ripple_pct}))))
    return out


def make_figures(tab: pd.DataFrame, spec: SweepSpec, rec: dict, *,
                 summary: pd.DataFrame | None = None) -> list[tuple[str, object, str]]:
    """Every figure of the sweep, drawn here.

    Parameters
    ----------
    tab : pandas.DataFrame
        The sweep table (``sweep.parquet``).
    spec : SweepSpec
        The sweep's specification.
    rec : dict
        The recommendation (:func:`torquemod.sweep.summary.recommend`).
    summary : pandas.DataFrame or None
        :func:`~torquemod.sweep.summary.point_summary` of ``tab`` when the caller has it.
        Default None (computed here).

    Returns
    -------
    list of tuple
        ``(file stem, matplotlib Figure, caption)``.
    """
    out = []
    for job in figure_jobs(tab, spec, rec, summary=summary):
        fig = job.figure()
        if fig is not None:
            out.append((job.stem, fig, job.caption))
    return out
