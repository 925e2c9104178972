"""Geometric checks and approximations before a bundle adjustment."""

from __future__ import annotations

import numpy as np

from baarda.block.camera import constants, ideal_image_coordinates, kinds, model_of, parameters
from baarda.block.photo_block import Block
from baarda.block.rotation import rotation_matrix
from baarda.bundle.collinearity import camera_projection
from baarda.errors import GeometryError, figure
from baarda.sections import MAX_LISTED


def usable_points(block: Block) -> tuple[np.ndarray, list[str]]:
    """Points that can be determined: two or more rays, or one ray and full XYZ control.

    Returns a boolean mask over block.points and messages for the points left out.
    """
    rays = block.rays()
    full = block.points.controlled.all(axis=1)
    ok = (rays >= 2) | ((rays == 1) & full)
    notes = []
    ties: dict[bool, list[str]] = {True: [], False: []}  # no ray / one ray: tie points
    for j in np.flatnonzero(~ok):
        pid, role = block.points.ids[j], block.points.role[j]
        if role == "tie":  # counted together: a large block can leave out thousands
            ties[bool(rays[j] == 0)].append(str(pid))
        else:  # control and check points each by name
            notes.append(_left_out(f"{role} point {pid}", 1, rays[j] == 0))
    for none, ids in ties.items():
        if len(ids) == 1:
            notes.append(_left_out(f"tie point {ids[0]}", 1, none))
        elif ids:
            shown = ", ".join(ids[:MAX_LISTED]) + (f" and {len(ids) - MAX_LISTED} more"
                                                  if len(ids) > MAX_LISTED else "")
            notes.append(_left_out(f"{len(ids)} tie points", len(ids), none) + f": {shown}")
    return ok, notes


def _left_out(what: str, n: int, no_ray: bool) -> str:
    """The note on points left out for want of rays: `what` the point(s), n how many."""
    if no_ray:
        return (f"{what} {'has' if n == 1 else 'have'} no ray (measured on no photo, or "
                "{} rays left out: see the notes above): left out".format(
                    "its" if n == 1 else "their"))
    return (f"{what} {'is' if n == 1 else 'are'} measured on one photo only (one ray "
            "cannot be intersected): left out")


def check_datum(block: Block, keep: np.ndarray) -> list[str]:
    """Raise GeometryError when the control cannot fix position, scale and orientation;
    else the warnings about weak control geometry (with their numbers)."""
    ctrl = block.points.controlled & keep[:, None]
    xyz = block.points.xyz
    plan = np.flatnonzero(ctrl[:, 0] & ctrl[:, 1])
    height = np.flatnonzero(ctrl[:, 2])
    height_xy = xyz[height, :2]
    height_xy = height_xy[np.isfinite(height_xy).all(axis=1)]  # height-only: X, Y may be empty
    problems = []
    if len(plan) < 2:
        problems.append(f"{len(plan)} planimetric (X, Y) control point(s); at least two are "
                        "needed for position, scale and azimuth")
    elif np.ptp(xyz[plan, :2], axis=0).max() <= 0:
        problems.append("the planimetric control points coincide")
    if len(height) < 3:
        problems.append(f"{len(height)} height control point(s); at least three not on one "
                        "line are needed to fix the tilt of the block")
    elif len(height_xy) >= 3:  # on one line? (only those with X and Y can be placed)
        with np.errstate(over="ignore", invalid="ignore"):
            p = height_xy - height_xy.mean(axis=0)
        s = np.linalg.svd(p, compute_uv=False) if np.isfinite(p).all() else np.ones(2)
        if s[-1] <= 1e-6 * max(s[0], 1e-9):
            problems.append("the height control points lie on one line: the block can tilt "
                            "about it")
    if problems:
        unused = np.flatnonzero(block.points.controlled.any(axis=1) & ~keep)
        left = (f" ({len(unused)} control point(s) are measured on fewer than two photos "
                "and were left out)") if len(unused) else ""
        raise GeometryError("datum defect: the control does not fix the block: "
                            + "; ".join(problems) + left + ". Add control points (with "
                            "sigma_X, sigma_Y, sigma_Z in ground_points.csv), or adjust the "
                            "block as a free network (baarda adjust --free, or datum = "
                            "\"free\" in project.toml).")
    return weak_control(block, xyz[plan, :2], height_xy)


WEAK_WIDTH = 0.25  # control narrower than this share of the block is weak


def weak_control(block: Block, plan_xy: np.ndarray, height_xy: np.ndarray) -> list[str]:
    """Warnings when the control covers the block badly: planimetric control spanning a
    small part of the block (scale and azimuth extrapolated), height control on a line or
    along one edge (the block tilts about it)."""
    centres = block.photos.eo[:, :2]
    centres = centres[np.isfinite(centres).all(axis=1)]
    if len(centres) < 2:
        return []
    out = []
    with np.errstate(over="ignore", invalid="ignore"):
        mid = centres.mean(axis=0)
        finite = all(np.isfinite(a - mid).all() for a in (centres, plan_xy, height_xy))
    if not finite:
        return []  # coordinates beyond any map: diagnose says so
    axes = np.linalg.svd(centres - mid, full_matrices=False)[2]  # block's main directions
    extent = np.ptp((centres - mid) @ axes.T, axis=0)
    for what, xy, k in (("planimetric", plan_xy, 0), ("height", height_xy, 1)):
        if extent[k] <= 0 or len(xy) == 0:
            continue
        span = np.ptp((xy - mid) @ axes.T, axis=0)
        share = span[k] / extent[k]
        if share < WEAK_WIDTH:
            direction = "length" if k == 0 else "width"
            out.append(f"weak control: the {what} control spans {share:.0%} of the block's "
                       f"{direction} ({figure(span[k])} m of {figure(extent[k])} m between the "
                       "outer projection centres); " + (
                           "scale and azimuth are extrapolated" if k == 0 else
                           "the block can tilt about it and heights far from it are weakly "
                           "determined") + ": add control on the other side")
    return out


