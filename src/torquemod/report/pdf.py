"""A PDF of any torquemod HTML report, for attaching to a mail or printing on A4.

:func:`html_to_pdf` reads the report's own HTML (headings, paragraphs, key/value lists,
tables, figures with captions; folded ``<details>`` are named, not printed) and lays it out
on A4 pages with matplotlib's PDF backend, a declared dependency, so it works wherever
torquemod installs. Tables wider than the page are split into column groups that repeat
the first column; rows split across pages repeat the header; figures are scaled to the text
width. ``engine="chromium"`` prints the page with a headless Chromium instead (the report's
print stylesheet applies), when one is installed.
"""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import tempfile
import textwrap
from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path
from typing import ClassVar

from torquemod.errors import InputError, OutputError

__all__ = ["PDF_ENGINES", "find_chromium", "html_to_pdf", "parse_report"]

PDF_ENGINES = ("matplotlib", "chromium")

# A4 in inches, margins, fonts [pt]; a monospace cell is 0.6 em wide (DejaVu Sans Mono)
PAGE_W, PAGE_H, MARGIN = 8.27, 11.69, 0.6
TEXT_W = PAGE_W - 2 * MARGIN
BODY_PT, SMALL_PT, TABLE_PT = 9.0, 7.5, 6.5
MONO_EM = 0.6
PROSE_EM = 0.56  # DejaVu Sans' mean advance is ~0.52 em: wrap a little early, never past
MAX_FIG_H = 4.4  # [in]: two figures with their captions on a page
MAX_CELL = 34  # [characters]: longer cells wrap within their column


# --------------------------------------------------------------------------- parsing

@dataclass
class Block:
    """One block of a report page as the PDF writer lays it out.

    Attributes
    ----------
    kind : str
        What the block is: h1, h2, h3, p, warn, kv, table, figure, pre or note.
    text : str
        Its text.
    pairs : list
        Key-value pairs of a definition list.
    header : list
        A table's header.
    rows : list
        A table's rows.
    left : list
        Which columns are left-aligned.
    png : bytes or None
        A figure's image.
    """

    kind: str  # h1 h2 h3 p warn kv table figure pre note
    text: str = ""
    pairs: list = field(default_factory=list)
    header: list = field(default_factory=list)
    rows: list = field(default_factory=list)
    left: list = field(default_factory=list)  # per column: left-aligned (text), else numbers
    png: bytes | None = None


