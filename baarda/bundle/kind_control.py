"""The observed control coordinates of border points as extra rows of the bundle
(bundle/observation_kinds.py), m.
"""

from __future__ import annotations

import numpy as np

from baarda.bundle.observation_kinds import XYZ, Context, ObservationKind, Rows, State
from baarda.kinds import CONTROL


class BorderControlRows(Rows):
    """The observed control coordinates of the border points (sigma > 0)."""

    units = {CONTROL.name: CONTROL.shown()}

    def __init__(self, ctx: Context, control: np.ndarray):
        pts = ctx.block.points
        sig = pts.sigma[control]
        self.sel = np.flatnonzero((np.isfinite(sig) & (sig > 0)).ravel())
        ci, cc = np.divmod(self.sel, 3)
        self.control, self.point_index, self.axis = control, control[ci], cc
        self.columns = ctx.point_columns(control)[ci, cc] if len(ci) else np.zeros(0, int)
        self.bidx = ctx.bremap[control]
        self.given = pts.xyz[control]
        self.sigma = sig.ravel()[self.sel]
        pids = np.asarray(pts.ids, dtype=object)
        self._labels(np.full(len(self.sel), "control", dtype=object),
                     np.tile(XYZ, len(control))[self.sel],
                     np.repeat(pids[control], 3)[self.sel],
                     control_index=np.repeat(control, 3)[self.sel])

    def linearize(self, state: State, ng: int):
        n = len(self.sel)
        j = np.zeros((n, ng))
        j[np.arange(n), self.columns] = 1.0
        cur = state.bxyz[self.bidx]
        return (self.given - cur).ravel()[self.sel], np.zeros((n, 6)), j


class BorderControl(ObservationKind):
    """The observed control coordinates of the border points."""

    name = "border_control"

    def bind(self, context: Context) -> Rows:
        pts = context.block.points
        control = context.border_ids[pts.role[context.border_ids] == "control"]
        return BorderControlRows(context, control)
