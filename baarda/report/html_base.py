"""The pieces every HTML page of the report is made of: the style sheet, escaped text,
numbers, tables and embedded figures (base64 PNG, no network access)."""

from __future__ import annotations

import base64
import html

import numpy as np
import pandas as pd

from baarda.report.plots import Plot

CSS = """
body{font-family:system-ui,Segoe UI,Helvetica,Arial,sans-serif;margin:0;color:#222}
header{background:#1f3b5a;color:#fff;padding:14px 24px}
header h1{margin:0;font-size:22px} header p{margin:4px 0 0;font-size:13px;opacity:.85}
header p.bad{background:#fff;color:#b00020;padding:4px 8px;border-radius:3px;opacity:1}
nav{padding:6px 24px;background:#e8eef5;font-size:13px}
nav a{margin-right:14px;color:#1f3b5a}
main{padding:8px 24px 40px;max-width:1400px}
h2{border-bottom:2px solid #1f3b5a;padding-bottom:2px;margin-top:28px;font-size:18px}
table{border-collapse:collapse;font-size:12px;margin:6px 0}
th,td{border:1px solid #ccd;padding:2px 6px;text-align:right;white-space:nowrap}
th{background:#eef2f7} td.t,th.t{text-align:left}
tr.rejected td{background:#fbd5d5} tr.flagged td{background:#fde7c8}
tr.uncontrolled td{color:#888}
.ok{color:#146c2e;font-weight:bold} .bad{color:#b00020;font-weight:bold} .note{color:#555}
pre{font-size:11px;line-height:1.15;background:#f7f7f7;padding:6px;overflow-x:auto}
figure{margin:10px 0} figcaption{font-size:12px;color:#444;max-width:1100px}
img{max-width:100%;border:1px solid #ddd}
.facts{font-size:14px;line-height:1.5} #render-status{font-size:11px;color:#666}
"""

def esc(x) -> str:
    return html.escape(str(x))


def num(x: float, decimals: int) -> str:
    """Fixed decimals without a negative zero."""
    return f"{round(float(x), decimals) + 0.0:.{decimals}f}"


def table(df: pd.DataFrame, fmt: dict[str, str] | None = None, row_class=None,
          text_cols: tuple[str, ...] = (), attrs: str = "") -> str:
    """An HTML table of `df`; numbers formatted with `fmt` (column -> format spec)."""
    fmt = fmt or {}
    head = "".join(f"<th{' class=t' if c in text_cols else ''}>{esc(c)}</th>"
                   for c in df.columns)
    rows = []
    classes = row_class(df) if row_class is not None else [""] * len(df)
    for rec, cls in zip(df.itertuples(index=False), classes, strict=True):
        cells = []
        for c, v in zip(df.columns, rec, strict=True):
            if isinstance(v, float | np.floating):
                f = fmt.get(c, ".4g")
                s = ("-" if not np.isfinite(v) else num(v, int(f[1:-1])) if f.endswith("f")
                     else format(v, f))
            else:
                s = str(v)
            cells.append(f"<td{' class=t' if c in text_cols else ''}>{esc(s)}</td>")
        rows.append(f"<tr{f' class={cls}' if cls else ''}>{''.join(cells)}</tr>")
    return f"<table {attrs}><thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>"


def figure(p: Plot | None) -> str:
    if p is None:
        return ""
    b64 = base64.b64encode(p.png).decode("ascii")
    return (f'<figure id="fig-{esc(p.name)}"><img alt="{esc(p.title)}" '
            f'src="data:image/png;base64,{b64}"><figcaption>{esc(p.caption)}</figcaption>'
            "</figure>")
