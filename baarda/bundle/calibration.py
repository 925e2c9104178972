"""The camera parameters of a bundle adjustment: which are estimated (self-calibration) and
where they sit among the unknowns of the Schur system.

Every camera has the parameter vector [c, x0, y0, coefficients of its model] (mm, the
model's units; block/camera.py); `free` (the block's settings.calibration_free, as the
run's configuration resolves it) names those that are unknowns.  A camera
shared by several photos has its free parameters among the global unknowns
(adjustment/schur_system.py: the border, shared by every image observation of the camera).
A camera that exactly one photo uses (BAL, COLMAP's camera per image) has them in that
photo's block instead: the photo's unknowns are its six orientation unknowns, then its
camera's free parameters (`photo_width` columns, as Ceres keeps them), eliminated with the
photo in the reduced camera system, so that no statistic pays for a dense border of three
columns per camera.  This holds when at least half of the photos own such a camera
(`PHOTO_BLOCK_SHARE`); the other photos' extra columns are then held (not unknowns), and
with fewer the border is cheaper.
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


PHOTO_BLOCK_SHARE = 0.5  # photos owning a camera with free parameters, at least this share


class Calibration:
    """Nominal parameters of every camera, the free ones and where they are unknowns: the
    global columns of a shared camera (`columns`), or the photo whose block holds those of a
    camera that one photo uses (`owner`, -1: none) at the first columns after its six
    orientation unknowns.  photo_camera: the camera of every photo (None: every camera in
    the border)."""

    def __init__(self, cameras, photo_camera: np.ndarray | None = None,
                 first_column: int = 0,
                 free: tuple[tuple[str, ...], ...] | None = None):
        n = len(cameras)
        self.cameras = cameras
        self.models = [model_of(k) for k in kinds(cameras)]
        self.names = [parameter_names(cameras, i) for i in range(n)]
        self.nominal = [parameters(cameras, i) for i in range(n)]
        self.constants = [constants(cameras, i) for i in range(n)]
        free = free if free is not None else ((),) * n
        self.free_index = [np.array([self.names[i].index(p) for p in free[i]], dtype=np.int64)
                           for i in range(n)]
        sizes = np.array([len(f) for f in self.free_index], dtype=np.int64)
        self.owner = np.full(n, -1, np.int64)
        self.n_photos = 0 if photo_camera is None else len(photo_camera)
        if photo_camera is not None and len(photo_camera):
            photo_camera = np.asarray(photo_camera, np.int64)
            single = (np.bincount(photo_camera, minlength=n) == 1) & (sizes > 0)
            owning = np.flatnonzero(single[photo_camera])
            if len(owning) and len(owning) >= PHOTO_BLOCK_SHARE * len(photo_camera):
                self.owner[photo_camera[owning]] = owning
        border = np.where(self.owner < 0, sizes, 0)
        starts = first_column + np.concatenate([[0], np.cumsum(border)[:-1]]).astype(np.int64)
        self.columns = [starts[i] + np.arange(border[i]) for i in range(n)]
        self.n = int(sizes.sum())
        self.n_global = int(border.sum())
        self.labels = [f"{self.names[i][j]} of camera {cameras.ids[i]}"
                       for i in range(n) for j in self.free_index[i]]
        self.global_labels = [f"{self.names[i][j]} of camera {cameras.ids[i]}"
                              for i in range(n) if self.owner[i] < 0
                              for j in self.free_index[i]]
        owned = np.flatnonzero(self.owner >= 0)
        self.photo_width = int(sizes[owned].max()) if len(owned) else 0
        # the photos' extra columns that are no unknowns (photos without a camera of their
        # own, or with fewer free parameters than photo_width)
        self.held_photo_columns = np.ones((self.n_photos, self.photo_width), bool)
        for i in owned:
            self.held_photo_columns[self.owner[i], :sizes[i]] = False

    @property
    def width(self) -> int:
        """The largest number of free parameters of one camera in the border (columns of
        jg)."""
        return max((len(f) for i, f in enumerate(self.free_index) if self.owner[i] < 0),
                   default=0)

    def start(self) -> np.ndarray:
        """The nominal values of the border's free parameters (the global vector's camera
        part)."""
        if not self.n_global:
            return np.zeros(0)
        return np.concatenate([self.nominal[i][f] for i, f in enumerate(self.free_index)
                               if self.owner[i] < 0])

    def photo_start(self) -> np.ndarray:
        """(n_photos, photo_width) the nominal values of the free parameters of the cameras
        in the photos' blocks (0 in held columns)."""
        out = np.zeros((self.n_photos, self.photo_width))
        for i in np.flatnonzero(self.owner >= 0):
            f = self.free_index[i]
            out[self.owner[i], :len(f)] = self.nominal[i][f]
        return out

    def current(self, g: np.ndarray, fp: np.ndarray | None = None) -> list[np.ndarray]:
        """Each camera's parameter vector with the free ones from the global vector g and
        (cameras in a photo's block) the photos' extra unknowns fp (n_photos,
        photo_width)."""
        out = []
        for i, nominal in enumerate(self.nominal):
            p = nominal.copy()
            f = self.free_index[i]
            p[f] = g[self.columns[i]] if self.owner[i] < 0 else fp[self.owner[i], :len(f)]  # type: ignore[index]  # fp: owned cameras
            out.append(p)
        return out

    def adjusted_cameras(self, g: np.ndarray, fp: np.ndarray | None = None):
        """`Cameras` with the parameters of g and fp (c, principal point and
        coefficients)."""
        params = self.current(g, fp)
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
