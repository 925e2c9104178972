"""The quality report (report/quality_report.py) as HTML: its parts as sections of a
self-contained page (`quality_page`), and its camera, control and GNSS parts as tables of
the main HTML report (`tables_html`, the correlations coloured like the heat map)."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
from markupsafe import Markup

from baarda.io.result_folder import Results
from baarda.kinds import GNSS, IMU
from baarda.output.verdict import failures
from baarda.report.html_base import (
    csv_link,
    esc,
    figure,
    page,
    table,
    with_user_templates,
    worst_table,
)
from baarda.report.plots import Plot, to_png
from baarda.report.quality_report import Part, calibration_parts, quality_content

HTML_ROWS = 20  # rows of a long table shown (the worst; the whole table linked as CSV)


def _table(p: Part, attrs: str = "") -> str:
    """A part's table: all rows, or the HTML_ROWS worst (p.order) with the whole as CSV."""
    t = p.full_in_html if p.full_in_html is not None else p.table
    assert t is not None and p.table is not None  # a table part
    text = tuple(c for c in t.columns if t[c].dtype == object)
    name = re.sub(r"[^a-z0-9]+", "_", p.title.lower()).strip("_")
    if p.order is not None and len(t) > HTML_ROWS:
        return str(worst_table(t, p.order, HTML_ROWS, name, p.rows_are, p.fmt, p.which,
                               text_cols=text, attrs=attrs))
    if p.full_in_html is not None and len(t) > len(p.table):
        return str(table(p.table, p.fmt, text_cols=text, attrs=attrs, note=(
            f"{len(p.table)} of {len(t)} rows shown;"), csv=csv_link(t, name),
            csv_text=f"all {len(t)} rows (CSV)", download=f"{name}.csv"))
    return str(table(t, p.fmt, text_cols=text, attrs=attrs))


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
    """The parts as HTML.  figures: draw them, the tables with ids (the quality page);
    without (the main report), a correlation matrix is coloured like its heat map."""
    out = []
    for p in parts:
        if p.kind == "alert":
            out.append(f'<p class="banner">{esc(p.text)}</p>')
        elif p.kind == "heading":
            ident = "" if figures or p.title not in SECTION_IDS else \
                f' id="{SECTION_IDS[p.title]}"'
            out.append(f"<h3{ident}>{esc(p.title)}</h3>")
        elif p.kind == "text":
            out.append("<p>" + "<br>".join(esc(x) for x in p.text.split("\n")) + "</p>")
        elif p.kind == "table":
            title = f"<h4>{esc(p.title[0].upper() + p.title[1:])}</h4>"
            if not figures and p.title.startswith("correlations of camera"):
                out.append(title + _corr_table(p.table))
                continue
            ident = p.ident or re.sub(r"[^a-z0-9]+", "-", p.title.lower()).strip("-")
            out.append(title + _table(p, f'id="q-{ident}"' if figures else ""))
        elif p.kind == "figure" and figures:
            if p.png is not None:
                png = p.png
            else:
                assert p.figure is not None  # a figure part
                png = to_png(p.figure())
            out.append(str(figure(Plot(re.sub(r"\W+", "-", p.title), p.title, png, p.text))))
    return "".join(out)


def quality_sections(parts: list[Part]) -> list[dict]:
    """The parts as page sections, one per heading (its id from the heading)."""
    out: list[dict] = []
    for p in parts:
        if p.kind == "heading":
            ident = SECTION_IDS.get(p.title) or re.sub(r"[^a-z0-9]+", "-",
                                                       p.title.lower()).strip("-")
            out.append({"id": ident, "nav": p.title.split(" (")[0], "title": p.title,
                        "parts": []})
        elif out:
            out[-1]["parts"].append(p)
    return [{"id": s["id"], "nav": s["nav"], "title": s["title"],
             "body": Markup(parts_html(s["parts"]))} for s in out]


SECTION_IDS = {"Summary": "summary", "Camera calibration": "camera",
               "Ground control and check points": "control", "Geometry": "geometry",
               GNSS.title: GNSS.name, IMU.title: IMU.name,
               "Reprojection errors per image": "reprojection",
               "Every observation: redundancy number, w-test, MDB": "observations",
               "Data snooping log": "log",
               "External reliability of the ground points": "reliability"}


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


@with_user_templates
def quality_page(res: Results, parts: list[Part] | None = None,
                 templates: str | Path | None = None, out: Path | None = None) -> str:
    """The quality report as a self-contained HTML page (the PDF's content): the quality
    check, accuracy, patterns and metadata first, then the parts; `parts`:
    quality_content(res) when it is at hand; `out`: where it will be written (the link to
    the result folder's observation table is relative to it)."""
    from baarda.report.html_report import _observations_link, footer, front_sections
    from baarda.report.text_report import ReportOptions

    parts = quality_content(res) if parts is None else parts
    body = [p for p in parts if p.kind != "alert"]
    rest = quality_sections(body)
    href, name = _observations_link(res, out)
    for s in rest:  # every observation: a link, not the table inside the page
        if s["id"] == "observations":
            s["body"] = Markup(str(s["body"]) + f'<p class=more>Every observation with r, w, '
                               f'MDB and the external reliability: <a href="{esc(href)}">'
                               f"{esc(name)}</a> of the result folder.</p>")
    sections = front_sections(res, ReportOptions(), rest) + rest
    return page("quality", templates, title=res.title, subtitle=f"{res.folder.name} · run "
                f"{res.run or 'not recorded'}", banners=failures(res.summary), sections=sections,
                footer=footer(res))
