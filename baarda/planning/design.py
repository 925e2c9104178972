"""Design-stage blocks: exact observations from a flight plan or from a project's geometry.

Reliability (redundancy numbers, MDB, external reliability) depends only on the design
matrix: which photo sees which point, the geometry and the weights.  A design block carries
error-free observations (image coordinates projected from the geometry, control equal to the
coordinates), so its adjustment converges at once and its residuals are zero; the measured
values of a project are never used.

Control layouts on a grid of positions (Gruen 1980, Figure 1, reconstructed): full (XYZ)
control on the perimeter of the area of four-fold coverage every `spacing` base lengths,
height control at the interior positions of the same grid; optionally each control point
with a twin close to it ("twin control").
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from baarda.block.photo_block import Block, GroundPoints, ImagePoints, Photos
from baarda.bundle.collinearity import project
from baarda.bundle.geometry import intersect
from baarda.errors import GeometryError
from baarda.simulate.aerial import FlightPlan, simulate_block

CONTROL_SIGMA_RATIO = 1e-4  # "error-free" control: sigma = ratio * image sigma on the ground


@dataclass
class ControlLayout:
    """Control on a grid of positions over the area between the outer nadir lines.

    spacing: bridging distance i along the strips in base lengths (positions 0, i, 2i, ...
    and the last nadir); spacing_y: across the strips in strip distances (default: the same
    number).  Positions snap to the nearest ground point of the plan's pattern.
    interior: 'height' (Gruen), 'full' or 'none' for the grid positions inside the perimeter.
    twin: each control point gets a companion at `twin_offset` (fraction of the point
    spacing) measured on the same photos and models.  sigma_m: None = error-free control
    (CONTROL_SIGMA_RATIO of the image sigma on the ground), else (sX, sY, sZ) in m.
    """

    spacing: float = 2.0
    spacing_y: float | None = None
    interior: str = "height"
    twin: bool = False
    twin_offset: float = 0.03
    sigma_m: tuple[float, float, float] | None = None
    centre: bool = True  # a grid without interior positions gets a height point at the centre


def _grid_positions(length: float, spacing: float) -> np.ndarray:
    """0, spacing, 2 spacing, ... and `length` (all in units of the grid)."""
    if spacing <= 0:
        raise ValueError("control spacing must be positive")
    pos = np.arange(0.0, length + 1e-9, spacing)
    if length - pos[-1] > 1e-9:
        pos = np.append(pos, length)
    return pos


def point_spacing(plan: FlightPlan) -> np.ndarray:
    """Distance (m) of neighbouring ground points along and across the strips."""
    side = plan.format_mm * 1e-3 * plan.image_scale
    out = []
    for overlap in (plan.forward_overlap, plan.side_overlap):
        step = (1 - overlap) * side
        half = step if step <= 0.45 * side else step / 2  # as baarda.simulate.aerial
        out.append(2 * half / (plan.pattern - 1))
    return np.array(out)


def vertical_geometry(plan: FlightPlan) -> tuple[Block, np.ndarray, np.ndarray]:
    """The plan's block with vertical photos and exact image coordinates.

    Returns (block without control, true EO (n, 6), true XYZ (k, 3)).  Flat terrain unless
    plan.relief_m; omega = phi = 0 and kappa = 0 (or pi for alternate strips).
    """
    plan = replace(plan, control="none", height_chains=0, twin_control=False, check_points=0,
                   noise=False, eo_error=(0.0, 0.0), blunders=0)
    block, truth = simulate_block(plan)
    eo = np.array([[truth["photos"][p][k] for k in ("X0", "Y0", "Z0", "omega", "phi", "kappa")]
                   for p in block.photos.ids])
    eo[:, 3:5] = 0.0
    eo[:, 5] = np.round(eo[:, 5] / np.pi) * np.pi
    xyz = np.array([truth["points"][p] for p in block.points.ids])
    return block, eo, xyz


def exact_observations(block: Block, eo: np.ndarray, xyz: np.ndarray) -> Block:
    """A copy of `block` whose image coordinates are projected from eo and xyz, whose
    approximate EO is `eo` and whose control (and check) coordinates equal xyz."""
    im = block.image
    cam = block.photos.camera[im.photo]
    xy = project(eo[im.photo], xyz[im.point], block.cameras.focal_mm[cam],
                 block.cameras.principal_point_mm[cam])
    image = replace(im, xy_mm=xy)
    pts = block.points
    given = np.where((pts.role == "tie")[:, None], np.nan, xyz)
    points = GroundPoints(list(pts.ids), given, pts.sigma.copy(), pts.role.copy())
    photos = Photos(list(block.photos.ids), block.photos.camera.copy(),
                    block.photos.strip.copy(), eo.copy())
    return replace(block, photos=photos, image=image, points=points, source="design",
                   notes=list(block.notes))


def apply_control(block: Block, eo: np.ndarray, xyz: np.ndarray, plan: FlightPlan,
                  layout: ControlLayout) -> tuple[Block, np.ndarray]:
    """Control roles and sigmas by `layout` (and twin points); returns (block, xyz)."""
    side = plan.format_mm * 1e-3 * plan.image_scale
    base = (1 - plan.forward_overlap) * side
    dist = (1 - plan.side_overlap) * side
    n = len(block.points)
    x0, y0 = eo[:, 0].min(), eo[:, 1].min()
    lx = (eo[:, 0].max() - x0) / base
    ly = (eo[:, 1].max() - y0) / dist
    sy = layout.spacing if layout.spacing_y is None else layout.spacing_y
    gx, gy = _grid_positions(lx, layout.spacing), _grid_positions(ly, sy)
    role = np.full(n, "tie", dtype=object)
    sigma = np.full((n, 3), np.nan)
    if layout.sigma_m is None:
        s = CONTROL_SIGMA_RATIO * float(np.median(block.image.sigma_mm)) * 1e-3 * plan.image_scale
        sig = (s, s, s)
    else:
        sig = tuple(layout.sigma_m)
    rays = block.rays()
    cand = np.flatnonzero(rays >= 2)
    if not len(cand):
        raise GeometryError(f"no point of the planned block is measured on two photos "
                            f"({plan.forward_overlap:.0%} forward and {plan.side_overlap:.0%} "
                            "side overlap): raise the overlaps")
    chosen: dict[int, str] = {}
    sites = [(px, py, "full" if i in (0, len(gx) - 1) or j in (0, len(gy) - 1)
              else layout.interior) for i, px in enumerate(gx) for j, py in enumerate(gy)]
    if layout.centre and layout.interior != "none" and (len(gx) < 3 or len(gy) < 3):
        sites.append((lx / 2, ly / 2, layout.interior))  # Gruen's Figure 9, i = L
    for px, py, kind in sites:
        if kind == "none":
            continue
        target = np.array([x0 + px * base, y0 + py * dist])
        k = int(cand[np.argmin(np.linalg.norm(xyz[cand, :2] - target, axis=1))])
        if kind == "full" or k not in chosen:
            chosen[k] = kind
    for k, kind in chosen.items():
        role[k] = "control"
        if kind == "full":
            sigma[k] = sig
        elif kind == "height":
            sigma[k, 2] = sig[2]
        else:
            raise ValueError(f"unknown interior control '{layout.interior}'")
    pts = GroundPoints(list(block.points.ids), xyz.copy(), sigma, role)
    block = replace(block, points=pts)
    if layout.twin:
        block, xyz = add_twins(block, xyz, np.array(sorted(chosen)),
                               layout.twin_offset * point_spacing(plan))
    return exact_observations(block, eo, xyz), xyz


def add_twins(block: Block, xyz: np.ndarray, points: np.ndarray,
              offset_m: np.ndarray) -> tuple[Block, np.ndarray]:
    """Give each of `points` a twin at `offset_m` (dX, dY) measured on the same image rows."""
    im, pts = block.image, block.points
    n = len(pts)
    new_xyz = xyz[points] + np.array([offset_m[0], offset_m[1], 0.0])
    twin_index = np.full(n, -1)
    twin_index[points] = n + np.arange(len(points))
    rows = np.flatnonzero(twin_index[im.point] >= 0)
    image = ImagePoints(np.concatenate([im.photo, im.photo[rows]]),
                        np.concatenate([im.point, twin_index[im.point[rows]]]),
                        np.vstack([im.xy_mm, im.xy_mm[rows]]),
                        np.concatenate([im.sigma_mm, im.sigma_mm[rows]]),
                        None if im.model is None else np.concatenate([im.model, im.model[rows]]),
                        None if im.sigma_xy_mm is None else
                        np.vstack([im.sigma_xy_mm, im.sigma_xy_mm[rows]]))
    points_new = GroundPoints(list(pts.ids) + [pts.ids[j] + "T" for j in points],
                              np.vstack([pts.xyz, new_xyz]),
                              np.vstack([pts.sigma, pts.sigma[points]]),
                              np.concatenate([pts.role, pts.role[points]]))
    return replace(block, image=image, points=points_new), np.vstack([xyz, new_xyz])


def design_block(plan: FlightPlan, layout: ControlLayout | None = None) -> Block:
    """An error-free block for the flight plan with the given control layout."""
    block, eo, xyz = vertical_geometry(plan)
    block, _ = apply_control(block, eo, xyz, plan, layout or ControlLayout())
    block.settings.name = plan.name
    return block


def design_from_project(block: Block, start: tuple[np.ndarray, np.ndarray] | None = None
                        ) -> Block:
    """A design block with the geometry of a project: its measurements are not used.

    The geometry is the approximate EO of the project and its control coordinates; tie
    points are intersected from the approximate EO (their rays only give the direction),
    or `start` = (eo (n, 6), xyz (k, 3)) from an earlier adjustment.  The observations are
    then replaced by exact projections, so only the design (which photo sees which point,
    stereo models, weights) enters the statistics.
    """
    if start is not None:
        eo, xyz = start
    else:
        eo = block.photos.eo
        xyz = block.points.xyz.copy()
        need = ~np.isfinite(xyz).all(axis=1)
        if need.any():
            xi = intersect(block, eo, np.flatnonzero(need))
            xyz[need] = np.where(np.isfinite(xyz[need]), xyz[need], xi)
        lost = ~np.isfinite(xyz).all(axis=1) & (block.rays() >= 2)
        if lost.any():
            names = ", ".join(block.points.ids[j] for j in np.flatnonzero(lost)[:10])
            raise GeometryError(f"{int(lost.sum())} point(s) cannot be placed from the "
                                f"approximate orientations: {names}")
        xyz = np.where(np.isfinite(xyz), xyz, 0.0)
    return exact_observations(block, np.asarray(eo, float), np.asarray(xyz, float))
