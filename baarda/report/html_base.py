"""The pieces every HTML page of the reports is made of: the Jinja2 templates
(report/templates: the pages, the style sheet and the macros for tables, figures, the
quality check and the sign-off block; a user's folder of templates of the same names
overrides them), escaped text, the formatting rules of numbers, tables and embedded
figures (base64 PNG, no network access).

The number rules of every cell are baarda/table_data.py's (`cell`): a table is data
(`TableData`), `html_table` renders it.
"""

from __future__ import annotations

import base64
import functools
import html
import inspect
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from jinja2 import ChoiceLoader, Environment, FileSystemLoader, StrictUndefined
from jinja2.sandbox import SandboxedEnvironment

from baarda.errors import ProjectError
from baarda.report.plots import Plot
from baarda.table_data import TableData

TEMPLATES = Path(__file__).parent / "templates"
MACROS = "macros.html.j2"

#: the user's folder of templates (--templates) of the page being built: the macros that
#: the page's pieces are made with (tables, figures, ...) come from it too
_USER_TEMPLATES: ContextVar[str | None] = ContextVar("user_templates", default=None)


@contextmanager
def user_templates(folder: str | Path | None) -> Iterator[None]:
    """While a page is built: `folder` (a user's templates, None: baarda's own) supplies
    the macros of every piece (`macro`), as it supplies the page's templates."""
    token = _USER_TEMPLATES.set(str(folder) if folder else None)
    try:
        yield
    finally:
        _USER_TEMPLATES.reset(token)


def with_user_templates(build: Callable[..., str]) -> Callable[..., str]:
    """A page builder whose `templates` argument (a folder that overrides baarda's
    templates) also supplies the macros of every piece it builds (`user_templates`)."""
    signature = inspect.signature(build)

    @functools.wraps(build)
    def wrapper(*args: Any, **kwargs: Any) -> str:
        with user_templates(signature.bind(*args, **kwargs).arguments.get("templates")):
            return build(*args, **kwargs)

    return wrapper


@lru_cache(maxsize=4)
def environment(user_dir: str | None = None) -> Environment:
    """The templates: a user's folder first (restyling, branding), then baarda's own.  A
    sandbox (jinja2.sandbox): a folder of templates is a document, often shared, not a
    program, so a template reaches no Python internals (no `__globals__`, no `os`)."""
    loaders = [FileSystemLoader(user_dir)] if user_dir else []
    return SandboxedEnvironment(
        loader=ChoiceLoader([*loaders, FileSystemLoader(str(TEMPLATES))]), autoescape=True,
        undefined=StrictUndefined, trim_blocks=False)


def page(name: str, user_dir: str | Path | None = None, **context) -> str:
    """A whole page from template `name` (adjustment, quality, evaluation, plan).  An error
    of a template (syntax, an undefined name, a missing include, a failure while rendering,
    a forbidden attribute) is a ProjectError "template FILE, line N: ..." (`template_error`)."""
    env = environment(str(user_dir) if user_dir else None)
    context.setdefault("banners", [])
    context.setdefault("sections", [])
    context.setdefault("footer", "")
    try:
        return env.get_template(f"{name}.html.j2").render(**context) + "\n"
    except Exception as e:
        error = template_error(e, f"{name}.html.j2", user_dir)
        if error is None:
            raise
        raise error from None


def _template_frame(e: BaseException) -> tuple[str, int] | None:
    """(file, line) of the innermost template frame of `e`'s traceback (jinja2 rewrites its
    frames to the template's file and line), None when no template ran."""
    found = None
    tb = e.__traceback__
    while tb is not None:
        name = tb.tb_frame.f_code.co_filename
        if name.endswith(".j2"):
            found = (name, tb.tb_lineno)
        tb = tb.tb_next
    return found


def template_error(e: Exception, name: str, user_dir) -> ProjectError | None:
    """The ProjectError "template FILE, line N: message" of an error raised while loading or
    rendering template `name`; None for an error of baarda's own code with no user template
    involved (a bug, not bad input)."""
    from jinja2 import TemplateError, TemplateNotFound, TemplateSyntaxError

    if isinstance(e, TemplateSyntaxError):
        where = e.filename or e.name or name
        return ProjectError(f"template {where}", e.message or str(e), e.lineno)
    frame = _template_frame(e)
    user = bool(user_dir) and frame is not None and \
        Path(frame[0]).resolve().is_relative_to(Path(user_dir).resolve())
    if not isinstance(e, TemplateError) and not user:
        return None
    if isinstance(e, TemplateNotFound):
        message = f"includes or extends '{e.name}', which is neither in the template " \
                  "folder nor one of baarda's templates"
    else:
        message = f"{type(e).__name__}: {e}" if not isinstance(e, TemplateError) else str(e)
    if frame is None:
        return ProjectError(f"template {name}", message)
    return ProjectError(f"template {frame[0]}", message, frame[1])