class _ReportParser(HTMLParser):
    """Our reports' HTML as a list of :class:`Block` (only the tags the reports use)."""

    TEXT_TAGS: ClassVar[set[str]] = {"h1", "h2", "h3", "h4", "p", "li", "caption",
                                     "figcaption", "dt", "dd", "th", "td", "pre", "summary",
                                     "title"}

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.blocks: list[Block] = []
        self.title = ""
        self._text: list[str] | None = None
        self._tag = ""
        self._cls = ""
        self._table: Block | None = None
        self._row: list[str] | None = None
        self._row_is_head = False
        self._kv: Block | None = None
        self._figure: Block | None = None
        self._details = 0
        self._summary = ""
        self._skip = 0  # <style>, <script>

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag in ("style", "script"):
            self._skip += 1
        elif tag == "details":
            self._details += 1
        elif tag == "table" and not self._details:
            self._table = Block("table")
        elif tag == "tr" and self._table is not None:
            self._row, self._row_is_head = [], True
        elif tag == "dl" and not self._details:
            self._kv = Block("kv")
        elif tag == "figure" and not self._details:
            self._figure = Block("figure")
        elif tag == "img" and self._figure is not None:
            src = a.get("src") or ""
            if src.startswith("data:image/png;base64,"):
                import base64
                self._figure.png = base64.b64decode(src.split(",", 1)[1])
        elif tag == "br" and self._text is not None:
            self._text.append("\n")
        if tag in self.TEXT_TAGS and not self._skip:
            self._text, self._tag, self._cls = [], tag, a.get("class") or ""
            if tag == "td":
                self._row_is_head = False

    def handle_endtag(self, tag):
        if tag in ("style", "script"):
            self._skip = max(0, self._skip - 1)
            return
        if tag == self._tag and self._text is not None:
            text = " ".join("".join(self._text).split()) if tag != "pre" \
                else "".join(self._text)
            self._text, self._tag = None, ""
            self._text_done(tag, text)
        if tag == "tr" and self._table is not None and self._row is not None:
            if self._row_is_head and not self._table.header:
                self._table.header = self._row
            elif self._row:
                self._table.rows.append(self._row)
            self._row = None
        elif tag == "table" and self._table is not None:
            self.blocks.append(self._table)
            self._table = None
        elif tag == "dl" and self._kv is not None:
            self.blocks.append(self._kv)
            self._kv = None
        elif tag == "figure" and self._figure is not None:
            if self._figure.png is not None:
                self.blocks.append(self._figure)
            self._figure = None
        elif tag == "details" and self._details:
            self._details -= 1
            if not self._details and self._summary:
                self.blocks.append(Block("note", f"{self._summary}: folded in the HTML "
                                                 "report, not printed here"))
                self._summary = ""

    def _text_done(self, tag, text):
        if tag == "title":
            self.title = text
        elif tag == "summary":
            self._summary = text
        elif self._details:
            return
        elif tag in ("th", "td") and self._row is not None:
            self._row.append(text)
            if tag == "th" and self._table is not None and not self._table.header:
                self._table.left.append("l" in self._cls.split())
        elif tag == "caption" and self._table is not None:
            self._table.text = text
        elif tag == "figcaption" and self._figure is not None:
            self._figure.text = text
        elif tag == "dt" and self._kv is not None:
            self._kv.pairs.append([text, ""])
        elif tag == "dd" and self._kv is not None and self._kv.pairs:
            self._kv.pairs[-1][1] = text
        elif tag in ("h1", "h2", "h3", "h4"):
            self.blocks.append(Block("h3" if tag == "h4" else tag, text))
        elif tag == "li":
            self.blocks.append(Block("p", "• " + text))
        elif tag == "pre":
            self.blocks.append(Block("pre", text))
        elif tag == "p" and text:
            self.blocks.append(Block("warn" if "warn" in self._cls else "p", text))

    def handle_data(self, data):
        if self._text is not None and not self._skip:
            self._text.append(data)


def parse_report(html_text: str) -> tuple[str, list[Block]]:
    """The page title and blocks of a report's HTML.

    Parameters
    ----------
    html_text : str
        The report.

    Returns
    -------
    title : str
        The page's title.
    blocks : list of Block
        Its blocks, in order.
    """
    p = _ReportParser()
    p.feed(html_text)
    p.close()
    return p.title, p.blocks


# --------------------------------------------------------------------------- layout

def _wrap(text: str, chars: int) -> list[str]:
    out = []
    for para in str(text).split("\n"):
        out += textwrap.wrap(para, max(chars, 4), break_long_words=True,
                             break_on_hyphens=False) or [""]
    return out


def _chars(width_in: float, pt: float, em: float) -> int:
    return int(width_in * 72 / (pt * em))


def _line_h(pt: float) -> float:
    return 1.3 * pt / 72


