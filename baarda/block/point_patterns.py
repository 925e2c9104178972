"""Named point patterns in the left image of a normal-case model (Kratky and El-Hakim 1983,
Figures 2, 4, 7): the points of a pattern as data, for the design of a pattern
(relative/point_pattern.py) and for simulated strips (simulate/online_strip.py).

Pattern names: "6" (2 x 3), "9" (3 x 3), "10" (2 x 5), "12" (3 x 4), "15" (3 x 5), "13"
(= "9+corners": 9 standard positions, the 4 corners doubled), or "CxR" (C columns, R rows)
with "+corners" (double the corners) or "+edges" (double the top and bottom of every column).
Point numbering runs down each column from the left (Kratky's Figure 1: 1-3 left, 4-6 right for
the 6-point pattern); twins follow their original as "3'".  Tie points (scale transfer) are
the points of the left column.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from baarda.options import PATTERNS

NAMED = PATTERNS


@dataclass
class PatternPoint:
    name: str
    x: float  # left image, mm
    y: float
    tie: bool = False
    twin_of: str | None = None


def standard_pattern(spec: str, ties: int = 0, base: float = 92.0, width: float = 92.0,
                     twin_offset: float = 1.0) -> list[PatternPoint]:
    """Points of a named or "CxR[+corners|+edges]" pattern; rows span y in [-width, width].

    ties: 0, or the number of tie points = the number of points in the left column.
    Twins lie twin_offset mm from their original, towards the model's x axis.
    """
    s = NAMED.get(spec, spec)
    m = re.fullmatch(r"(\d+)x(\d+)(\+corners|\+edges)?", s)
    if not m:
        raise ValueError(f"unknown pattern {spec!r}: use one of {', '.join(NAMED)} or CxR, "
                         "CxR+corners, CxR+edges")
    ncol, nrow, extra = int(m.group(1)), int(m.group(2)), m.group(3)
    if ncol < 2 or nrow < 2:
        raise ValueError(f"pattern {spec!r}: at least 2 columns and 2 rows")
    pts: list[PatternPoint] = []
    k = 0
    for ci, x in enumerate(np.linspace(0.0, base, ncol)):
        for ri, y in enumerate(np.linspace(width, -width, nrow)):
            k += 1
            pts.append(PatternPoint(str(k), float(x), float(y)))
            edge = ri in (0, nrow - 1)
            if (extra == "+corners" and edge and ci in (0, ncol - 1)) or (
                    extra == "+edges" and edge):
                pts.append(PatternPoint(f"{k}'", float(x), float(y - np.sign(y) * twin_offset),
                                        twin_of=str(k)))
    if ties:
        left = [p for p in pts if p.x == 0.0]
        if ties != len(left):
            raise ValueError(f"pattern {spec!r} has {len(left)} points in the left column, not "
                             f"{ties} tie points")
        for p in left:
            p.tie = True
    return pts