def macro(name: str) -> Callable[..., str]:
    """A macro of macros.html.j2 (table, figure, check, meta, signoff), from the user's
    folder of templates of the page being built when it has one (`with_user_templates`),
    returning plain `str`: the page is assembled from `str` pieces and marked safe once,
    where a section's body is handed to the template (a `Markup` joined to a `str` escapes
    the `str`).  An error of the user's macros is "template FILE, line N: ..."."""
    user_dir = _USER_TEMPLATES.get()

    def refuse(e: Exception) -> ProjectError:
        error = template_error(e, MACROS, user_dir)
        if error is None:
            raise e
        return error

    try:
        module = environment(user_dir).get_template(MACROS).module
    except Exception as e:
        raise refuse(e) from None
    m = getattr(module, name, None)
    if m is None:
        where = Path(user_dir or TEMPLATES) / MACROS
        raise ProjectError(f"template {where}", f"defines no macro '{name}' (the reports "
                           "call table, figure, check, meta and signoff)")

    def call(*args: Any, **kwargs: Any) -> str:
        try:
            return str(m(*args, **kwargs))
        except Exception:
            try:  # the traceback rewritten to the template's lines, as render() does
                environment(user_dir).handle_exception()
            except Exception as e:
                raise refuse(e) from None
            raise

    return call


def esc(x) -> str:
    return html.escape(str(x))


def csv_link(df: pd.DataFrame, name: str) -> str:
    """The whole table as a CSV data URI (the report stays one file), for spreadsheets: a
    text cell that begins with =, +, -, @ is written "'=..." (output/tables.py, as with
    --excel-safe: a report's table is for people, never read back)."""
    from baarda.output.tables import csv_chunks

    data = b"".join(csv_chunks(df.reset_index(drop=True), excel_safe=True))
    return "data:text/csv;base64," + base64.b64encode(data).decode("ascii")


def table(df: pd.DataFrame, fmt: dict[str, str] | None = None, row_class=None,
          text_cols: tuple[str, ...] = (), attrs: str = "", *, note: str = "",
          csv: str | None = None, csv_text: str = "", download: str | None = None) -> str:
    """An HTML table of `df`, numbers formatted with `fmt` (column -> format spec);
    `attrs` may name its id; `note` and a link (`csv`: a data URI or a relative path) above
    it."""
    t = TableData.from_frame(df, fmt, text_cols)
    if row_class is not None:
        t = t.with_row_class(list(row_class(df)))
    return html_table(t, attrs, note=note, csv=csv, csv_text=csv_text, download=download)


def html_table(t: TableData, attrs: str = "", *, note: str = "", csv: str | None = None,
               csv_text: str = "", download: str | None = None) -> str:
    """The HTML renderer of a table (table_data.py: its cells are formatted there)."""
    m = re.search(r'id="([^"]+)"', attrs)
    classes = t.row_class or ("",) * len(t.rows)
    cols = t.titles
    rows = [(cls, list(zip(cols, cells, strict=True)))
            for cells, cls in zip(t.cells(), classes, strict=True)]
    view = {"id": m.group(1) if m else "", "columns": cols,
            "text_cols": {c.head for c in t.columns if c.text},
            "rows": rows, "note": note, "csv": csv, "csv_text": csv_text or "whole table (CSV)",
            "download": download}
    return macro("table")(view)


def worst_table(df: pd.DataFrame, order: np.ndarray | pd.Series, n: int, name: str,
                what: str, fmt: dict[str, str] | None = None, which: str = "worst",
                **kw) -> str:
    """The n worst rows of `df` (`order`: larger is worse), in that order, with the whole
    table linked as CSV when it has more; what: the rows' noun, e.g. 'photos'; which: the
    words for the rows kept ("worst"; "first" for a log kept in its order)."""
    if len(df) <= n:
        return table(df, fmt, **kw)
    key = np.nan_to_num(np.asarray(order, float), nan=-np.inf)
    keep = np.argsort(-key, kind="stable")[:n]
    say = (f"The {n} worst of {len(df)} {what} shown, worst first;" if which == "worst" else
           f"The {which} {n} of {len(df)} {what} shown, in their order;")
    return table(df.iloc[keep].reset_index(drop=True), fmt, note=say, csv=csv_link(df, name),
        csv_text=f"all {len(df)} {what} (CSV)", download=f"{name}.csv", **kw)


def figure(p: Plot | None, width: int | None = None) -> str:
    if p is None:
        return ""
    return macro("figure")({"name": p.name, "title": p.title, "caption": p.caption,
                                   "b64": base64.b64encode(p.png).decode("ascii"),
                                   "width": width})


def run_metadata(run) -> list[tuple[str, str]]:
    """What every report states about its run (the adjustment reports from run.json):
    baarda's version, the date, the run id and the command; `run`: the run being written
    (output/run_folder.py: run_id, started, command)."""
    from baarda.output.run_folder import package_version

    started = getattr(run, "started", None)
    return [("baarda version", str(package_version() or "not recorded")),
            ("processed", started.isoformat(timespec="seconds") if started else "not recorded"),
            ("run", str(getattr(run, "run_id", None) or "not recorded")),
            ("command", str(getattr(run, "command", None) or "not recorded"))]


def metadata_section(meta: list[tuple[str, str]], title: str = "Run", before: str = "",
                     after: str = "") -> dict:
    """The page section of `meta` (run_metadata), its nav entry "Run"; before, after: HTML
    around the list (the report's project facts and sign-off block)."""
    from markupsafe import Markup

    return {"id": "metadata", "nav": "Run", "title": title,
            "body": Markup(before + macro("meta")(meta) + after)}
