"""The quality report (report/quality_report.py) as a PDF of A4 pages: the same `Part`s as
the HTML, laid out by matplotlib's PdfPages (tables drawn as text, figures as vector
graphics)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from baarda.output.result_folder import Results  # noqa: E402
from baarda.report.html_base import cell as format_cell  # noqa: E402
from baarda.report.plots import to_png  # noqa: E402
from baarda.report.quality_report import Part, quality_content  # noqa: E402

A4 = (8.27, 11.69)
ROWS_PER_PAGE = 46


def _text_lines(t: pd.DataFrame, fmt: dict | None) -> list[str]:
    fmt = fmt or {}
    cells = [[str(c) for c in t.columns]] + [
        [(format_cell(v, fmt.get(c)) if not isinstance(v, str) else v) for c, v in
         zip(t.columns, r, strict=True)] for r in t.itertuples(index=False)]
    cells = [[c[:48] for c in row] for row in cells]
    width = [max(len(row[k]) for row in cells) for k in range(len(cells[0]))]
    return ["  ".join(c.rjust(w) for c, w in zip(row, width, strict=True)) for row in cells]


def write_quality_pdf(res: Results, path: str | Path, parts: list[Part] | None = None) -> int:
    """The quality report as a PDF (A4 pages); returns the number of pages.  `parts`:
    quality_content(res) when it is at hand."""
    parts = quality_content(res) if parts is None else parts
    from matplotlib.backends.backend_pdf import PdfPages

    from baarda.output.atomic import atomic_open

    pages = 0
    with plt.rc_context({"pdf.fonttype": 42}), atomic_open(path, "wb") as f, \
            PdfPages(f, metadata={"Title": f"baarda quality report: {res.title}"}) as pdf:
        fig, y = None, 0.0

        def new_page():
            nonlocal fig, y, pages
            if fig is not None:
                pdf.savefig(fig)
                plt.close(fig)
            fig = plt.figure(figsize=A4)
            pages += 1
            fig.text(0.5, 0.985, f"baarda quality report: {res.title}", ha="center",
                     va="top", fontsize=8, color="#555")
            fig.text(0.5, 0.01, f"page {pages}", ha="center", fontsize=7, color="#555")
            y = 0.96

        def line(text: str, size: float = 7.0, mono: bool = False, bold: bool = False,
                 color: str = "black"):
            nonlocal y
            step = size / 72 / A4[1] * 1.35
            if y - step < 0.03:
                new_page()
            fig.text(0.05, y, text, fontsize=size, va="top",
                     family="monospace" if mono else "sans-serif",
                     weight="bold" if bold else "normal", color=color)
            y -= step

        new_page()
        import textwrap

        for p in parts:
            if p.kind == "alert":
                for w in textwrap.wrap(p.text, 100):
                    line(w, 9, bold=True, color="#b00000")
            elif p.kind == "heading":
                if y < 0.2:
                    new_page()
                y -= 0.01
                line(p.title, 12, bold=True)
            elif p.kind == "text":
                for para in p.text.split("\n"):
                    for w in textwrap.wrap(para, 120) or [""]:
                        line(w, 7.5)
            elif p.kind == "table":
                line(p.title[0].upper() + p.title[1:], 8, bold=True)
                rows = _text_lines(p.table, p.fmt)
                size = 6.0 if max(len(r) for r in rows) < 150 else 4.5
                for r in rows:
                    line(r, size, mono=True)
            elif p.kind == "figure":
                src = p.figure()
                w, h = src.get_size_inches()
                png = to_png(src)
                frac_h = min(0.45, h / A4[1])
                if y - frac_h < 0.05:
                    new_page()
                ax = fig.add_axes([0.05, y - frac_h, min(0.9, w / A4[0] * frac_h / (h / A4[1])),
                                   frac_h])
                import io

                ax.imshow(plt.imread(io.BytesIO(png)))
                ax.axis("off")
                y -= frac_h + 0.01
                for t in textwrap.wrap(p.text, 120):
                    line(t, 7)
        pdf.savefig(fig)
        plt.close(fig)
    return pages
