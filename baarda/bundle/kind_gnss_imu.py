"""GNSS positions and IMU attitudes of the photos as extra rows of the bundle
(bundle/observation_kinds.py; the observation equations in bundle/gnss_imu.py), with their
global unknowns (shifts, drifts, boresight).
"""

from __future__ import annotations

from baarda.block.photo_block import Block
from baarda.bundle.gnss_imu import GnssImu
from baarda.bundle.observation_kinds import Context, ObservationKind, Rows, State, _empty
from baarda.kinds import EXTERIOR


class GnssImuRows(Rows):
    """GNSS positions and IMU attitudes of the photos (bundle/gnss_imu.py): X, Y, Z of every
    position, then omega, phi, kappa of every attitude."""

    def __init__(self, ctx: Context):
        b = ctx.block
        self.gnss_imu = gi = GnssImu(b, ctx.layout.start("gnss_imu"))
        self.units = {k.name: k.shown(b.settings.angle_unit) for k in EXTERIOR}
        self.sigma = gi.sigma
        self._labels(gi.kind, gi.component, _empty(gi.m), gi.photos, block=b)

    def linearize(self, state: State, ng: int):
        e, jxf, jxg = self.gnss_imu.rows(state.eo, state.g, ng, state.rot)
        return e, jxf[:, 0], jxg[:, 0]


class GnssImuKind(ObservationKind):
    """block.gnss and block.imu, with the shifts, drifts and boresight the block's settings
    ask for."""

    name = "gnss_imu"

    def global_labels(self, block: Block) -> list[str]:
        return GnssImu(block, 0).labels

    def bind(self, context: Context) -> Rows:
        return GnssImuRows(context)
