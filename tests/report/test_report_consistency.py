"""The rig report agrees with itself: one saturation torque Ts behind the summary, Table 1's
% Ts, Figure 3's axis and caption and ``steps.torque_pct_saturation``; an undetermined μ is
never printed as a value ± error; figures are numbered from 1."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest

import torquemod as tm
from torquemod.analysis.analyzer import saturation_torque
from torquemod.demo import synthetic_result
from torquemod.report import write_report
from torquemod.report.figures import phase_figure


@pytest.fixture(scope="module")
def phase_only():
    """Steps to 80 % of saturation with noisy CoA: the force fit leaves μ open, the phase
    fit determines it (checked below, so a change of either fit shows up here)."""
    res = synthetic_result(seed=0, saturation_fractions=(0.003, 0.3, 0.5, 0.65, 0.75, 0.8),
                           coa_noise=0.004)
    ana = tm.analyze(res)
    assert ana.mu is None and ana.phase_fit is not None and ana.phase_fit.mu_determined
    return res, ana


@pytest.fixture(scope="module")
def written(phase_only, tmp_path_factory):
    """The report of ``phase_only``, written once: (folder, its HTML)."""
    folder = tmp_path_factory.mktemp("report")
    res, ana = phase_only
    return folder, write_report(folder, res, ana).read_text(encoding="utf-8")


def test_saturation_torque_prefers_forces_then_phase():
    forces = SimpleNamespace(mu=0.3, mu_stderr=0.01)
    phase = SimpleNamespace(mu=0.25, mu_stderr=0.002, mu_determined=True)
    open_forces = SimpleNamespace(mu=None, mu_stderr=None)
    nr = {"normal_load_n": 4000.0, "wheel_radius_m": 0.1}
    assert saturation_torque(forces, phase, **nr) == pytest.approx((120.0, 4.0, "forces"))
    ts, se, src = saturation_torque(open_forces, phase, **nr)
    assert (ts, se, src) == (pytest.approx(100.0), pytest.approx(0.8), "phase")
    phase_open = SimpleNamespace(mu=None, mu_stderr=None, mu_determined=False)
    assert saturation_torque(open_forces, phase_open, **nr) == (None, None, None)
    assert saturation_torque(None, None, **nr) == (None, None, None)


def test_one_ts_everywhere(phase_only, written):
    _, ana = phase_only
    ts = ana.saturation_torque_nm
    assert ana.saturation_torque_source == "phase"
    assert ts == pytest.approx(ana.mu_from_phase * ana.normal_load_n * ana.wheel_radius_m)
    pct = ana.steps["torque_pct_saturation"].to_numpy(float)
    np.testing.assert_allclose(pct, 100 * ana.steps["dc_torque_nm"].to_numpy(float) / ts)
    doc = ana.to_dict()
    assert doc["saturation_torque_nm"] == pytest.approx(ts)
    assert doc["saturation_torque_source"] == "phase"

    drawn = phase_figure(ana)  # a Figure, or its Axes (plots that return what they draw on)
    label = (drawn.get_axes()[0] if hasattr(drawn, "get_axes") else drawn).get_xlabel()
    assert "% of Ts" in label and f"{ts:.1f}" in label and "phase" in label

    html = written[1]
    summary = html.split("<h2>Figures</h2>")[0]
    assert f"{ts:.4g}" in summary  # the summary's Ts is the number of the axis
    caption = re.search(r"<figcaption>(Figure 3[^<]*)</figcaption>", html).group(1)
    assert f"{ts:.1f}" in caption and "percentage of the saturation torque" in caption
    table1 = html.split("Table 1:")[1].split("</table>")[0]
    cells = re.findall(r"<tr>(.*?)</tr>", table1, flags=re.S)
    pct_cells = [re.findall(r"<td[^>]*>(.*?)</td>", c)[2] for c in cells if "<td" in c]
    assert pct_cells == [f"{v:.4g}" for v in pct]  # no "—" beside a known Ts


def test_undetermined_mu_is_not_printed_as_a_value(phase_only, written):
    _, ana = phase_only
    html = written[1]
    polach = html.split("<h2>Polach fit</h2>")[1].split("<h2>")[0]
    assert "μ determined</dt><dd>no" in polach
    mu_row = re.search(r"<tr><td class=\"l\">mu</td>(.*?)</tr>", polach).group(1)
    assert "not determined" in mu_row and "±" not in mu_row
    assert f"{ana.polach.params['mu']:.4g}" not in mu_row
    text = ana.report()
    mu_lines = [ln for ln in text.splitlines() if ln.strip().startswith("mu ")]
    assert mu_lines and all("+/-" not in ln for ln in mu_lines)


def test_figures_numbered_from_one(written):
    folder, html = written
    numbers = [int(n) for n in re.findall(r"<figcaption>Figure (\d+)", html)]
    assert numbers == list(range(1, len(numbers) + 1)) and len(numbers) == 4
    assert sorted(p.stem for p in (folder / "figures").glob("*.png")) == [
        "fig1_signals", "fig2_creep_curve", "fig3_phase", "fig4_mu_from_phase"]


def test_signals_on_one_axes_draw_one_panel(phase_only):
    from matplotlib.figure import Figure

    from torquemod.processing.figures import signals_figure
    res, _ = phase_only
    ax = Figure().subplots()
    signals_figure(res.traces[(3, 1)], step=3, cycle=1, ax=ax)
    titles = [t for a in ax.figure.get_axes() for t in
              (a.get_title("left"), a.get_title(), a.get_title("right")) if t]
    assert len(titles) == 1 and "(a)" not in titles[0] and "(b)" not in titles[0]
    pair = Figure().subplots(2, 1)
    signals_figure(res.traces[(3, 1)], step=3, cycle=1, ax=pair)
    assert [a.get_title("left")[:3] for a in pair] == ["(a)", "(b)"]
