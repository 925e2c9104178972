"""Point-pattern design without measurements (Kratky and El-Hakim 1983, Figures 2, 4, 7).

A pattern is a set of points in the left image of a normal-case model (flat terrain, photos
without rotation, base b along x): x = 0 is the left nadir column, x = b the right one.  The
redundancy numbers, Qvv P and the critical transfers depend only on the geometry, so they are
computed at the true orientation with zero residuals, through the same orientation code and the
quality layer as the measured models.  Tie points (scale transfer) are the points of the left
column, 3 or 5 of them.

Pattern names: "6" (2 x 3), "9" (3 x 3), "10" (2 x 5), "12" (3 x 4), "15" (3 x 5), "13"
(= "9+corners": 9 standard positions, the 4 corners doubled), or "CxR" (C columns, R rows)
with "+corners" (double the corners) or "+edges" (double the top and bottom of every column).
Point numbering runs down each column from the left (Kratky's Figure 1: 1-3 left, 4-6 right for
the 6-point pattern); twins follow their original as "3'".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.block.point_patterns import NAMED, PatternPoint, standard_pattern  # noqa: F401
from baarda.options import DEFAULT_QTIE, DEFAULT_QYY
from baarda.quality.matrices import Transfer, critical_transfers, qvv_p_matrix
from baarda.quality.statistics import analyse
from baarda.relative.orientation import (
    ModelSetup,
    Orientation,
    PhotoPose,
    orient,
)


@dataclass
class PatternDesign:
    points: list[PatternPoint]
    orientation: Orientation
    redundancy_number: np.ndarray  # (k,) y of every point, then x of the tie points
    qvvp: np.ndarray
    transfers: list[Transfer]  # critical (level 1)
    serious: list[Transfer]  # at least `serious_level` of the diagonal, not critical
    trace_qgg: float  # trace of Q_gg, image coordinates in units of the base, sigma_x = 1
    serious_level: float

    @property
    def n(self) -> int:
        return len(self.redundancy_number)

    @property
    def r0(self) -> float:
        return float(np.mean(self.redundancy_number))

    def label(self, i: int) -> str:
        o = self.orientation
        return f"{o.points[o.obs_point[i]]}{o.obs_component[i]}"


def design(points: list[PatternPoint], focal: float = 152.0, base: float = 92.0,
           qyy: float = DEFAULT_QYY, serious_level: float = 0.8,
           qtie: float = DEFAULT_QTIE) -> PatternDesign:
    """Redundancy numbers, Qvv P, critical transfers and trace(Q_gg) of a point pattern.

    focal, base in mm.  Tie points take their model coordinates from the true geometry.
    """
    if len({p.name for p in points}) != len(points):
        raise ValueError("point names must be unique")
    left = np.array([[p.x, p.y] for p in points], float)
    right = left - [base, 0.0]
    ti = np.array([i for i, p in enumerate(points) if p.tie], int)
    xyz = np.column_stack([left, np.full(len(points), -focal)])  # Z = -c: photo scale
    sigma_x = 1000.0 * base  # µm: sigma 1 in units of the base
    setup = ModelSetup(focal, PhotoPose(np.zeros(3), np.eye(3)), base, ti, xyz[ti],
                       scale=len(ti) > 0, sigma_x=sigma_x, qyy=qyy, qtie=qtie)
    o = orient("pattern", [p.name for p in points], left, right, setup)
    model = o.dense_model()
    q = analyse(model)
    m = qvv_p_matrix(model)
    crit = critical_transfers(m)
    seen = {(t.source, t.target) for t in crit}
    ser = [t for t in critical_transfers(m, serious_level) if (t.source, t.target) not in seen]
    twins = {p.name: p.twin_of for p in points}

    def between_twins(t: Transfer) -> bool:
        a, b = (o.points[o.obs_point[k]] for k in (t.source, t.target))
        same = o.obs_component[t.source] == o.obs_component[t.target]
        return same and (twins.get(a) == b or twins.get(b) == a)

    return PatternDesign(points, o, q.redundancy_number, m,
                         [t for t in crit if not between_twins(t)],
                         [t for t in ser if not between_twins(t)],
                         float(np.trace(model.qxx)), serious_level)
