"""The report of `baarda plan` as HTML in the reports' look, from the files plan wrote:
the advice (what, remedy, where) first, the remedies side by side (plan_what_if.csv), the
reliability per point class, the maps and the text report."""

from __future__ import annotations

import base64
from collections.abc import Callable
from pathlib import Path

import pandas as pd
from markupsafe import Markup

from baarda.report.html_base import (
    esc,
    metadata_section,
    page,
    run_metadata,
    table,
    with_user_templates,
)


def _csv(path: Path) -> pd.DataFrame | None:
    return pd.read_csv(path, keep_default_na=False, na_values=[""]) if path.is_file() else None


@with_user_templates
def plan_html(file: Callable[[str], Path], title: str = "",
              templates: str | Path | None = None, run=None) -> str:
    """The page; `file(name)`: the path of a file plan wrote; `run`: the run being written
    (its version, date, id and command head the page as in the adjustment reports)."""
    sections = []
    advice = _csv(Path(file("plan_advice.csv")))
    if advice is not None and len(advice):
        sections.append({"id": "advice", "nav": "Advice", "title": "Advice",
                         "body": Markup(table(advice.fillna(""), text_cols=tuple(
                             advice.columns), attrs='id="advice"'))})
    else:
        sections.append({"id": "advice", "nav": "Advice", "title": "Advice",
                         "body": Markup("<p>No weakness found: no advice.</p>")})
    wi = _csv(Path(file("plan_what_if.csv")))
    if wi is not None and len(wi):
        text = tuple(c for c in wi.columns if wi[c].dtype == object)
        sections.append({"id": "what-if", "nav": "Remedies", "title": "Remedies side by side",
                         "body": Markup(table(wi, text_cols=text, attrs='id="what-if"'))})
    cls = _csv(Path(file("plan_classes.csv")))
    if cls is not None and len(cls):
        text = tuple(c for c in cls.columns if cls[c].dtype == object)
        sections.append({"id": "classes", "nav": "Point classes",
                         "title": "Reliability per point class",
                         "body": Markup(table(cls, text_cols=text, attrs='id="classes"'))})
    maps = Path(file("plan_maps.png"))
    if maps.is_file():
        b64 = base64.b64encode(maps.read_bytes()).decode("ascii")
        sections.append({"id": "maps", "nav": "Maps", "title": "Maps",
                         "body": Markup(f'<figure id="fig-plan-maps"><img alt="plan maps" '
                                        f'src="data:image/png;base64,{b64}"></figure>')})
    rep = Path(file("plan_report.txt"))
    if rep.is_file():
        sections.append({"id": "text", "nav": "Text report", "title": "Text report",
                         "body": Markup(f"<pre>{esc(rep.read_text(encoding='utf-8'))}</pre>")})
    meta = run_metadata(run)
    sections.append(metadata_section(meta))
    return page("plan", templates, title=title or "design", subtitle="baarda plan · run "
                f"{meta[2][1]}", sections=sections,
                footer=f"baarda {meta[0][1]} · run {meta[2][1]} · {meta[1][1]}")