class _Pages:
    """A4 pages drawn top to bottom; a new page when the next piece does not fit."""

    def __init__(self, pdf, title: str):
        self.pdf, self.title, self.page, self.fig, self.y = pdf, title, 0, None, 0.0

    def new(self):
        from matplotlib.figure import Figure
        self.close_page()
        self.page += 1
        self.fig = Figure(figsize=(PAGE_W, PAGE_H))
        self.y = PAGE_H - MARGIN
        self.fig.text(PAGE_W / 2 / PAGE_W, 0.35 / PAGE_H, f"{self.title} — page {self.page}",
                      ha="center", va="bottom", fontsize=7, color="0.4")

    def close_page(self):
        if self.fig is not None:
            self.pdf.savefig(self.fig)
            self.fig = None

    def need(self, height: float):
        if self.fig is None or self.y - height < MARGIN:
            self.new()

    def text(self, x_in: float, line: str, pt: float, **kw):
        self.fig.text(x_in / PAGE_W, self.y / PAGE_H, line, fontsize=pt, va="top",
                      ha="left", **kw)

    def lines(self, lines: list[str], pt: float, x_in: float = MARGIN, **kw):
        for line in lines:
            self.need(_line_h(pt))
            self.text(x_in, line, pt, **kw)
            self.y -= _line_h(pt)


def _column_groups(widths: list[int], avail: int, keep: int) -> list[list[int]]:
    """Column indices per printed part: as many columns as fit in ``avail`` characters, the
    first ``keep`` columns repeated in each part."""
    fixed = list(range(min(keep, len(widths))))
    base = sum(widths[i] + 2 for i in fixed)
    groups, cur, used = [], [], base
    for i in range(len(fixed), len(widths)):
        if cur and used + widths[i] + 2 > avail:
            groups.append(fixed + cur)
            cur, used = [], base
        cur.append(i)
        used += widths[i] + 2
    if cur or not groups:
        groups.append(fixed + cur)
    return groups


