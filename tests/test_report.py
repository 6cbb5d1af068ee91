"""Figures (headless) and the self-contained HTML report."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from html.parser import HTMLParser

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from torquemod.analysis import fit_results_folder
from torquemod.demo import write_synthetic_results
from torquemod.errors import InputError
from torquemod.report import ReportOptions, write_report
from torquemod.report.figures import (
    available_cycles,
    creep_curve_figure,
    phase_figure,
    save_figure,
    signals_figure,
)

FIGURES = ("fig2_signals", "fig3_creep_curve", "fig4_phase")
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


@pytest.fixture
def results(tmp_path):
    return write_synthetic_results(tmp_path / "results", seed=0)


def test_figures_are_headless_figures(results):
    fit_results_folder(results)
    fit = json.loads((results / "fit.json").read_text())
    steps = pd.read_csv(results / "steps.csv")
    with np.load(results / "traces.npz") as npz:
        traces = {k: npz[k] for k in npz.files}
    assert (3, 1) in available_cycles(traces)
    figs = {"a": signals_figure(traces, step=3, cycle=1),
            "b": creep_curve_figure(steps, fit, coa_multiplier=10, creepage_multiplier=2),
            "c": phase_figure(steps, fit)}
    for name, fig in figs.items():
        assert isinstance(fig, Figure)
        paths = save_figure(fig, results / "out" / name)
        assert [p.suffix for p in paths] == [".png", ".svg"]
        assert all(p.stat().st_size > 1000 for p in paths)
    legend = [t.get_text() for t in figs["b"].axes[0].get_legend().get_texts()]
    assert any("10× std CoA" in t and "2× std creepage" in t for t in legend)
    assert any("μ = 0.2" in t for t in legend)
    with pytest.raises(InputError):
        signals_figure(traces, step=99, cycle=1)


def test_report_modules_do_not_need_pyplot():
    code = ("import sys, torquemod.report, torquemod.report.figures; "
            "assert 'matplotlib.pyplot' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_report_contains_every_figure_and_table(results):
    path = write_report(results)  # runs the fit first: no fit.json yet
    assert path == results / "report.html"
    for name in FIGURES:
        for ext in ("png", "svg"):
            assert (results / "figures" / f"{name}.{ext}").stat().st_size > 1000
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
    n_cycles = len(pd.read_csv(results / "cycles.csv"))
    assert text.count("<tr>") >= n_cycles + 6


def test_report_escapes_text(results):
    prov_path = results / "provenance.json"
    prov = json.loads(prov_path.read_text())
    prov["warnings"].append("<script>alert('x')</script> & more")
    prov["experiment"]["manifest"] = "<b>evil</b>.toml"
    prov_path.write_text(json.dumps(prov))
    text = write_report(results).read_text(encoding="utf-8")
    assert "<script>" not in text and "<b>evil</b>" not in text
    assert "&lt;script&gt;alert(&#x27;x&#x27;)&lt;/script&gt; &amp; more" in text


def test_report_options_and_fallbacks(results):
    opts = ReportOptions(step=42, cycle=7, coa_multiplier=15, creepage_multiplier=3,
                         formats=("png",), title="Lab run 7")
    text = write_report(results, options=opts).read_text(encoding="utf-8")
    assert "<title>Lab run 7</title>" in text
    assert "step 42 cycle 7 has no traces" in text
    assert "15× the standard deviation" in text
    assert not list((results / "figures").glob("*.svg"))
    with pytest.raises(InputError):
        ReportOptions.coerce({"colour": "red"})
    (results / "traces.npz").unlink()
    p = parse(write_report(results, options={"refit": True}))
    assert sum(1 for t, k, _ in p.attrs if t == "img" and k == "src") == 3


def test_report_when_mu_undetermined(tmp_path):
    d = write_synthetic_results(tmp_path / "r", saturation_fractions=(0.01, 0.05, 0.1, 0.15,
                                                                       0.2, 0.25))
    text = write_report(d).read_text(encoding="utf-8")
    assert "not determined" in text
    assert "do not determine the friction coefficient" in text
    assert text.count("data:image/png;base64,") == 4
