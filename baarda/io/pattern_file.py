"""A point pattern of a stereo model given as a file (`baarda pattern FILE.csv`): columns
name, x, y (left image, mm) and optionally tie (1/0, yes/no, true/false)."""

from __future__ import annotations

import csv
from pathlib import Path

from baarda.errors import ProjectError


def read_pattern_points(path: str | Path) -> list[tuple[str, float, float, bool]]:
    """(name, x, y, tie) of every point, in file order; ProjectError names the file, line
    and field of a bad value."""
    path = Path(path)
    try:
        fh = open(path, encoding="utf-8", newline="")
    except OSError as e:
        raise ProjectError(path, f"cannot read: {e.strerror}") from None
    with fh:
        rows = list(csv.reader(fh))
    if not rows or [c.strip().lower() for c in rows[0][:3]] != ["name", "x", "y"]:
        raise ProjectError(path, "the header must be name,x,y[,tie]", 1)
    header = [c.strip().lower() for c in rows[0]]
    pts = []
    for n, row in enumerate(rows[1:], 2):
        if not row or not "".join(row).strip():
            continue
        if len(row) != len(header):
            raise ProjectError(path, f"{len(row)} fields, expected {len(header)}", n)
        vals = dict(zip(header, (c.strip() for c in row), strict=True))
        xy = []
        for k in ("x", "y"):
            try:
                xy.append(float(vals[k]))
            except ValueError:
                raise ProjectError(path, f"not a number: {vals[k]!r}", n, k) from None
        tie = vals.get("tie", "0").lower()
        if tie not in ("0", "1", "yes", "no", "true", "false", ""):
            raise ProjectError(path, f"tie must be 1/0 or yes/no, got {tie!r}", n, "tie")
        pts.append((vals["name"], xy[0], xy[1], tie in ("1", "yes", "true")))
    if len({p[0] for p in pts}) != len(pts):
        raise ProjectError(path, "point names must be unique")
    return pts
