"""The quality report as a PDF typeset by ReportLab: A4 pages with the quality check, the
accuracy statement, the rejection patterns and the metadata with a sign-off block first,
then the same `Part`s as the HTML (report/quality_report.py): tables as tables (long ones:
the worst rows, the whole in the HTML and its CSV), figures as images; searchable text,
"page x of y" on every page."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from reportlab.lib import colors
from reportlab.lib.enums import TA_CENTER
from reportlab.lib.pagesizes import A4
from reportlab.lib.styles import ParagraphStyle, getSampleStyleSheet
from reportlab.lib.units import mm
from reportlab.pdfbase.pdfmetrics import stringWidth
from reportlab.pdfgen import canvas
from reportlab.platypus import (
    Image,
    KeepTogether,
    PageBreak,
    Paragraph,
    SimpleDocTemplate,
    Spacer,
    Table,
    TableStyle,
)

from baarda.io.result_folder import Results
from baarda.output.accuracy import TABLE_FORMATS
from baarda.output.verdict import failures
from baarda.report.front import accuracy, metadata, patterns, quality_check
from baarda.report.plots import DPI, to_png
from baarda.report.quality_report import Part, quality_content
from baarda.table_data import TableData

PDF_ROWS = 25  # rows of a long table in the PDF (the worst)
MARGIN = 14 * mm
WIDTH = A4[0] - 2 * MARGIN
STATUS = {"pass": "#146c2e", "warn": "#8a4b00", "fail": "#9b001b", "info": "#4a5563"}
WORDS = {"pass": "PASS", "warn": "REVIEW", "fail": "FAIL", "info": "NOTE"}


def _styles() -> dict[str, ParagraphStyle]:
    base = getSampleStyleSheet()
    body = ParagraphStyle("body", parent=base["BodyText"], fontName="Helvetica", fontSize=9,
                          leading=11.5, spaceAfter=3)
    return {"body": body,
            "small": ParagraphStyle("small", parent=body, fontSize=8, leading=10),
            "cell": ParagraphStyle("cell", parent=body, fontSize=8, leading=10, spaceAfter=0),
            "h1": ParagraphStyle("h1", parent=base["Heading1"], fontSize=16, spaceAfter=4),
            "h2": ParagraphStyle("h2", parent=base["Heading2"], fontSize=12.5, spaceBefore=8,
                                 spaceAfter=3, textColor=colors.HexColor("#1f3b5a")),
            "h3": ParagraphStyle("h3", parent=base["Heading3"], fontSize=10, spaceBefore=5,
                                 spaceAfter=2),
            "banner": ParagraphStyle("banner", parent=body, fontName="Helvetica-Bold",
                                     textColor=colors.HexColor("#9b001b"), borderPadding=4,
                                     borderColor=colors.HexColor("#9b001b"), borderWidth=1,
                                     spaceBefore=4, spaceAfter=6),
            "status": ParagraphStyle("status", parent=body, fontName="Helvetica-Bold",
                                     fontSize=8, textColor=colors.white, alignment=TA_CENTER)}


def _p(text: str, style: ParagraphStyle) -> Paragraph:
    from xml.sax.saxutils import escape

    return Paragraph(escape(str(text)).replace("\n", "<br/>"), style)


class _NumberedCanvas(canvas.Canvas):
    """A canvas that writes "page x of y" once the number of pages is known."""

    def __init__(self, *args, title: str = "", **kwargs):
        super().__init__(*args, **kwargs)
        self._pages: list[dict] = []
        self._title = title

    def showPage(self):  # noqa: N802 (ReportLab's name)
        self._pages.append(dict(self.__dict__))
        self._startPage()

    def save(self):
        n = len(self._pages)
        for state in self._pages:
            self.__dict__.update(state)
            self.setFont("Helvetica", 8)
            self.setFillColor(colors.HexColor("#333333"))
            self.drawString(MARGIN, 8 * mm, f"baarda quality report: {self._title}"[:100])
            self.drawRightString(A4[0] - MARGIN, 8 * mm, f"page {self._pageNumber} of {n}")
            super().showPage()
        super().save()


PAD = 3.0  # pt of padding on each side of a cell
GAP = 6.0  # pt left free between neighbouring cells' text: a PDF reader's text layer
#            separates them (0 pt ran "002007" and "4600.046" together)
WRAP_AT = 0.45  # a text column wider than this share of the page wraps in its cells


def _table(df: pd.DataFrame, fmt: dict | None, st: dict, head_bg="#eef2f7") -> list:
    """One or more ReportLab tables of df (`pdf_table`), numbers formatted by `fmt`."""
    text = [str(c) for c, t in zip(df.columns, df.dtypes, strict=True)
            if not pd.api.types.is_numeric_dtype(t)]
    return pdf_table(TableData.from_frame(df, fmt, text), st, head_bg)


def pdf_table(table: TableData, st: dict, head_bg="#eef2f7") -> list:
    """The PDF renderer of a table (table_data.py formats its cells): one or more
    ReportLab tables (wide ones split by columns, the first column repeated; a long text
    column wraps within the page)."""
    cols = table.titles
    body = table.cells()
    size = 7.0
    width = [max([stringWidth(c, "Helvetica-Bold", size)] + [
        stringWidth(r[k], "Helvetica", size) for r in body]) + 2 * PAD + GAP
        for k, c in enumerate(cols)]
    wrap = set()
    if sum(width) > WIDTH:  # the widest text columns wrap, in Paragraphs of a capped width
        for k in sorted(range(len(cols)), key=lambda k: -width[k]):
            if sum(width) <= WIDTH or width[k] <= WRAP_AT * WIDTH:
                break
            if table.columns[k].text:
                width[k] = max(WRAP_AT * WIDTH, width[k] - (sum(width) - WIDTH))
                wrap.add(k)
    if wrap:
        cst = ParagraphStyle("wrapcell", parent=st["cell"], fontSize=size, leading=size + 1.5)
        body = [[_p(v, cst) if k in wrap else v for k, v in enumerate(r)] for r in body]
    chunks, cur, used = [], [0], width[0]
    for k in range(1, len(cols)):
        if used + width[k] > WIDTH and len(cur) > 1:
            chunks.append(cur)
            cur, used = [0], width[0]
        cur.append(k)
        used += width[k]
    chunks.append(cur)
    out = []
    for ks in chunks:
        data = [[cols[k] for k in ks]] + [[r[k] for k in ks] for r in body]
        t = Table(data, colWidths=[min(width[k], WIDTH) for k in ks], repeatRows=1)
        t.setStyle(TableStyle([
            ("FONT", (0, 0), (-1, 0), "Helvetica-Bold", size),
            ("FONT", (0, 1), (-1, -1), "Helvetica", size),
            ("BACKGROUND", (0, 0), (-1, 0), colors.HexColor(head_bg)),
            ("GRID", (0, 0), (-1, -1), 0.3, colors.HexColor("#c8cfda")),
            ("ALIGN", (0, 0), (-1, -1), "RIGHT"), ("ALIGN", (0, 0), (0, -1), "LEFT"),
            ("VALIGN", (0, 0), (-1, -1), "TOP"),
            ("LEFTPADDING", (0, 0), (-1, -1), PAD), ("RIGHTPADDING", (0, 0), (-1, -1), PAD),
            ("TOPPADDING", (0, 0), (-1, -1), 1), ("BOTTOMPADDING", (0, 0), (-1, -1), 1)]))
        out += [t, Spacer(1, 4)]
    return out


def _worst(p: Part) -> tuple[pd.DataFrame, str]:
    """The rows of a part's table the PDF shows, and the words that say which."""
    t = p.table
    assert t is not None  # a table part
    if len(t) <= PDF_ROWS:
        return t, ""
    if p.order is not None:
        key = np.nan_to_num(np.asarray(p.order, float), nan=-np.inf)
        keep = np.argsort(-key, kind="stable")[:PDF_ROWS]
        say = f"first {PDF_ROWS}" if p.which == "first" else f"{PDF_ROWS} {p.which}"
        return (t.iloc[keep], f"The {say} of {len(t)} {p.rows_are} (the HTML report links "
                "the whole table as CSV).")
    return t.head(PDF_ROWS), f"The first {PDF_ROWS} of {len(t)} rows."


