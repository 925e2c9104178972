"""The observation kinds of the bundle carried as extra rows of the Schur system, one
protocol for all (the way GTSAM's factors and Ceres' cost functions work, vectorised per
kind).

The Schur system's own rows are the image points and the control of the eliminated points
(bundle/bundle_problem.py).  Every other observation is an extra row tied to at most one
photo and to the global unknowns, and comes from an `ObservationKind`, one module each
(`kind_image.py`: the image points of border points, `kind_control.py`: their control,
`kind_distance.py`, `kind_gnss_imu.py`), registered in `registered_kinds.py`:

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
