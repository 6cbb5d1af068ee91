"""The sweep report's figures over explicit creep curves: one panel per condition (a
distinct combination of the non-modulation parameters), compact labels, crosses where the
wheel slipped, no blank figure, categorical conditions not joined by lines."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from torquemod.sweep.conditions import condition_labels
from torquemod.sweep.evaluate import evaluate_point, tasks
from torquemod.sweep.report import make_figures, render
from torquemod.sweep.spec import parse_sweep
from torquemod.sweep.summary import recommend

# two Polach curves (constant friction; friction falling with slip) at two frequencies
CURVES = """
name = "curves"
mode = "theory"
[steps]
fractions_of_peak = [0.0, 0.5, 0.7, 0.9]
[grid]
modulation.frequency_hz = [1.0, 3.0]
[[point]]
contact = { mu0 = 0.30, a_ratio = 1.0, b_s_m = 0.0, k_a = 0.30, k_s = 0.10 }
[[point]]
contact = { mu0 = 0.55, a_ratio = 0.40, b_s_m = 0.60, k_a = 1.00, k_s = 0.40 }
"""


@pytest.fixture(scope="module")
def curves():
    spec = parse_sweep(CURVES)
    tab = pd.concat([evaluate_point(t) for t in tasks(spec)], ignore_index=True)
    # the twin slipped at the last step of the first point (in full mode the twin can slip
    # before the theory's periodic state ends): it has no phase there
    last = tab.index[(tab["point_index"] == 0) & (tab["step"] == tab["step"].max())]
    tab["slipped_twin"] = False
    tab.loc[last, "slipped_twin"] = True
    tab.loc[last, "phase_deg"] = np.nan
    figs = {stem: (fig, caption) for stem, fig, caption in
            make_figures(tab, spec, recommend(tab, spec))}
    return spec, tab, figs


def _visible(fig):
    return [a for a in fig.axes if a.get_visible()]


def _has_data(ax) -> bool:
    for line in ax.get_lines():
        y = np.asarray(line.get_ydata(), float)
        if y.size and np.isfinite(y).any():
            return True
    return bool(ax.patches) or any(len(c.get_paths()) for c in ax.collections)


def test_labels_name_only_what_differs_between_conditions():
    tab = pd.DataFrame({"contact.mu0": [0.3, 0.3, 0.55], "contact.k_a": [0.3, 0.3, 0.3],
                        "contact.condition": [None, None, None],
                        "rig.speed_km_h": [np.nan, np.nan, 12.0],
                        "modulation.frequency_hz": [1.0, 3.0, 1.0]})
    swept = list(tab)
    labels = condition_labels(tab, swept)
    # the frequency is no part of a condition; k_a does not differ; the unset speed is left out
    assert list(labels) == ["μ0=0.3", "μ0=0.3", "μ0=0.55, V=12 km/h"]
    named = pd.DataFrame({"contact.condition": ["dry", "wet"], "modulation.frequency_hz": 2.0})
    assert list(condition_labels(named, list(named))) == ["dry", "wet"]
    assert set(condition_labels(named.iloc[:1], list(named))) == {""}  # a single condition


def test_one_panel_per_condition_each_with_every_frequency(curves):
    figs = curves[2]
    assert not [s for s in figs if s.startswith("phase_family")]  # no per-key copies
    fig, _ = figs["phase_by_condition"]
    axes = _visible(fig)
    assert [a.get_title() for a in axes] == [
        "μ0=0.3, A=1, B=0, kA=0.3, kS=0.1", "μ0=0.55, A=0.4, B=0.6, kA=1, kS=0.4"]
    solid = [[tuple(np.round(ln.get_ydata(), 6)) for ln in a.get_lines()
              if ln.get_linestyle() == "-" and len(ln.get_xdata()) > 1] for a in axes]
    # each panel: one large-signal curve per frequency, and the panels' curves differ
    assert [len(s) for s in solid] == [2, 2]
    assert not set(solid[0]) & set(solid[1])
    # the dotted Eq. (1) curve beside each
    assert all(sum(ln.get_linestyle() == ":" for ln in a.get_lines()) == 2 for a in axes)
    # the conditions compared at each swept frequency
    assert [a.get_title() for a in _visible(figs["phase_by_frequency"][0])] == ["1 Hz", "3 Hz"]
    assert len(_visible(figs["creep_curves"][0])) == 2


def test_the_step_where_the_wheel_slipped_is_marked(curves):
    _, tab, figs = curves
    u = 100 * tab.loc[tab["slipped_twin"], "utilisation"].iloc[0]
    first = _visible(figs["phase_by_condition"][0])[0]
    crosses = [ln for ln in first.get_lines() if ln.get_marker() == "x"
               and len(ln.get_xdata())]
    assert [list(ln.get_xdata()) for ln in crosses] == [[u]]
    # the theory still draws that step (only the twin slipped there)
    assert any(u in ln.get_xdata() for ln in first.get_lines() if ln.get_linestyle() == "-")


def test_no_blank_figure_and_conditions_not_joined(curves):
    spec, tab, figs = curves
    for stem, (fig, caption) in figs.items():
        assert caption, stem
        assert all(_has_data(a) for a in _visible(fig)), stem
    ax = figs["mu_error"][0].axes[0]
    assert [t.get_text().replace("\n", " ") for t in ax.get_xticklabels()] == [
        "μ0=0.3, A=1, B=0, kA=0.3, kS=0.1", "μ0=0.55, A=0.4, B=0.6, kA=1, kS=0.4"]
    # markers only: no line joins two conditions
    for ln in ax.get_lines():
        if ln.get_transform() is not ax.transData:  # the zero line, the separators
            continue
        x = np.asarray(ln.get_xdata(), float)
        if x.size > 1 and np.ptp(np.round(x)) > 0:
            assert ln.get_linestyle() in ("None", "none", ""), ln
    page = render(tab, spec, recommend(tab, spec), [])
    assert "available adhesion" in page and "<b>Recommended:" in page


def test_figure_functions_return_the_axes_they_drew_on(curves):
    """The notebook convention of every plot function: given ``ax`` it is returned; without
    one the new Figure's Axes (an array for several panels), never through pyplot."""
    import matplotlib.pyplot as plt
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from torquemod.sweep import figures as F
    from torquemod.sweep.conditions import CONDITION_COLUMN
    from torquemod.sweep.summary import point_summary
    spec, tab, _ = curves
    plt.close("all")
    summary = point_summary(tab, spec)
    labelled = tab.assign(**{CONDITION_COLUMN: condition_labels(tab, spec.swept)})
    ax = Figure().subplots()
    assert F.sensitivity_figure(summary, ax=ax) is ax
    assert isinstance(F.mu_error_figure(summary), Axes)
    pair = Figure().subplots(1, 2)
    assert F.phase_panels_figure(labelled, ax=pair) is pair
    made = F.phase_panels_figure(labelled)
    assert len(made) == labelled[CONDITION_COLUMN].nunique() == 2
    assert made[0].figure is made[1].figure
    assert plt.get_fignums() == []
