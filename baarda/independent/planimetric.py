"""Planimetric independent-model adjustment with a separate height adjustment.

The planimetric adjustment (4 parameters per model, projection centres left out) assumes
level models, as FOTEF's and PAT-M's planimetric blocks do: a tilt t of a model moves a point
of height difference dz by t dz in planimetry.  Tilted models (analytical relative
orientation in the frame of the left photo) can be levelled first (`level`): each model is
rotated about its centroid by the tilt of its transformation in a spatial adjustment, so
that its z axis is vertical (kappa kept), as a plotter operator levels a model in absolute
orientation.

The height adjustment (vertical shift and two tilts per model, the scale from planimetry,
projection centres as height tie points) is linear.  In it the longitudinal tilt of a model
is carried only by height control and tie-point heights: in independent-model
triangulation the tilt is transferred along a strip by the planimetric position of the
projection centres, which a separate height adjustment does not see (PAT-M43 users put the
height control in dense cross chains for that reason).  A model whose tilts are not
determined is reported (GeometryError): use the spatial (3D) adjustment for such blocks.
"""

from __future__ import annotations

import numpy as np

from baarda.block.model_block import ModelBlock
from baarda.independent.model_problem import adjust_models
from baarda.independent.model_result import ModelResult
from baarda.independent.similarity import rotation3d
from baarda.options import Progress


def height_possible(block: ModelBlock, control_keep: np.ndarray | None = None) -> str | None:
    """None if the models can be levelled and a height adjustment made, else the reason."""
    if not np.isfinite(block.obs_xyz[:, 2]).all():
        return "model coordinates without z: planimetry only (the models must be level)"
    keep = block.controlled[:, 2]
    if control_keep is not None:
        keep = keep & control_keep[:, 2]
    if keep.sum() < 3:
        return (f"{int(keep.sum())} height control point(s): planimetry only, models not "
                "levelled")
    return None


def levelling_rotations(params3d: np.ndarray) -> np.ndarray:
    """(nm, 3, 3) rotations Q of the model frames that make their z axis vertical.

    R (model -> terrain) maps n = R^T e_Z to e_Z; Q is the smallest rotation with Q n = e_z,
    so that R Q^T is a rotation about the vertical only.
    """
    r = rotation3d(params3d)
    n = r[:, 2, :]  # R^T e_Z: the vertical in model coordinates
    ez = np.array([0.0, 0.0, 1.0])
    axis = np.cross(n, ez)
    s = np.linalg.norm(axis, axis=1)
    c = n @ ez
    k = np.where(s[:, None] > 1e-15, axis / np.where(s > 1e-15, s, 1)[:, None], 0.0)
    kx = np.zeros((len(n), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx = kx - np.swapaxes(kx, 1, 2)
    return (np.eye(3) + s[:, None, None] * kx
            + (1 - c)[:, None, None] * kx @ kx)


def level(block: ModelBlock, obs_keep: np.ndarray | None = None,
          control_keep: np.ndarray | None = None, start: tuple | None = None,
          progress: Progress | None = None) -> tuple[ModelBlock, np.ndarray]:
    """Level the models by the tilts of a spatial adjustment.

    Returns (levelled block, tilt angle of each model (nm,) [rad]).
    """
    say = progress or (lambda msg: None)
    r3 = adjust_models(block, "3d", obs_keep=obs_keep, control_keep=control_keep, start=start)
    q = levelling_rotations(r3.params)
    c = r3.problem.centroid
    obs = block.obs_xyz.copy()
    m = block.obs_model
    obs = c[m] + np.einsum("mij,mj->mi", q[m], obs - c[m])
    tilt = np.arccos(np.clip(np.einsum("mii->m", q) * 0.5 - 0.5, -1, 1))
    say(f"models levelled by up to {np.max(tilt, initial=0) * 1e3:.3g} mrad")
    return block.with_observations(obs), tilt


def check_tilts(result: ModelResult, factor: float = 30.0) -> None:
    """Raise GeometryError when the height control does not determine the model tilts.

    A tilt (mm at the model edge) whose a-priori standard deviation exceeds `factor` times
    the largest a-priori sigma of z is taken as undetermined.
    """
    from baarda.errors import GeometryError

    q = result.factor.frame_covariance()
    std = np.sqrt(np.maximum(np.diagonal(q, axis1=1, axis2=2), 0))[:, 1:]
    limit = factor * float(np.max(result.problem.sigma_obs))
    bad = np.flatnonzero(np.max(std, axis=1) > limit)
    if len(bad):
        names = ", ".join(result.block.models[m] for m in bad[:10])
        raise GeometryError(
            f"the height adjustment cannot determine the tilts of model(s) {names} "
            f"(standard deviation up to {np.max(std) * 1e3:.0f} µm at the model edge): the "
            "height control does not reach them (a separate height adjustment needs height "
            "control strings at every model boundary); use the spatial adjustment (3D)")