def _front(res: Results, st: dict) -> list:
    """The first page: banners, the quality check, the accuracy statement, metadata and
    sign-off."""
    v = quality_check(res)
    out: list = [_p(f"Quality report: {res.title}", st["h1"])]
    out += [_p(f, st["banner"]) for f in failures(res.summary)]
    out.append(_p(v.headline, ParagraphStyle("head", parent=st["body"], fontSize=11,
                                             fontName="Helvetica-Bold",
                                             textColor=colors.HexColor(STATUS[v.status]))))
    rows = [[_p(WORDS[r.status], st["status"]), _p(r.label, st["cell"]), _p(r.text, st["cell"])]
            for r in v.rows]
    t = Table(rows, colWidths=[17 * mm, 34 * mm, WIDTH - 51 * mm])
    t.setStyle(TableStyle([("GRID", (0, 0), (-1, -1), 0.3, colors.HexColor("#c8cfda")),
                           ("VALIGN", (0, 0), (-1, -1), "TOP")] + [
        ("BACKGROUND", (0, i), (0, i), colors.HexColor(STATUS[r.status]))
        for i, r in enumerate(v.rows)]))
    out += [_p("Quality check", st["h2"]), t]
    acc = accuracy(res)
    out.append(_p("Accuracy on check points", st["h2"]))
    if acc.stated:
        out += _table(acc.table.drop(columns="n"), TABLE_FORMATS, st)
        out += [_p(f"{k}: {val}", st["body"]) for k, val in acc.statements]
        out.append(_p(acc.statement_text(), st["body"]))
    out += [_p(w, st["body"]) for w in acc.warnings]
    _, advice = patterns(res)
    if advice:
        out.append(_p("Rejection patterns", st["h2"]))
        out += [_p(f"{a.what}. Remedy: {a.remedy}. Where: {a.where}.", st["body"])
                for a in advice]
    from baarda.report.facts import project_facts

    meta = [[_p(k, st["cell"]), _p(val, st["cell"])] for k, val in
            project_facts(res) + metadata(res)]
    mt = Table(meta, colWidths=[45 * mm, WIDTH - 45 * mm])
    mt.setStyle(TableStyle([("VALIGN", (0, 0), (-1, -1), "TOP"),
                            ("LINEBELOW", (0, 0), (-1, -1), 0.2, colors.HexColor("#dddddd"))]))
    sign = Table([["Processed by (name, date)", "Checked by (name, date)",
                   "Accepted for delivery (signature)"], ["", "", ""]],
                 colWidths=[WIDTH / 3] * 3, rowHeights=[12, 28])
    sign.setStyle(TableStyle([("FONT", (0, 0), (-1, -1), "Helvetica", 8),
                              ("LINEABOVE", (0, 0), (-1, 0), 0.6, colors.black)]))
    # the metadata and the sign-off on one page: a sign-off never stands alone
    out += [KeepTogether([_p("Run, input and settings", st["h2"]), mt, Spacer(1, 8),
                          _p("Sign-off", st["h3"]), sign]), PageBreak()]
    return out


