"""Systematic model deformations: the standard set of non-conventional alternative hypotheses.

FOTEF (sec. 5, after Molenaar 1978) tests deformations of the photogrammetric models that are
the same in every model (block-invariant) or in every model of a strip (strip-invariant),
instead of adding self-calibration parameters blindly.  The set below follows from the
systematic errors that survive relative orientation of a stereo pair:

========== =================== ===================================================
name       field (du, dv, dw)  cause
========== =================== ===================================================
affinity   (u, -v, 0)          film or plotter affinity: different x and y scale
shear      (v, u, 0)           non-orthogonal comparator/plotter axes
radial     (u r2, v r2, 0)     uncorrected radial distortion (third order)
z_scale    (0, 0, w)           wrong principal distance: height scale differs
dishing    (0, 0, r2)          earth curvature, refraction, radial distortion in z
bend       (0, 0, u2 - v2)     cylindrical bending (film unflatness, residual phi)
torsion    (0, 0, u v)         model twist (residual omega of the base, unflatness)
========== =================== ===================================================

u, v, w are the model coordinates relative to the model centroid divided by the block's
typical model radius L (median over the models of the largest planimetric distance of a
model point from the centroid), r2 = u^2 + v^2.  A deformation of size 1 moves a point at
distance L by about 1 unit; the H columns are built in µm so the estimated size nabla is the
displacement in µm at the model's edge.  Parts of a field that a similarity transformation
absorbs (constant, linear in the rotation/scale directions) are not testable; the test
handles that by itself (the quadratic form only sees what the adjustment cannot absorb).
"""

from __future__ import annotations

import numpy as np

from baarda.block.model_block import ModelBlock

PLANIMETRIC = ("affinity", "shear", "radial")
HEIGHT = ("z_scale", "dishing", "bend", "torsion")
ALL = PLANIMETRIC + HEIGHT


def model_radius(block: ModelBlock, centroids: np.ndarray | None = None) -> float:
    """Median over models of the largest planimetric distance of a point from the centroid."""
    c = block.centroids() if centroids is None else centroids
    use = ~block.pc[block.obs_point]
    d = np.hypot(*(block.obs_xyz[use, :2] - c[block.obs_model[use], :2]).T)
    rmax = np.zeros(block.n_models)
    np.maximum.at(rmax, block.obs_model[use], d)
    rmax = rmax[rmax > 0]
    return float(np.median(rmax)) if len(rmax) else 1.0


def deformation_rows(block: ModelBlock, name: str, centroids: np.ndarray | None = None,
                     radius: float | None = None) -> np.ndarray:
    """Displacement (m, 3) of every model coordinate row for a deformation of size 1."""
    if name not in ALL:
        raise ValueError(f"unknown deformation '{name}' (known: {', '.join(ALL)})")
    c = block.centroids() if centroids is None else centroids
    el = model_radius(block, c) if radius is None else radius
    u, v, w = ((block.obs_xyz - c[block.obs_model]) / el).T
    w = np.nan_to_num(w)
    r2 = u**2 + v**2
    zero = np.zeros_like(u)
    field = {
        "affinity": (u, -v, zero), "shear": (v, u, zero), "radial": (u * r2, v * r2, zero),
        "z_scale": (zero, zero, w), "dishing": (zero, zero, r2),
        "bend": (zero, zero, u**2 - v**2), "torsion": (zero, zero, u * v),
    }[name]
    return np.column_stack(field)
