"""The image observations of a bundle as the linearisation takes them, camera by camera.

An ImageRows is one set of rows of block.image (BundleProblem: those of the eliminated
points and those of the border points) with what no iteration changes computed once; its
`evaluate` gives the collinearity equations' values and Jacobians (bundle/collinearity.py)
of every row with its camera's model (with the columns of the free parameters of a camera
in its photo's block among the photo's), `free_columns` the columns of the free camera
parameters in the border (bundle/calibration.py).
"""

from __future__ import annotations

import numpy as np

from baarda.block.photo_block import Block
from baarda.bundle.calibration import Calibration
from baarda.bundle.collinearity import camera_projection


def model_groups(calibration: Calibration) -> list[tuple]:
    """(camera model, indices of its cameras) for every model of the block."""
    groups: dict[int, tuple] = {}
    for i, model in enumerate(calibration.models):
        groups.setdefault(id(model), (model, []))[1].append(i)
    return list(groups.values())


FUSED = "brown_forward"  # the camera model linearised in one numba pass


def _stacked(rot: tuple) -> np.ndarray:
    """(n, 3, 3, 3) the derivatives of the rotations by omega, phi, kappa."""
    return np.ascontiguousarray(np.stack(rot[1:], 1))


class ImageRows:
    """One set of image rows (rows of block.image) as the linearisation takes them, with
    what no iteration changes computed once: the photo of each row, the rows of each camera
    model's cameras with their observations and constants, the rows of each camera with
    free parameters."""

    def __init__(self, block: Block, calibration: Calibration, rows: np.ndarray):
        im = block.image
        photo = im.photo[rows]
        cam = block.photos.camera[photo]
        self.m = len(rows)
        self.photo = photo
        self.width = 3 + max((mo.n_params for mo in calibration.models), default=0)
        # (model, its cameras, their rows, the photo and observation of each, the index
        # among the cameras of each row (None: one camera), the constants (of each row))
        self.groups = []
        for model, cams in model_groups(calibration):
            if len(cams) == 1:
                i = cams[0]
                sel = np.flatnonzero(cam == i)
                which, k = None, calibration.constants[i]
            else:  # cameras of one model at once (BAL: a camera per photo), row by row
                local = np.full(len(calibration.models), -1)
                local[cams] = np.arange(len(cams))
                sel = np.flatnonzero(local[cam] >= 0)
                which = local[cam[sel]]
                k = np.array([calibration.constants[i] for i in cams], float)[which]
            if len(sel):
                self.groups.append((model, cams, sel, photo[sel], im.xy_mm[rows[sel]], which,
                                    k))
        # (rows of a camera, its free parameters) of every camera with free parameters in
        # the border
        owner = calibration.owner
        self.free = [(np.flatnonzero(cam == i), idx)
                     for i, idx in enumerate(calibration.free_index)
                     if len(idx) and owner[i] < 0 and (cam == i).any()]
        self.n_free = calibration.width
        # (rows, free parameters) of the cameras in their photo's block, grouped by the
        # parameters they free; the brown_forward kernel writes those of its cameras itself
        # (`columns`: the column of each parameter of each of its cameras, or -1)
        by_free: dict[tuple, list[int]] = {}
        fused = {i for model, cams in model_groups(calibration) if model.name == FUSED
                 for i in cams}
        for i in np.flatnonzero(owner >= 0):
            if i not in fused:
                by_free.setdefault(tuple(calibration.free_index[i]), []).append(int(i))
        self.owned = []
        for idx, cams in by_free.items():
            sel = np.flatnonzero(np.isin(cam, cams))
            if len(sel):
                self.owned.append((sel, np.array(idx, np.int64)))
        self.columns = {}
        for model, cams, *_ in self.groups:
            if model.name == FUSED:
                table = np.full((len(cams), 3 + model.n_params), -1, np.int64)
                for q, i in enumerate(cams):
                    if owner[i] >= 0:
                        table[q, calibration.free_index[i]] = 6 + np.arange(
                            len(calibration.free_index[i]))
                self.columns[id(model)] = table
        self.photo_width = calibration.photo_width
        # d f / d(camera parameters) is needed for the border's columns (free_columns) and
        # the cameras in their photo's block that the kernel does not write itself
        self.need_jpar = bool(self.free) or bool(self.owned)

    def evaluate(self, eo: np.ndarray, xyz: np.ndarray, params, rot: tuple):
        """f, je, jp, jpar (3 + k columns of its camera) of the rows, camera by camera:
        eo (n_photos, 6), xyz (m, 3) the point of each row, params the parameters of
        every camera, rot rotation_and_derivatives of every photo's angles.  je: d/d(the
        photo's unknowns), its orientation (6), then the free parameters of a camera in the
        photo's block (photo_width columns, 0 for the other rows)."""
        from baarda.bundle.projection_kernel import brown_forward_rows, take_columns

        m = self.m
        f = np.zeros((m, 2))
        je, jp = np.zeros((m, 2, 6 + self.photo_width)), np.zeros((m, 2, 3))
        jpar = np.zeros((m if self.need_jpar else 0, 2, self.width))
        for model, cams, sel, photo, observed, which, k in self.groups:
            if model.name == FUSED:  # BAL, COLMAP, OpenSfM: one numba pass
                table = np.array([params[i] for i in cams], float)
                brown_forward_rows(
                    np.ascontiguousarray(rot[0]), _stacked(rot),
                    np.ascontiguousarray(eo[:, :3], dtype=float), self.photo,
                    np.ascontiguousarray(xyz, dtype=float), sel, table,
                    np.zeros(len(sel), np.int64) if which is None else which,
                    self.columns[id(model)], f, je, jp, jpar)
                continue
            p = params[cams[0]] if which is None else np.array(
                [params[i] for i in cams], float)[which]
            out = camera_projection(eo, xyz[sel], photo, p, model, k, observed, rot)
            if len(sel) == m and not self.photo_width:
                f, je, jp = out[0], out[1], out[2]
            else:
                f[sel], je[sel, :, :6], jp[sel] = out[0], out[1], out[2]
            if self.need_jpar:
                jpar[sel, :, :out[3].shape[2]] = out[3]
        for sel, idx in self.owned:
            take_columns(jpar, sel, idx, je, 6)
        return f, je, jp, jpar

    def free_columns(self, jpar: np.ndarray) -> np.ndarray:
        """jpar restricted to the free parameters of each row's camera in the border,
        (m, 2, width)."""
        out = np.zeros((self.m, 2, self.n_free))
        for sel, idx in self.free:
            out[sel, :, :len(idx)] = jpar[sel][:, :, idx]
        return out
