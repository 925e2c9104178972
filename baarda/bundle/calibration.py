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
    coefficients,
    constants,
    kinds,
    model_of,
    parameter_names,
    parameters,
)

INTERIOR_GROUP = ("interior orientation", ("c", "x0", "y0"))


def parameter_groups(model) -> list[tuple[str, tuple[str, ...]]]:
    """Groups of a model's parameters that are tested together (the significance tests of
    a self-calibration): interior orientation, radial, decentring, affinity; Ebner's and
    Gruen's sets as one group each."""
    if model.name == "aicon":
        extra = [("radial distortion", ("a1", "a2", "a3")),
                 ("decentring distortion", ("b1", "b2")), ("affinity and shear", ("c1", "c2"))]
    elif model.name == "fisheye_forward":
        extra = [("radial distortion", ("k1", "k2", "k3", "k4")), ("aspect", ("a",))]
    elif model.name in ("ebner", "gruen"):
        extra = [(f"{model.name} additional parameters", model.params)]
    else:
        extra = [("radial distortion", ("k1", "k2", "k3")),
                 ("decentring distortion", ("p1", "p2")),
                 ("affinity and shear", ("b1", "b2", "a"))]
    return [INTERIOR_GROUP] + extra


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


def with_calibration(block, model: str | None = None, free=None):
    """The block with every camera on camera model `model` (coefficients 0 unless it keeps
    its model; Ebner's and Gruen's grid spacing from the extent of the image points) and
    with `free` estimated: a list of parameter names for every camera, "none" (nothing
    estimated) or "all" (c, x0, y0 and every coefficient of the model); None keeps the
    block's (readers and project.toml set it)."""
    from baarda.block.camera import INTERIOR, KINDS

    cams = block.cameras
    n = len(cams)
    if model is not None:
        if model not in KINDS:
            raise ValueError(f"unknown camera model '{model}' (known: {', '.join(KINDS)})")
        new = model_of(model)
        old = kinds(cams)
        coef = np.zeros((n, new.n_params))
        for i in range(n):
            if model_of(old[i]).name == new.name:
                coef[i] = coefficients(cams, i)
        const = np.full((n, len(new.constants)), np.nan)
        if new.name in ("ebner", "gruen"):
            cam = block.photos.camera[block.image.photo]
            for i in range(n):
                xy = block.image.xy_mm[cam == i] - cams.principal_point_mm[i]
                extent = float(np.max(np.abs(xy), initial=1.0))
                const[i, 0] = extent if new.name == "ebner" else extent / 2
        elif new.constants:
            raise ValueError(f"camera model '{model}' needs {', '.join(new.constants)}: give "
                             "it in cameras.csv")
        cams = replace(cams, model=np.full(n, model, dtype=object),
                       coefficients=coef if new.n_params else None,
                       constants=const if new.constants else None, free=None)
    if free is not None:
        if free == "none":
            chosen = ((),) * n
        elif free == "all":
            chosen = tuple(INTERIOR + model_of(k).params for k in kinds(cams))
        else:
            names = tuple(free)
            for i in range(n):
                bad = [p for p in names if p not in parameter_names(cams, i)]
                if bad:
                    raise ValueError(f"camera {cams.ids[i]}: '{bad[0]}' is not a parameter of "
                                     f"its model '{kinds(cams)[i]}' "
                                     f"({', '.join(parameter_names(cams, i))})")
            chosen = (names,) * n
        cams = replace(cams, free=chosen)
    return replace(block, cameras=cams)
