"""The quality report (report/quality_report.py) as HTML: its parts as sections of a
self-contained page (`quality_page`), and its camera, control and GNSS parts as tables of
the main HTML report (`tables_html`, the correlations coloured like the heat map)."""

from __future__ import annotations

import re

import matplotlib
import numpy as np
import pandas as pd

from baarda.output.result_folder import Results
from baarda.report.html_base import CSS, esc, figure
from baarda.report.plots import Plot, to_png
from baarda.report.quality_report import Part, calibration_parts, quality_content


def format_cell(v, f: str | None) -> str:
    """A table cell as text: a number in format f (blank when not finite), anything else
    HTML-escaped (the PDF passes its text cells as they are)."""
    if isinstance(v, float | np.floating):
        if not np.isfinite(v):
            return ""
        return format(float(v), f) if f else f"{float(v):.6g}"
    return esc(v)


def html_table(t: pd.DataFrame, fmt: dict | None, attrs: str = "") -> str:
    fmt = fmt or {}
    head = "".join(f"<th>{esc(c)}</th>" for c in t.columns)
    rows = "".join("<tr>" + "".join(f"<td>{format_cell(v, fmt.get(c))}</td>" for c, v in
                                    zip(t.columns, r, strict=True)) + "</tr>"
                   for r in t.itertuples(index=False))
    return f"<table {attrs}><tr>{head}</tr>{rows}</table>"


def _corr_cell(v: float) -> str:
    """A correlation coefficient as a table cell coloured like the heat map."""
    if not np.isfinite(v):
        return "<td></td>"
    c = matplotlib.colormaps["RdBu_r"]((float(v) + 1) / 2)
    rgb = "#" + "".join(f"{int(255 * x):02x}" for x in c[:3])
    ink = "#fff" if abs(v) > 0.6 else "#000"
    return f'<td style="background:{rgb};color:{ink}">{v:+.3f}</td>'


def _corr_table(t: pd.DataFrame) -> str:
    head = "".join(f"<th>{esc(c)}</th>" for c in t.columns)
    rows = "".join(f"<tr><td>{esc(r[0])}</td>" + "".join(_corr_cell(v) for v in r[1:])
                   + "</tr>" for r in t.itertuples(index=False))
    return f"<table><tr>{head}</tr>{rows}</table>"


def parts_html(parts: list[Part], figures: bool = True) -> str:
    """The parts as HTML sections.  figures: draw them, the tables with ids (the quality
    page); without (the main report), a correlation matrix is coloured like its heat map."""
    out = []
    for p in parts:
        if p.kind == "alert":
            out.append(f'<p class="bad">{esc(p.text)}</p>')
        elif p.kind == "heading":
            out.append(f"<h3>{esc(p.title)}</h3>")
        elif p.kind == "text":
            out.append("<p>" + "<br>".join(esc(x) for x in p.text.split("\n")) + "</p>")
        elif p.kind == "table":
            title = f"<h4>{esc(p.title[0].upper() + p.title[1:])}</h4>"
            if not figures and p.title.startswith("correlations of camera"):
                out.append(title + _corr_table(p.table))
                continue
            ident = re.sub(r"[^a-z0-9]+", "-", p.title.lower()).strip("-")
            out.append(title + html_table(p.table, p.fmt, f'id="q-{ident}"' if figures else ""))
            if p.full_in_html is not None and len(p.full_in_html) > len(p.table):
                out.append(f"<details><summary>all {len(p.full_in_html)} rows</summary>"
                           + html_table(p.full_in_html, p.fmt) + "</details>")
        elif p.kind == "figure" and figures:
            out.append(figure(Plot(re.sub(r"\W+", "-", p.title), p.title,
                                   to_png(p.figure()), p.text)))
    return "".join(out)


def tables_html(res: Results, calibration: list[Part] | None = None) -> str:
    """The camera, control and GNSS parts (`calibration`: calibration_parts(res) when they
    are at hand) as tables for the main HTML report (no figures: the correlation matrix
    coloured like the heat map); '' when there is nothing to show."""
    parts = calibration_parts(res) if calibration is None else calibration
    if not any(p.kind == "table" for p in parts):
        return ""
    return parts_html(parts, figures=False) + (
        "<p>The quality report (baarda report OUT --quality FILE.html --pdf FILE.pdf) adds "
        "reprojection errors per image, the observations' r, w and MDB and external "
        "reliability.</p>")


def quality_page(res: Results, parts: list[Part] | None = None) -> str:
    """The quality report as a self-contained HTML page (the PDF's content); `parts`:
    quality_content(res) when it is at hand."""
    parts = quality_content(res) if parts is None else parts
    return ("<!DOCTYPE html><html lang=en><head><meta charset=utf-8>"
            f"<title>baarda quality report: {esc(res.title)}</title><style>{CSS}"
            "</style></head><body><header><h1>Quality report: "
            f"{esc(res.title)}</h1><p>{esc(res.folder)}</p></header>"
            f"<main>{parts_html(parts)}</main></body></html>\n")
