"""Distances between two points (scale bars, taped distances) as extra rows of the bundle
(bundle/observation_kinds.py), m; their points become border points.
"""

from __future__ import annotations

import numpy as np

from baarda.block.photo_block import Block
from baarda.bundle.observation_kinds import Context, ObservationKind, Rows, State
from baarda.kinds import DISTANCE


class DistanceRows(Rows):
    """Distances between two border points (scale bars, taped distances), m."""

    units = {DISTANCE.name: DISTANCE.shown()}

    def __init__(self, ctx: Context, which: np.ndarray):
        d = ctx.block.distances
        self.a, self.b = d.point_a[which], d.point_b[which]
        self.ia, self.ib = ctx.bremap[self.a], ctx.bremap[self.b]
        self.ca, self.cb = ctx.point_columns(self.a), ctx.point_columns(self.b)
        self.length = d.length_m[which]
        self.sigma = d.sigma_m[which]
        self._labels(np.full(len(which), "distance", dtype=object),
                     np.full(len(which), "d", dtype=object),
                     np.array([d.ids[k] for k in which], dtype=object))

    def linearize(self, state: State, ng: int):
        n = len(self.a)
        diff = state.bxyz[self.ib] - state.bxyz[self.ia]
        length = np.linalg.norm(diff, axis=1)
        unit = diff / length[:, None]
        j = np.zeros((n, ng))
        for k in range(3):
            j[np.arange(n), self.ca[:, k]] = -unit[:, k]
            j[np.arange(n), self.cb[:, k]] = unit[:, k]
        return self.length - length, np.zeros((n, 6)), j


class Distances(ObservationKind):
    """block.distances between points that are adjusted (`usable`: the problem's)."""

    name = "distances"

    def __init__(self, usable: np.ndarray):
        self.usable = usable

    def _which(self, block: Block) -> np.ndarray:
        d = block.distances
        return np.flatnonzero(self.usable[d.point_a] & self.usable[d.point_b])

    def tied_points(self, block: Block) -> np.ndarray:
        d = block.distances
        w = self._which(block)
        return np.concatenate([d.point_a[w], d.point_b[w]]).astype(np.int64)

    def bind(self, context: Context) -> Rows:
        return DistanceRows(context, self._which(context.block))