def predicted_observations(block: Block, eo: np.ndarray | None = None,
                           xyz: np.ndarray | None = None) -> np.ndarray:
    """What each image observation is compared with (m, 2) in mm: the projection of the
    point with its camera's model (for backward models minus the correction of the
    observation, bundle/collinearity.py camera_projection), so observed - predicted is the
    misclosure.  eo (n_photos, 6) and xyz (n_points, 3) default to the block's."""
    eo = block.photos.eo if eo is None else eo
    xyz = block.points.xyz if xyz is None else xyz
    im = block.image
    out = np.full((len(im), 2), np.nan)
    cam = block.photos.camera[im.photo]
    for i in np.unique(cam):
        rows = np.flatnonzero(cam == i)
        out[rows] = camera_projection(eo, xyz[im.point[rows]], im.photo[rows],
                                      parameters(block.cameras, i),
                                      model_of(kinds(block.cameras)[i]),
                                      constants(block.cameras, i), im.xy_mm[rows])[0]
    return out


def intersect(block: Block, eo: np.ndarray, points: np.ndarray,
              ideal: np.ndarray | None = None) -> np.ndarray:
    """Least-squares intersection of the rays of `points` (indices) from photos `eo`.

    Minimises the squared distances of the point to all its rays; returns (len(points), 3)
    with NaN where fewer than two rays exist.  ideal: the block's
    ideal_image_coordinates, when known.
    """
    im = block.image
    sel = np.flatnonzero(np.isin(im.point, points))  # the rays of these points only
    photo, point = im.photo[sel], im.point[sel]
    cam = block.photos.camera[photo]
    c = block.cameras.focal_mm[cam]
    pp = block.cameras.principal_point_mm[cam]
    if ideal is None:
        ideal = ideal_image_coordinates(block)
    # an orientation or image coordinate that is not finite (an absurd input) makes its
    # rays NaN: their points are left out below, without a warning for each
    with np.errstate(all="ignore"):
        r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])[photo]
        dirs_cam = np.column_stack([ideal[sel] - pp, -c])
        dirs = np.einsum("mij,mj->mi", r, dirs_cam)
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        proj = np.eye(3)[None] - dirs[:, :, None] * dirs[:, None, :]
        pc = np.einsum("mij,mj->mi", proj, eo[photo, :3])
    n = len(block.points)
    a = np.stack([np.bincount(point, proj[:, i, j], n) for i in range(3) for j in range(3)],
                 axis=1).reshape(n, 3, 3)[points]
    b = np.stack([np.bincount(point, pc[:, i], n) for i in range(3)], axis=1)[points]
    out = np.full((len(points), 3), np.nan)
    good = np.isfinite(a).all(axis=(1, 2)) & np.isfinite(b).all(axis=1)  # not from inf/NaN
    with np.errstate(all="ignore"):
        lam = np.linalg.eigvalsh(a[good])  # a is a sum of projectors: symmetric, semi-definite
        good[good] = lam[:, 0] > 1e-10 * lam[:, 2]
    out[good] = np.linalg.solve(a[good], b[good][:, :, None])[:, :, 0]
    return out


def intersected_points(block: Block, ideal: np.ndarray | None = None) -> np.ndarray:
    """(n_points, 3): every usable point intersected from the block's approximate
    orientations (NaN for the rest and where the rays do not determine it), for
    approximate_points and the diagnosis (bundle/diagnostics.py) at once; a point's
    intersection depends on its own rays only.  ideal: as for intersect."""
    out = np.full((len(block.points), 3), np.nan)
    idx = np.flatnonzero(usable_points(block)[0])
    with np.errstate(all="ignore"):  # absurd inputs: the diagnosis names them
        out[idx] = intersect(block, block.photos.eo, idx, ideal)
    return out


def approximate_points(block: Block, keep: np.ndarray,
                       intersected: np.ndarray | None = None) -> np.ndarray:
    """Approximate coordinates: control as given, the rest by intersection (taken from
    `intersected`, intersected_points of this block, when given)."""
    xyz = block.points.xyz.copy()
    need = keep & ~np.isfinite(xyz).all(axis=1) | (block.points.role == "check") & keep
    idx = np.flatnonzero(need)
    if len(idx):
        xi = intersect(block, block.photos.eo, idx) if intersected is None else \
            intersected[idx]
        own = np.isfinite(block.points.xyz[idx]) & (block.points.role[idx] == "control")[:, None]
        xyz[idx] = np.where(own, block.points.xyz[idx], xi)
        lost = idx[~np.isfinite(xyz[idx]).all(axis=1)]
        if len(lost):
            names = ", ".join(block.points.ids[j] for j in lost[:10])
            raise GeometryError(f"{len(lost)} point(s) cannot be intersected from the "
                                f"approximate orientations (parallel rays): {names}")
    return xyz
