"""The ground covered by the photos, per ground cell: how many photo footprints
(report/footprint.py) cover each cell's centre, as Pix4D counts images per orthomosaic
pixel.  Gives the covered area and the overlap map (holes and seams show; photos per
tie point, averaged on a grid, show an hourglass on a uniform block)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.path import Path as PolyPath

CELLS = 240  # cells along the longer side of the block


@dataclass(frozen=True)
class Coverage:
    counts: np.ndarray  # (ny, nx) photos covering each cell's centre
    x0: float  # west edge of the grid (m)
    y0: float  # south edge of the grid (m)
    cell: float  # cell size (m)

    @property
    def area_m2(self) -> float:
        """The area covered by at least one photo (m^2)."""
        return float((self.counts >= 1).sum()) * self.cell**2

    def share(self, k: int) -> float:
        """The share of the covered area seen by at least k photos."""
        n = int((self.counts >= 1).sum())
        return float((self.counts >= k).sum()) / n if n else float("nan")


def coverage(outlines: dict[str, np.ndarray], cells: int = CELLS) -> Coverage | None:
    """Photos per ground cell from the footprints (4 x 2 corners in m each); None without
    any."""
    if not outlines:
        return None
    allp = np.concatenate(list(outlines.values()))
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    cell = float(max(hi - lo)) / cells
    if not np.isfinite(cell) or cell <= 0:
        return None
    nx, ny = int(np.ceil((hi[0] - lo[0]) / cell)) + 1, int(np.ceil((hi[1] - lo[1]) / cell)) + 1
    counts = np.zeros((ny, nx), np.int32)
    for poly in outlines.values():  # each footprint tested on the cells of its bounding box
        (ax, ay), (bx, by) = poly.min(axis=0), poly.max(axis=0)
        i0, i1 = int((ax - lo[0]) / cell), min(int((bx - lo[0]) / cell) + 1, nx)
        j0, j1 = int((ay - lo[1]) / cell), min(int((by - lo[1]) / cell) + 1, ny)
        gx, gy = np.meshgrid(lo[0] + (np.arange(i0, i1) + 0.5) * cell,
                             lo[1] + (np.arange(j0, j1) + 0.5) * cell)
        inside = PolyPath(poly).contains_points(np.column_stack([gx.ravel(), gy.ravel()]))
        counts[j0:j1, i0:i1] += inside.reshape(gx.shape)
    return Coverage(counts, float(lo[0]), float(lo[1]), cell)
