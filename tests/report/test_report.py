"""Figures (headless) and the self-contained HTML report."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from html.parser import HTMLParser

import pytest
from matplotlib.axes import Axes
from matplotlib.figure import Figure

import torquemod as tm
from torquemod.demo import synthetic_result
from torquemod.errors import InputError
from torquemod.processing.figures import signals_figure
from torquemod.report import ReportOptions, write_report
from torquemod.report.figures import (
    creep_curve_figure,
    figure_of,
    phase_figure,
    phase_fit_figure,
    save_figure,
)

FIGURES = ("fig1_signals", "fig2_creep_curve", "fig3_phase")
TABLE1_HEADERS = ("Step", "DC applied torque [N·m]", "DC torque [% Ts]", "Phase φ [deg]",
                  "Theory φ [deg]")
TABLE2_HEADERS = ("Cycle", "Peak frequency torque [Hz]",
                  "Peak frequency wheel angular velocity [Hz]",
                  "Common modulation frequency [Hz]")


class _Collect(HTMLParser):
    def __init__(self):
        super().__init__()
        self.tags: dict[str, int] = {}
        self.attrs: list[tuple[str, str, str | None]] = []
        self.headers: list[str] = []
        self.captions: list[str] = []
        self._in: str | None = None
        self._buf = ""

    def handle_starttag(self, tag, attrs):
        self.tags[tag] = self.tags.get(tag, 0) + 1
        self.attrs += [(tag, k, v) for k, v in attrs]
        if tag in ("th", "caption"):
            self._in, self._buf = tag, ""

    def handle_endtag(self, tag):
        if tag == self._in:
            (self.headers if tag == "th" else self.captions).append(self._buf.strip())
            self._in = None

    def handle_data(self, data):
        if self._in:
            self._buf += data


def parse(path):
    p = _Collect()
    p.feed(path.read_text(encoding="utf-8"))
    return p


@pytest.fixture(scope="module")
def synthetic():
    res = synthetic_result(seed=0)
    return res, tm.analyze(res)


def _report(tmp_path, res, ana, options=None):
    return write_report(tmp_path, res, ana, options=options)


def test_figures_are_headless_figures(synthetic, tmp_path):
    res, ana = synthetic
    assert (3, 1) in res.traces
    figs = {"a": signals_figure(res.traces[(3, 1)], step=3, cycle=1),
            "b": creep_curve_figure(ana, coa_multiplier=10, creepage_multiplier=2),
            "c": phase_figure(ana), "d": phase_fit_figure(ana)}
    assert len(figs["a"]) == 2 and isinstance(figs["a"][0].figure, Figure)
    for name, drawn in figs.items():
        paths = save_figure(drawn, tmp_path / "out" / name)
        assert [p.suffix for p in paths] == [".png", ".svg"]
        assert all(p.stat().st_size > 1000 for p in paths)
    figs = {k: figure_of(v) for k, v in figs.items()}
    assert all(isinstance(f, Figure) for f in figs.values())
    legend = [t.get_text() for t in figs["b"].axes[0].get_legend().get_texts()]
    assert any("10× std CoA" in t and "2× std creepage" in t for t in legend)
    assert any("μ = 0.2" in t for t in legend)
    # Figure 3 marks the onset step (step 3 of the synthetic data)
    legend4 = [t.get_text() for t in figs["c"].axes[0].get_legend().get_texts()]
    assert "saturation onset (step 3)" in legend4
    with pytest.raises(InputError):
        res.plot_signals(99, 1)


def test_plots_draw_on_a_given_ax(synthetic):
    """A plot method given an ax returns that Axes (a notebook cell then shows the figure
    once); without one it returns the Axes of a new Figure that pyplot does not hold."""
    import matplotlib.pyplot as plt
    res, ana = synthetic
    plt.close("all")
    fig = Figure()
    axes = fig.subplots(1, 4)
    assert ana.plot_creep_curve(ax=axes[0]) is axes[0]
    assert ana.plot_phase(ax=axes[1]) is axes[1]
    assert ana.plot_phase_fit(ax=axes[2]) is axes[2]
    assert res.plot_signals(3, 1, ax=axes[3]) is axes[3]
    assert len(fig.axes) == 5  # the wheel speed on a twin axis of the fourth
    assert all(len(a.lines) > 0 for a in fig.axes)
    pair = Figure().subplots(2, 1)
    assert res.plot_signals(3, 1, ax=pair) is pair
    for made in (ana.plot_creep_curve(), ana.plot_phase(), ana.plot_phase_fit()):
        assert isinstance(made, Axes) and isinstance(made.figure, Figure)
    two = res.plot_signals(3, 1)
    assert len(two) == 2 and two[0].figure is two[1].figure
    assert plt.get_fignums() == []  # nothing went through pyplot


def test_report_modules_do_not_need_pyplot():
    code = ("import sys, torquemod, torquemod.report, torquemod.report.figures; "
            "assert 'matplotlib.pyplot' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_report_contains_every_figure_and_table(synthetic, tmp_path):
    res, ana = synthetic
    path = _report(tmp_path, res, ana)
    assert path == tmp_path / "report.html"
    for name in FIGURES:
        for ext in ("png", "svg"):
            assert (tmp_path / "figures" / f"{name}.{ext}").stat().st_size > 1000
    p = parse(path)
    imgs = [v for t, k, v in p.attrs if t == "img" and k == "src"]
    assert len(imgs) == 4  # Figures 2-4 and 5 (mu from the phase)
    assert all(v.startswith("data:image/png;base64,") for v in imgs)
    for h in TABLE1_HEADERS + TABLE2_HEADERS + ("Parameter", "Standard error"):
        assert h in p.headers, h
    assert any(c.startswith("Table 1") for c in p.captions)
    assert any(c.startswith("Table 2") for c in p.captions)
    text = path.read_text(encoding="utf-8")
    # self-contained: no external references of any kind
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", text, re.I)
    assert not re.search(r"url\(\s*['\"]?https?:", text, re.I)
    assert "<link" not in text and "<script" not in text
    for key in ("Coefficient of friction μ", "Saturation torque", "Saturation onset",
                "RMS difference", "Provenance", "Warnings"):
        assert key in text
    assert "step 3" in text  # the onset of the synthetic data (true k halved at step 3)
    assert text.count("<tr>") >= len(res.cycles) + 6
    # Table 2 per step (6 rows, not 18 of nearly the same number), per cycle folded away
    assert "Table 2: modulation frequencies from the FFT, mean over each step" in text
    assert "<summary>Modulation frequencies per cycle</summary>" in text
    # creepage in % in Table 1, as in Figure 2: step 6's 100*xi appears
    xi6 = 100 * float(res.steps.loc[res.steps.step == 6, "creepage"].iloc[0])
    assert f"<td>{xi6:.4g}</td>" in text
    # tables scroll instead of overflowing; numbers do not wrap
    assert '<div class="scroll"><table>' in text and "white-space:nowrap" in text
    # SVG text is text, not outlines
    svg = (tmp_path / "figures" / "fig2_creep_curve.svg").read_text(encoding="utf-8")
    assert "<text" in svg and "Longitudinal creepage" in svg


def test_report_title_names_the_experiment_and_says_onset_once(synthetic, tmp_path):
    res, ana = synthetic
    text = _report(tmp_path, res, ana).read_text(encoding="utf-8")
    assert "<title>torquemod report: synthetic</title>" in text
    assert text.count("tan(phase) at least") == 1  # the onset criterion, said once
    # no optimiser status text (scipy's message) in the report
    assert ana.polach.message and ana.polach.message not in text
    assert "status" not in text.split("Fit converged", 1)[1].split("</dd>", 1)[0]


def test_report_converged_only_for_a_monotone_curve(synthetic, tmp_path):
    """'Fit converged: yes' needs the fitted curve to rise monotonically up to its maximum;
    a curve with a dip (theta made up: a negative kS*s gives a curve that first falls) is
    reported with what is wrong."""
    res, ana = synthetic
    text = _report(tmp_path / "a", res, ana).read_text(encoding="utf-8")
    assert re.search(r"Fit converged</dt><dd>yes<", text)
    bent = dataclasses.replace(ana.polach, theta=ana.polach.theta * [1.0, 1.0, -3.0])
    assert not bent.curve([1e-4]) > 0  # the made-up curve starts downwards
    bad = dataclasses.replace(ana, polach=bent)
    assert bad.converged is False and "does not rise" in bad.curve_ok[1]
    text = _report(tmp_path / "b", res, bad).read_text(encoding="utf-8")
    assert re.search(r"Fit converged</dt><dd>no: the fitted curve does not rise", text)
    assert bad.to_dict()["converged"] is False


def test_report_escapes_text(synthetic, tmp_path):
    res, ana = synthetic
    evil = dataclasses.replace(res, warnings=[*res.warnings,
                                              "<script>alert('x')</script> & more"])
    text = write_report(tmp_path, evil, ana, options={"title": "<b>evil</b>"}).read_text(
        encoding="utf-8")
    assert "<script>" not in text and "<b>evil</b>" not in text
    assert "&lt;script&gt;alert(&#x27;x&#x27;)&lt;/script&gt; &amp; more" in text


def test_report_options_and_fallbacks(synthetic, tmp_path):
    res, ana = synthetic
    opts = ReportOptions(step=42, cycle=7, coa_multiplier=15, creepage_multiplier=3,
                         formats=("png",), title="Lab run 7")
    text = _report(tmp_path / "a", res, ana, opts).read_text(encoding="utf-8")
    assert "<title>Lab run 7</title>" in text
    assert "step 42 cycle 7 has no traces" in text
    assert "15× the standard deviation" in text
    assert not list((tmp_path / "a" / "figures").glob("*.svg"))
    with pytest.raises(InputError):
        ReportOptions.coerce({"colour": "red"})
    bare = dataclasses.replace(res, traces={})
    p = parse(_report(tmp_path / "b", bare, ana))
    assert sum(1 for t, k, _ in p.attrs if t == "img" and k == "src") == 3


def test_report_when_mu_undetermined(tmp_path):
    res = synthetic_result(saturation_fractions=(0.01, 0.05, 0.1, 0.15, 0.2, 0.25))
    text = _report(tmp_path, res, tm.analyze(res)).read_text(encoding="utf-8")
    assert "not determined" in text
    assert "do not determine the friction coefficient" in text
    assert text.count("data:image/png;base64,") == 4
