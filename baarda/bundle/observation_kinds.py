"""The observation kinds of the bundle carried as extra rows of the Schur system, one
protocol for all (the way GTSAM's factors and Ceres' cost functions work, vectorised per
kind).

The Schur system's own rows are the image points and the control of the eliminated points
(bundle/bundle_problem.py).  Every other observation is an extra row tied to at most one
photo and to the global unknowns, and comes from an `ObservationKind`:

* `tied_points(block)`: the ground points it ties together; they become global unknowns
  (border points, three columns each) instead of being eliminated (a distance, a height
  difference between two points);
* `global_labels(block)`: unknowns of its own (GNSS shifts, drifts, the IMU boresight);
* `bind(context)`: its rows in a given problem (`Rows`): the a-priori sigma, the labels and
  the photo of each row, and `linearize(state)` -> misclosures e = observed - computed (m,),
  d/d(photo's unknowns) (m, 6): its orientation, or (m, 6 + photo_width) with the free
  parameters of a camera in the photo's block (bundle/calibration.py), and d/d(global
  unknowns) (m, ng).

Held unknowns (a free network's datum, fixed control) are the problem's business: it zeroes
their columns in every kind's Jacobians.  The global unknowns are a named layout
(`GlobalLayout`): the camera parameters, the border points, then each kind's own.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from baarda.block.photo_block import Block
from baarda.bundle.calibration import Calibration
from baarda.bundle.gnss_imu import ANGLE_UNITS, GnssImu
from baarda.bundle.image_rows import ImageRows

XY = np.array(["x", "y"], dtype=object)
XYZ = np.array(["X", "Y", "Z"], dtype=object)


@dataclass(frozen=True)
class GlobalLayout:
    """The global unknowns in named segments, in order: `start(name)`, `columns(name)`."""

    names: tuple[str, ...]
    sizes: tuple[int, ...]
    labels: tuple[str, ...]

    @property
    def n(self) -> int:
        return int(sum(self.sizes))

    def start(self, name: str) -> int:
        i = self.names.index(name)
        return int(sum(self.sizes[:i]))

    def columns(self, name: str) -> slice:
        a = self.start(name)
        return slice(a, a + self.sizes[self.names.index(name)])


@dataclass(frozen=True)
class Context:
    """What a kind needs to bind its rows: the block, its camera parameters, the global
    layout and the border points (block indices, and each point's border index or -1)."""

    block: Block
    calibration: Calibration
    layout: GlobalLayout
    border_ids: np.ndarray
    bremap: np.ndarray

    def point_columns(self, points: np.ndarray) -> np.ndarray:
        """(n, 3) global columns of the X, Y, Z of border points (block indices)."""
        return self.layout.start("points") + 3 * self.bremap[points][:, None] + np.arange(3)


@dataclass(frozen=True)
class State:
    """The estimate as the kinds see it: orientations (n_photos, 6), the global vector, the
    camera parameters per camera, the border points (nb, 3) and the photos' rotations
    with their derivatives (block/rotation.rotation_and_derivatives)."""

    eo: np.ndarray
    g: np.ndarray
    params: list
    bxyz: np.ndarray
    rot: tuple


def _empty(n: int) -> np.ndarray:
    return np.full(n, "", dtype=object)


class Rows(ABC):
    """The rows of one kind in one problem.  Per row: `sigma` (a priori), `kind`,
    `component`, `frame` (photo id or ''), `point` (point id or a name), `photo` (photo index
    or -1), `image_row` and `control_index` (into block.image / block.points, or -1)."""

    sigma: np.ndarray
    kind: np.ndarray
    component: np.ndarray
    frame: np.ndarray
    point: np.ndarray
    photo: np.ndarray
    image_row: np.ndarray
    control_index: np.ndarray
    units: dict[str, tuple[float, str]] = {}

    @property
    def m(self) -> int:
        return len(self.sigma)

    @abstractmethod
    def linearize(self, state: State, ng: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(e (m,), jxf (m, 6) or (m, 6 + photo_width), jxg (m, ng)) at `state`."""

    def _labels(self, kind, component, point, photo=None, image_row=None,
                control_index=None, block: Block | None = None) -> None:
        m = len(self.sigma)
        self.kind = np.asarray(kind, dtype=object)
        self.component = np.asarray(component, dtype=object)
        self.point = np.asarray(point, dtype=object)
        self.photo = np.full(m, -1) if photo is None else np.asarray(photo, np.int64)
        ids = np.asarray(block.photos.ids, dtype=object) if block is not None else None
        self.frame = _empty(m) if photo is None else ids[self.photo]  # type: ignore[index]  # photos: a block
        self.image_row = np.full(m, -1) if image_row is None else np.asarray(image_row)
        self.control_index = (np.full(m, -1) if control_index is None
                              else np.asarray(control_index))


class ObservationKind(ABC):
    """An observation kind of the bundle (module docstring); `name` names its own global
    unknowns in the layout."""

    @property
    def name(self) -> str:
        return type(self).__name__

    def tied_points(self, block: Block) -> np.ndarray:
        """Block indices of the points it ties together (they become border points)."""
        return np.zeros(0, np.int64)

    def global_labels(self, block: Block) -> list[str]:
        """Labels of the global unknowns of its own (none by default)."""
        return []

    @abstractmethod
    def bind(self, context: Context) -> Rows:
        """Its rows in a problem."""


# ------------------------------------------------------------------ the built-in kinds
class BorderImageRows(Rows):
    """The image points of the border points: x and y of each, with the camera parameters
    and the point's three global columns."""

    units = {"image": (1e3, "µm")}

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


class BorderControlRows(Rows):
    """The observed control coordinates of the border points (sigma > 0)."""

    units = {"control": (1.0, "m")}

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


class DistanceRows(Rows):
    """Distances between two border points (scale bars, taped distances), m."""

    units = {"distance": (1.0, "m")}

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


class GnssImuRows(Rows):
    """GNSS positions and IMU attitudes of the photos (bundle/gnss_imu.py): X, Y, Z of every
    position, then omega, phi, kappa of every attitude."""

    def __init__(self, ctx: Context):
        b = ctx.block
        self.gnss_imu = gi = GnssImu(b, ctx.layout.start("gnss_imu"))
        unit = b.settings.angle_unit
        self.units = {"gnss": (1.0, "m"),
                      "imu": ANGLE_UNITS.get(unit, ANGLE_UNITS["rad"])}
        self.sigma = gi.sigma
        self._labels(gi.kind, gi.component, _empty(gi.m), gi.photos, block=b)

    def linearize(self, state: State, ng: int):
        e, jxf, jxg = self.gnss_imu.rows(state.eo, state.g, ng, state.rot)
        return e, jxf[:, 0], jxg[:, 0]


class BorderImages(ObservationKind):
    def bind(self, context: Context) -> Rows:
        b = context.block
        rows = np.flatnonzero(context.bremap[b.image.point] >= 0)
        return BorderImageRows(context, rows)


class BorderControl(ObservationKind):
    def bind(self, context: Context) -> Rows:
        pts = context.block.points
        control = context.border_ids[pts.role[context.border_ids] == "control"]
        return BorderControlRows(context, control)


class Distances(ObservationKind):
    """block.distances between points that are adjusted (`usable`: the problem's)."""

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


class GnssImuKind(ObservationKind):
    name = "gnss_imu"

    def global_labels(self, block: Block) -> list[str]:
        return GnssImu(block, 0).labels

    def bind(self, context: Context) -> Rows:
        return GnssImuRows(context)
