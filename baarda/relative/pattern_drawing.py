"""Drawings of a point pattern with its redundancy numbers and critical error transfers, as
text and as SVG (in the manner of Kratky and El-Hakim 1983, Figures 2, 4 and 7)."""

from __future__ import annotations

from xml.sax.saxutils import escape

import numpy as np

from baarda.quality.matrices import Transfer
from baarda.relative.point_pattern import PatternDesign


def _r(v: float) -> str:
    return f"{v:.2f}".replace("0.", ".", 1) if v < 1 else f"{v:.2f}"


def _obs_r(d: PatternDesign) -> tuple[dict[str, float], dict[str, float]]:
    o = d.orientation
    ry: dict[str, float] = {}
    rx: dict[str, float] = {}
    for i, r in enumerate(d.redundancy_number):
        (ry if o.obs_component[i] == "y" else rx)[o.points[o.obs_point[i]]] = float(r)
    return ry, rx


def summary_line(d: PatternDesign, title: str = "pattern") -> str:
    m = int(sum(p.tie for p in d.points))
    npt = len(d.points)
    u = 6 if m else 5
    formula = "(n-5)/n" if not m else f"(n-{u - m})/(n+{m})"
    return (f"{title}: {npt} points, {m} tie points -> {d.n} observations, {u} unknowns, "
            f"r0 = {d.r0:.3f} = {formula}, trace(Qgg) = {d.trace_qgg:.2f} (image coordinates "
            "in units of the base)")


def transfer_text(d: PatternDesign, items: list[Transfer]) -> list[str]:
    return [f"  {d.label(t.source):>6} -> {d.label(t.target):<6} {t.value:+.2f}  (diagonal "
            f"{t.diagonal:.2f})" for t in items]


def text_drawing(d: PatternDesign, title: str = "pattern", width: int = 60,
                 height: int | None = None) -> str:
    """The pattern on a character canvas: 'name r_y[/r_x x]' at each point (left image)."""
    ry, rx = _obs_r(d)
    xs = np.array([p.x for p in d.points])
    ys = np.array([p.y for p in d.points])
    xspan = max(np.ptp(xs), 1e-9)
    yspan = max(np.ptp(ys), 1e-9)
    if height is None:
        height = 2 * len({p.y for p in d.points if p.twin_of is None}) + 1
    canvas = [[" "] * (width + 16) for _ in range(height + len(d.points))]
    for p in d.points:
        col = int(round((p.x - xs.min()) / xspan * width))
        row = int(round((ys.max() - p.y) / yspan * (height - 1)))
        label = f"{p.name} {_r(ry[p.name])}" + (f"/{_r(rx[p.name])}x" if p.name in rx else "")
        col = min(col, width + 16 - len(label))
        while any(c != " " for c in canvas[row][max(col - 1, 0):col + len(label) + 1]):
            row += 1
        canvas[row][col:col + len(label)] = list(label)
    body = "\n".join("  " + "".join(r).rstrip() for r in canvas).rstrip("\n ")
    lines = [summary_line(d, title),
             "  left image, x to the right, y up; r of y'' at each point, r of x'' of tie points "
             "after '/'", "", body, ""]
    lines.append("critical transfers (an error in -> shows at least as large at: Qvv P value):")
    lines += transfer_text(d, d.transfers) or ["  none"]
    lines.append(f"serious transfers (>= {d.serious_level:g} of the diagonal):")
    lines += transfer_text(d, d.serious) or ["  none"]
    return "\n".join(lines) + "\n"


def svg_drawing(d: PatternDesign, title: str = "pattern", size: int = 460) -> str:
    """SVG: points (squares: tie points), r values, heavy arrows for critical transfers and
    dashed ones for serious transfers (blue: x'' observations)."""
    ry, rx = _obs_r(d)
    m = 70
    w, h = size, size
    xs = np.array([p.x for p in d.points])
    ys = np.array([p.y for p in d.points])
    xspan = max(np.ptp(xs), 1e-9)
    yspan = max(np.ptp(ys), 1e-9)
    pos = {}
    for p in d.points:
        px = m + (p.x - xs.min()) / xspan * (w - 2 * m)
        py = 50 + (ys.max() - p.y) / yspan * (h - 50 - m)
        pos[p.name] = [px, py]
    for p in d.points:  # twins: drawn apart so that both can be seen
        if p.twin_of and abs(pos[p.name][1] - pos[p.twin_of][1]) < 16:
            sgn = 1.0 if p.y >= 0 else -1.0
            pos[p.name][1] = pos[p.twin_of][1] + 16 * sgn
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
           f'viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">',
           '<defs><marker id="head" markerWidth="8" markerHeight="8" refX="7" refY="4" '
           'orient="auto"><path d="M0,0 L8,4 L0,8 z" fill="black"/></marker>'
           '<marker id="headx" markerWidth="8" markerHeight="8" refX="7" refY="4" '
           'orient="auto"><path d="M0,0 L8,4 L0,8 z" fill="#1f5fbf"/></marker></defs>',
           f'<rect x="0" y="0" width="{w}" height="{h}" fill="white"/>',
           f'<text x="10" y="20" font-size="13">{escape(title)}</text>',
           f'<text x="10" y="{h - 12}">n = {d.n}, r0 = {d.r0:.2f}, tr = {d.trace_qgg:.1f}'
           '</text>']
    o = d.orientation
    for kind, items in (("critical", d.transfers), ("serious", d.serious)):
        for t in items:
            a = o.points[o.obs_point[t.source]]
            b = o.points[o.obs_point[t.target]]
            if a == b:
                continue
            (x1, y1), (x2, y2) = pos[a], pos[b]
            ln = max(np.hypot(x2 - x1, y2 - y1), 1e-9)
            ux, uy = (x2 - x1) / ln, (y2 - y1) / ln
            xcomp = o.obs_component[t.source] == "x"
            col = "#1f5fbf" if xcomp else "black"
            style = (f'stroke="{col}" stroke-width="3"' if kind == "critical" else
                     f'stroke="{col}" stroke-width="1.5" stroke-dasharray="4,3"')
            out.append(f'<line class="{kind}" x1="{x1 + 9 * ux:.1f}" y1="{y1 + 9 * uy:.1f}" '
                       f'x2="{x2 - 9 * ux:.1f}" y2="{y2 - 9 * uy:.1f}" {style} '
                       f'marker-end="url(#{"headx" if xcomp else "head"})"/>')
            out.append(f'<text x="{(x1 + x2) / 2 + 4:.1f}" y="{(y1 + y2) / 2 - 4:.1f}" '
                       f'font-size="10" fill="{col}">{abs(t.value):.2f}</text>')
    for p in d.points:
        x, y = pos[p.name]
        if p.tie:
            out.append(f'<rect class="tie" x="{x - 5:.1f}" y="{y - 5:.1f}" width="10" '
                       'height="10" fill="black"/>')
        else:
            out.append(f'<circle class="point" cx="{x:.1f}" cy="{y:.1f}" r="5" '
                       'fill="white" stroke="black"/>')
        out.append(f'<text x="{x + 9:.1f}" y="{y + 4:.1f}">{escape(p.name)}: '
                   f'{_r(ry[p.name])}</text>')
        if p.name in rx:
            out.append(f'<text x="{x - 9:.1f}" y="{y + 4:.1f}" text-anchor="end" '
                       f'fill="#1f5fbf">x {_r(rx[p.name])}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"