def _figure(p: Part, st: dict) -> list:
    import io

    if p.png is not None:  # drawn already: its size from the PNG
        from reportlab.lib.utils import ImageReader

        png = p.png
        w, h = (x / DPI for x in ImageReader(io.BytesIO(png)).getSize())
    else:
        assert p.figure is not None  # a figure part
        fig = p.figure()
        w, h = fig.get_size_inches()
        png = to_png(fig)
    width = min(WIDTH, w * 72)
    img = Image(io.BytesIO(png), width=width, height=width * h / w)
    return [KeepTogether([img, _p(p.text, st["small"])])]


def _side_by_side(figs: list[Part], st: dict) -> list:
    """Drawn figures two to a row, each with its caption (the geometry figures)."""
    import io

    from reportlab.lib.utils import ImageReader

    half = WIDTH / 2 - 6
    cells = []
    for p in figs:
        assert p.png is not None  # drawn already
        w, h = ImageReader(io.BytesIO(p.png)).getSize()
        cells.append([Image(io.BytesIO(p.png), width=half, height=half * h / w),
                      _p(p.text, st["small"])])
    rows = [cells[i:i + 2] + [[]] * (2 - len(cells[i:i + 2])) for i in range(0, len(cells), 2)]
    t = Table(rows, colWidths=[WIDTH / 2] * 2)
    t.setStyle(TableStyle([("VALIGN", (0, 0), (-1, -1), "TOP")]))
    return [t]


def story(res: Results, parts: list[Part]) -> list:
    st = _styles()
    out = _front(res, st)
    drawn: list[Part] = []
    for p in parts:
        if p.kind == "figure" and p.png is not None:
            drawn.append(p)
            continue
        if drawn:
            out += _side_by_side(drawn, st)
            drawn = []
        if p.kind == "alert":
            continue  # on the first page already
        if p.kind == "heading":
            out.append(_p(p.title, st["h2"]))
        elif p.kind == "text":
            out.append(_p(p.text, st["body"]))
        elif p.kind == "table":
            t, note = _worst(p)
            out.append(_p(p.title[0].upper() + p.title[1:], st["h3"]))
            if note:
                out.append(_p(note, st["small"]))
            out += _table(t, p.fmt, st)
        elif p.kind == "figure":
            out += _figure(p, st)
    return out + (_side_by_side(drawn, st) if drawn else [])


def write_quality_pdf(res: Results, path: str | Path, parts: list[Part] | None = None) -> int:
    """The quality report as a PDF (A4 pages); returns the number of pages.  `parts`:
    quality_content(res) when it is at hand."""
    import io

    from baarda.output.atomic import atomic_open

    parts = quality_content(res) if parts is None else parts
    buf = io.BytesIO()
    doc = SimpleDocTemplate(buf, pagesize=A4, leftMargin=MARGIN, rightMargin=MARGIN,
                            topMargin=MARGIN, bottomMargin=16 * mm,
                            title=f"baarda quality report: {res.title}", author="baarda",
                            subject="bundle adjustment quality report")
    doc.build(story(res, parts),
              canvasmaker=lambda *a, **k: _NumberedCanvas(*a, title=res.title, **k))
    data = buf.getvalue()
    with atomic_open(path, "wb") as f:
        f.write(data)
    return _page_count(data)


def _page_count(data: bytes) -> int:
    import re

    return len(re.findall(rb"/Type\s*/Page[^s]", data))
