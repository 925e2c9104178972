"""The image points of border points (points tied by another kind, global unknowns) as
extra rows of the bundle: x and y of each, with the camera parameters and the point's
three global columns (bundle/observation_kinds.py).
"""

from __future__ import annotations

import numpy as np

from baarda.bundle.image_rows import ImageRows
from baarda.bundle.observation_kinds import XY, Context, ObservationKind, Rows, State
from baarda.kinds import IMAGE


class BorderImageRows(Rows):
    """The image points of the border points: x and y of each, with the camera parameters
    and the point's three global columns."""

    units = {IMAGE.name: IMAGE.shown()}

    def __init__(self, ctx: Context, rows: np.ndarray):
        b = ctx.block
        im = b.image
        self.rows = rows
        self.calibration = ctx.calibration
        self.image_rows = ImageRows(b, ctx.calibration, rows)
        self.bidx = ctx.bremap[im.point[rows]]
        self.camera = b.photos.camera[im.photo[rows]]
        self.columns = ctx.point_columns(im.point[rows])
        self.xy = im.xy_mm[rows]
        self.sigma = im.sigma_xy[rows].ravel()
        pids = np.asarray(b.points.ids, dtype=object)
        self._labels(np.full(2 * len(rows), "image", dtype=object), np.tile(XY, len(rows)),
                     np.repeat(pids[im.point[rows]], 2), np.repeat(im.photo[rows], 2),
                     np.repeat(rows, 2), None, b)

    def linearize(self, state: State, ng: int):
        mb = len(self.rows)
        f, je, jp, jpar = self.image_rows.evaluate(state.eo, state.bxyz[self.bidx],
                                                   state.params, state.rot)
        jg = np.zeros((mb, 2, ng))
        free = self.image_rows.free_columns(jpar)
        for i, cols in enumerate(self.calibration.columns):
            sel = np.flatnonzero(self.camera == i)
            if len(sel) and len(cols):
                jg[sel[:, None, None], np.arange(2)[None, :, None], cols[None, None, :]] = \
                    free[sel][:, :, :len(cols)]
        for k in range(3):
            jg[np.arange(mb), :, self.columns[:, k]] = jp[:, :, k]
        return ((self.xy - f).ravel(), je.reshape(2 * mb, je.shape[2]), jg.reshape(2 * mb, ng))


class BorderImages(ObservationKind):
    """The image points of the border points (bundle/bundle_problem.py eliminates the
    others)."""

    name = "border_images"

    def bind(self, context: Context) -> Rows:
        b = context.block
        rows = np.flatnonzero(context.bremap[b.image.point] >= 0)
        return BorderImageRows(context, rows)
