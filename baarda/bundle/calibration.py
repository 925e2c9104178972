"""The camera parameters of a bundle adjustment: which are estimated (self-calibration) and
where they sit among the global unknowns of the Schur system.

Every camera has the parameter vector [c, x0, y0, coefficients of its model] (mm, the
model's units; block/camera.py); `Cameras.free` names those that are unknowns.  They are
global unknowns (adjustment/schur_system.py): each one is shared by every image observation of
its camera.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from baarda.block.camera import (
    constants,
    kinds,
    model_of,
    parameter_names,
    parameters,
)

INTERIOR_GROUP = ("interior orientation", ("c", "x0", "y0"))


def parameter_groups(model) -> list[tuple[str, tuple[str, ...]]]:
    """Groups of a model's parameters that are tested together (the significance tests of
    a self-calibration): the interior orientation, then the groups the camera model declares
    (block/camera_models.py: radial, decentring, affinity; Ebner's and Gruen's sets as one
    group each)."""
    return [INTERIOR_GROUP, *model.parameter_groups]


class Calibration:
    """Nominal parameters of every camera, the free ones and their global columns."""

    def __init__(self, cameras, first_column: int = 0):
        n = len(cameras)
        self.cameras = cameras
        self.models = [model_of(k) for k in kinds(cameras)]
        self.names = [parameter_names(cameras, i) for i in range(n)]
        self.nominal = [parameters(cameras, i) for i in range(n)]
        self.constants = [constants(cameras, i) for i in range(n)]
        free = cameras.free if cameras.free is not None else ((),) * n
        self.free_index = [np.array([self.names[i].index(p) for p in free[i]], dtype=np.int64)
                           for i in range(n)]
        sizes = [len(f) for f in self.free_index]
        starts = first_column + np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        self.columns = [starts[i] + np.arange(sizes[i]) for i in range(n)]
        self.n = int(sum(sizes))
        self.labels = [f"{self.names[i][j]} of camera {cameras.ids[i]}"
                       for i in range(n) for j in self.free_index[i]]

    @property
    def width(self) -> int:
        """The largest number of free parameters of one camera (columns of jg)."""
        return max((len(f) for f in self.free_index), default=0)

    def start(self) -> np.ndarray:
        """The nominal values of the free parameters (the global vector's camera part)."""
        if not self.n:
            return np.zeros(0)
        return np.concatenate([self.nominal[i][f] for i, f in enumerate(self.free_index)])

    def current(self, g: np.ndarray) -> list[np.ndarray]:
        """Each camera's parameter vector with the free ones from the global vector g."""
        out = []
        for i, nominal in enumerate(self.nominal):
            p = nominal.copy()
            p[self.free_index[i]] = g[self.columns[i]]
            out.append(p)
        return out

    def adjusted_cameras(self, g: np.ndarray):
        """`Cameras` with the parameters of g (c, principal point and coefficients)."""
        params = self.current(g)
        c = self.cameras
        width = max((m.n_params for m in self.models), default=0)
        coef = np.zeros((len(c), width))
        for i, p in enumerate(params):
            coef[i, :len(p) - 3] = p[3:]
        return replace(c, focal_mm=np.array([p[0] for p in params]),
                       principal_point_mm=np.array([p[1:3] for p in params]),
                       coefficients=coef if width else c.coefficients)

    def groups(self, camera: int) -> list[tuple[str, np.ndarray]]:
        """(name, indices among the camera's free parameters) of each group of its free
        parameters to test together (`parameter_groups`)."""
        names = [self.names[camera][j] for j in self.free_index[camera]]
        out = []
        for label, members in parameter_groups(self.models[camera]):
            rows = np.array([k for k, p in enumerate(names) if p in members], dtype=np.int64)
            if len(rows):
                out.append((label, rows))
        return out
