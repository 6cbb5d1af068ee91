"""Reports a colleague can print or attach: the shared print stylesheet, the PDF made from
any report's HTML with matplotlib (always available) or a headless Chromium (optional)."""

from __future__ import annotations

import re

import pytest

import torquemod as tm
from torquemod.cli import main
from torquemod.demo import synthetic_result
from torquemod.errors import InputError, OptionError
from torquemod.report import ReportOptions, write_report
from torquemod.report import pdf as pdfmod
from torquemod.report.html import CSS, table


@pytest.fixture(scope="module")
def report_html(tmp_path_factory):
    d = tmp_path_factory.mktemp("rep")
    res = synthetic_result(seed=0)
    return write_report(d, res, tm.analyze(res))


def _pages(path) -> int:
    return len(re.findall(rb"/Type\s*/Page\b", path.read_bytes()))


def test_print_stylesheet_is_shared_and_a4():
    assert "@media print" in CSS and "size:A4" in CSS
    assert "thead{display:table-header-group}" in CSS  # headers repeat on each page
    assert "break-inside:avoid" in CSS and "max-height" in CSS  # figures fit a page
    from torquemod.fleet import report as fleetreport
    from torquemod.sweep import report as sweep_report
    assert fleetreport.CSS is CSS and sweep_report.CSS is CSS


def test_parse_report_finds_every_part(report_html):
    title, blocks = pdfmod.parse_report(report_html.read_text(encoding="utf-8"))
    kinds = [b.kind for b in blocks]
    assert title.startswith("torquemod report")
    assert kinds.count("figure") == 4 and all(b.png for b in blocks if b.kind == "figure")
    captions = [b.text for b in blocks if b.kind == "table"]
    assert any(c.startswith("Table 1") for c in captions)
    t1 = next(b for b in blocks if b.kind == "table" and b.text.startswith("Table 1"))
    assert t1.header[0] == "Step" and len(t1.rows) == 6
    assert all(len(r) == len(t1.header) for r in t1.rows)
    assert any(b.kind == "note" for b in blocks)  # folded details are named, not printed


def test_wide_tables_split_into_column_groups_that_fit():
    widths = [4, 12, 12, 12, 12, 12, 12, 12, 12, 12, 12, 12]
    groups = pdfmod._column_groups(widths, avail=60, keep=1)
    assert len(groups) > 1 and all(g[0] == 0 for g in groups)
    assert sorted({i for g in groups for i in g}) == list(range(len(widths)))
    assert all(sum(widths[i] + 2 for i in g) <= 60 for g in groups)


def test_matplotlib_pdf_of_a_report(report_html, tmp_path):
    out = pdfmod.html_to_pdf(report_html, tmp_path / "r.pdf")
    data = out.read_bytes()
    assert data.startswith(b"%PDF") and 2 <= _pages(out) <= 8
    assert [p.name for p in tmp_path.iterdir()] == ["r.pdf"]  # no temporary left behind


def test_a_long_table_runs_over_pages_with_its_header(tmp_path):
    rows = [[str(i), "x" * 50, f"{i * 0.123:.4g}"] for i in range(300)]
    html = (f"<html><head><title>t</title></head><body><h1>t</h1>"
            f"{table(['Row', 'Text', 'Value'], rows, caption='Long', left=2)}</body></html>")
    src = tmp_path / "t.html"
    src.write_text(html, encoding="utf-8")
    out = pdfmod.html_to_pdf(src)
    assert out == tmp_path / "t.pdf" and _pages(out) >= 3


def test_pdf_engine_is_checked_and_a_missing_chromium_is_named(report_html, tmp_path,
                                                              monkeypatch):
    with pytest.raises(OptionError, match="pdf"):
        ReportOptions(pdf="word")
    with pytest.raises(InputError, match="unknown PDF engine"):
        pdfmod.html_to_pdf(report_html, tmp_path / "x.pdf", engine="word")
    monkeypatch.setattr(pdfmod, "find_chromium", lambda: None)
    with pytest.raises(InputError, match="no Chromium"):
        pdfmod.html_to_pdf(report_html, tmp_path / "x.pdf", engine="chromium")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(pdfmod.find_chromium() is None, reason="the optional engine needs a "
                    "Chromium on the PATH (apt-get install chromium)")
def test_chromium_pdf_of_a_report(report_html, tmp_path):
    out = pdfmod.html_to_pdf(report_html, tmp_path / "c.pdf", engine="chromium")
    assert out.read_bytes().startswith(b"%PDF") and _pages(out) >= 2


def test_report_pdf_lives_and_dies_with_its_report(tmp_path, capsys):
    folder = tmp_path / "r"
    res = synthetic_result(seed=0, n_cycles=1)
    tm.save(res, tm.analyze(res), folder, report=False)
    assert main(["report", str(folder), "--pdf", "--quiet"]) == 0
    assert (folder / "report.pdf").read_bytes().startswith(b"%PDF")
    assert "pdf:" in capsys.readouterr().out
    # redrawn without --pdf: no stale PDF beside it (the report's own writer, no CLI)
    write_report(folder, res, tm.analyze(res), options={"formats": ("png",)})
    assert not (folder / "report.pdf").exists()