def _draw_table(pages: _Pages, block: Block):
    header = block.header or []
    ncol = max([len(header), *[len(r) for r in block.rows]] or [0])
    if ncol == 0:
        return
    header = header + [""] * (ncol - len(header))
    rows = [r + [""] * (ncol - len(r)) for r in block.rows]
    avail = _chars(TEXT_W, TABLE_PT, MONO_EM)
    widths = []
    for j in range(ncol):
        cells = max([len(r[j]) for r in rows] or [0])
        words = max([len(w) for w in header[j].split()] or [0])
        # as wide as the cells, the header's longest word, and a header in <= 3 lines
        widths.append(max(3, min(MAX_CELL, max(cells, words, -(-len(header[j]) // 3)))))
    left = block.left + [True] * (ncol - len(block.left)) if block.left else [True] * ncol

    def _cell(pages, x, y, line, j, bold=False):
        """One line of a cell: text left-aligned, numbers right-aligned in the column."""
        if not left[j]:
            x += widths[j] * TABLE_PT * MONO_EM / 72
        pages.fig.text(x / PAGE_W, y / PAGE_H, line, fontsize=TABLE_PT, family="monospace",
                       va="top", ha="left" if left[j] else "right",
                       weight="bold" if bold else "normal")

    groups = _column_groups(widths, avail, keep=1 if ncol > 2 else 0)
    lh = _line_h(TABLE_PT)
    for k, cols in enumerate(groups):
        caption = block.text + (f" (part {k + 1} of {len(groups)})" if len(groups) > 1 else "")
        head = [_wrap(header[j], widths[j]) for j in cols]
        head_h = max(len(h) for h in head) * lh
        first = _wrap(caption, _chars(TEXT_W, SMALL_PT, PROSE_EM)) if caption else []
        pages.need(len(first) * _line_h(SMALL_PT) + head_h + 2 * lh)
        pages.lines(first, SMALL_PT, weight="bold")

        def draw_head(cols=cols, head=head, head_h=head_h):
            x = MARGIN
            top = pages.y
            for j, h in zip(cols, head, strict=True):
                for n, line in enumerate(h):
                    _cell(pages, x, top - n * lh, line, j, bold=True)
                x += (widths[j] + 2) * TABLE_PT * MONO_EM / 72
            pages.y = top - head_h
            _rule(pages, 0.6)

        draw_head()
        for r in rows:
            cells = [_wrap(r[j], widths[j]) for j in cols]
            h = max(len(c) for c in cells) * lh
            if pages.y - h < MARGIN:
                pages.new()
                pages.lines([f"{caption} (continued)"] if caption else [], SMALL_PT,
                            weight="bold")
                draw_head()
            x = MARGIN
            for j, c in zip(cols, cells, strict=True):
                for n, line in enumerate(c):
                    _cell(pages, x, pages.y - n * lh, line, j)
                x += (widths[j] + 2) * TABLE_PT * MONO_EM / 72
            pages.y -= h
            _rule(pages, 0.2)
        pages.y -= 0.12


def _rule(pages: _Pages, lw: float):
    from matplotlib.lines import Line2D
    y = (pages.y + 0.02) / PAGE_H
    pages.fig.add_artist(Line2D([MARGIN / PAGE_W, 1 - MARGIN / PAGE_W], [y, y], lw=lw,
                                color="0.5", transform=pages.fig.transFigure))
    pages.y -= 0.03


def _draw_figure(pages: _Pages, block: Block):
    from matplotlib.image import imread
    img = imread(io.BytesIO(block.png), format="png")
    h_px, w_px = img.shape[:2]
    w = TEXT_W
    h = w * h_px / w_px
    if h > MAX_FIG_H:
        h, w = MAX_FIG_H, MAX_FIG_H * w_px / h_px
    cap = _wrap(block.text, _chars(TEXT_W, SMALL_PT, PROSE_EM))
    pages.need(h + len(cap) * _line_h(SMALL_PT) + 0.1)
    ax = pages.fig.add_axes([(MARGIN + (TEXT_W - w) / 2) / PAGE_W, (pages.y - h) / PAGE_H,
                             w / PAGE_W, h / PAGE_H])
    ax.imshow(img, interpolation="antialiased")
    ax.set_axis_off()
    pages.y -= h + 0.05
    pages.lines(cap, SMALL_PT, color="0.25")
    pages.y -= 0.15


def _draw_kv(pages: _Pages, block: Block):
    key_w = 0.36 * TEXT_W
    key_chars = _chars(key_w - 0.1, BODY_PT, PROSE_EM)
    val_chars = _chars(TEXT_W - key_w, BODY_PT, PROSE_EM)
    lh = _line_h(BODY_PT)
    for k, v in block.pairs:
        kl, vl = _wrap(k, key_chars), _wrap(v, val_chars)
        n = max(len(kl), len(vl))
        if n * lh > PAGE_H - 2 * MARGIN - 0.5:  # a very long value: key, then the value
            pages.lines(kl, BODY_PT, weight="bold")
            pages.lines(vl, BODY_PT)
            continue
        pages.need(n * lh)
        for i in range(n):
            if i < len(kl):
                pages.text(MARGIN, kl[i], BODY_PT, weight="bold")
            if i < len(vl):
                pages.text(MARGIN + key_w, vl[i], BODY_PT)
            pages.y -= lh
        pages.y -= 0.03
    pages.y -= 0.08


def _draw(pages: _Pages, block: Block):
    prose = _chars(TEXT_W, BODY_PT, PROSE_EM)
    if block.kind == "h1":
        pages.need(0.8)
        pages.lines(_wrap(block.text, _chars(TEXT_W, 15, PROSE_EM)), 15, weight="bold")
        pages.y -= 0.1
    elif block.kind in ("h2", "h3"):
        pt = 12 if block.kind == "h2" else 10
        pages.need(1.6)  # a heading is never the last line of a page
        pages.y -= 0.12
        pages.lines(_wrap(block.text, _chars(TEXT_W, pt, PROSE_EM)), pt, weight="bold")
        _rule(pages, 0.5)
        pages.y -= 0.04
    elif block.kind in ("p", "note"):
        pages.lines(_wrap(block.text, prose), BODY_PT if block.kind == "p" else SMALL_PT,
                    color="0.1" if block.kind == "p" else "0.4")
        pages.y -= 0.06
    elif block.kind == "warn":
        pages.lines(_wrap("⚠ " + block.text, prose), BODY_PT, color="#8a5a00")
        pages.y -= 0.06
    elif block.kind == "pre":
        lines = [seg for ln in block.text.splitlines()
                 for seg in _wrap(ln, _chars(TEXT_W, TABLE_PT, MONO_EM))]
        pages.lines(lines, TABLE_PT, family="monospace")
    elif block.kind == "kv":
        _draw_kv(pages, block)
    elif block.kind == "table":
        _draw_table(pages, block)
    elif block.kind == "figure":
        _draw_figure(pages, block)


def _render_matplotlib(html_text: str, out: Path) -> int:
    from matplotlib.backends.backend_pdf import PdfPages
    title, blocks = parse_report(html_text)
    with PdfPages(out, metadata={"Title": title or "torquemod report",
                                 "Creator": "torquemod"}) as pdf:
        pages = _Pages(pdf, title or "torquemod report")
        pages.new()
        for block in blocks:
            _draw(pages, block)
        pages.close_page()
        return pages.page


def find_chromium() -> str | None:
    """The first Chromium or Chrome on the PATH.

    Returns
    -------
    str or None
        Its path (``TORQUEMOD_CHROMIUM`` names one to prefer); None when there is none.
    """
    names = [os.environ.get("TORQUEMOD_CHROMIUM") or "", "chromium", "chromium-browser",
             "google-chrome", "google-chrome-stable"]
    return next((shutil.which(n) for n in names if n and shutil.which(n)), None)


def _render_chromium(html_path: Path, out: Path) -> None:
    exe = find_chromium()
    if exe is None:
        raise InputError("no Chromium or Chrome found on the PATH (or TORQUEMOD_CHROMIUM) for "
                         "the chromium PDF engine", hint="use the matplotlib engine, which "
                         "needs nothing more")
    with tempfile.TemporaryDirectory(prefix="torquemod-chromium-") as profile:
        cmd = [exe, "--headless", "--disable-gpu", "--no-sandbox", "--no-pdf-header-footer",
               f"--user-data-dir={profile}", f"--print-to-pdf={out}",
               html_path.resolve().as_uri()]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=180, check=False)
    if done.returncode != 0 or not out.is_file() or out.stat().st_size == 0:
        tail = " ".join((done.stderr or "").split()[-30:])
        raise OutputError(f"{out}: Chromium could not print the report ({tail})")


def html_to_pdf(html_path, pdf_path=None, *, engine: str = "matplotlib") -> Path:
    """Write a report as a PDF; the file appears whole or not at all.

    Parameters
    ----------
    html_path : str or pathlib.Path
        The report.
    pdf_path : str or pathlib.Path or None
        The PDF; None: beside the report, ``.pdf``.
    engine : {"matplotlib", "chromium"}
        "matplotlib" (always available) or "chromium" (a headless Chromium on the PATH prints
        the page with its print stylesheet). Default "matplotlib".

    Returns
    -------
    pathlib.Path
        The PDF.

    Raises
    ------
    InputError
        An unknown engine, an unreadable report, or no Chromium for that engine.
    OutputError
        Chromium could not print the report.
    """
    if engine not in PDF_ENGINES:
        raise InputError(f"unknown PDF engine {engine!r}; choose one of {PDF_ENGINES}")
    html_path = Path(html_path)
    out = Path(pdf_path) if pdf_path is not None else html_path.with_suffix(".pdf")
    try:
        html_text = html_path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the report ({getattr(exc, 'strerror', None) or exc})",
                         path=html_path) from None
    fd, tmp_name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        if engine == "chromium":
            _render_chromium(html_path, tmp)
        else:
            _render_matplotlib(html_text, tmp)
        os.chmod(tmp, 0o644)
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return out
