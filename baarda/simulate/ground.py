"""The geometry of a simulated aerial block: the photos' positions, the grid of ground points
(with terrain relief), which photo measures which point, and the control layout of the plan
(see FlightPlan).  `ground_layout` gives the points a block measures without simulating it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

if TYPE_CHECKING:
    from baarda.simulate.aerial import FlightPlan


def _terrain(x: np.ndarray, y: np.ndarray, amplitude: float, size: float) -> np.ndarray:
    if amplitude == 0:
        return np.zeros_like(x)
    k = 2 * np.pi / max(size, 1.0)
    return amplitude * (0.5 * np.sin(1.3 * k * x + 0.4) * np.cos(0.9 * k * y)
                        + 0.3 * np.sin(2.1 * k * y + 1.1) + 0.2 * np.cos(2.7 * k * (x + y)))


@dataclass(frozen=True)
class GroundLayout:
    """The ground points of a simulated block: ids, true coordinates (n, 3), roles (tie |
    control) and a-priori sigmas of the control coordinates (n, 3; NaN: not given)."""

    ids: list[str]
    xyz: np.ndarray
    role: np.ndarray
    sigma: np.ndarray


def ground_layout(plan: FlightPlan) -> GroundLayout:
    """The points simulate_block(plan) measures, with the control layout of the plan: no
    photos, observations, noise, check points or blunders (the layout of a large block in a
    fraction of the time)."""
    g = block_geometry(plan)
    kept = np.flatnonzero(_kept(g.seen, plan, len(g.ids)))
    return GroundLayout([g.ids[j] for j in kept], g.xyz[kept], g.role[kept], g.sigma[kept])


@dataclass(frozen=True)
class BlockGeometry:
    """The photo positions and the ground points of a plan, each point with the photos that
    see it (before dropping those seen by fewer than two)."""

    X0: np.ndarray
    Y0: np.ndarray
    s_idx: np.ndarray  # strip of each photo
    p_idx: np.ndarray  # photo in its strip
    flying_height: float  # Z0 of the photos
    ids: list[str]
    xyz: np.ndarray
    role: np.ndarray
    sigma: np.ndarray
    on_border: np.ndarray  # the first and last rows and columns (grid points only)
    seen: list[np.ndarray]  # the points inside the pattern window of each photo


def block_geometry(plan: FlightPlan) -> BlockGeometry:
    """The photos' positions, the grid of ground points and the control layout."""
    n = plan.pattern
    if n < 2:
        raise ValueError("pattern must be at least 2 (2x2 points per photo)")
    side = plan.format_mm * 1e-3 * plan.image_scale  # ground side of a photo
    base = (1 - plan.forward_overlap) * side
    dist = (1 - plan.side_overlap) * side
    height = plan.focal_mm * 1e-3 * plan.image_scale
    ex = base if base <= 0.45 * side else base / 2
    ey = dist if dist <= 0.45 * side else dist / 2
    dx, dy = 2 * ex / (n - 1), 2 * ey / (n - 1)

    # photo positions
    s_idx, p_idx = np.meshgrid(np.arange(plan.strips), np.arange(plan.photos_per_strip),
                               indexing="ij")
    s_idx, p_idx = s_idx.ravel(), p_idx.ravel()
    X0 = p_idx * base
    Y0 = s_idx * dist

    # ground grid covering every pattern window
    gx = np.arange(np.floor(-ex / dx), np.ceil((X0.max() + ex) / dx) + 1) * dx
    gy = np.arange(np.floor(-ey / dy), np.ceil((Y0.max() + ey) / dy) + 1) * dy
    GX, GY = np.meshgrid(gx, gy, indexing="xy")
    gxy = np.column_stack([GX.ravel(), GY.ravel()])
    cols = np.rint(gxy[:, 0] / dx).astype(int)
    rows = np.rint(gxy[:, 1] / dy).astype(int)
    if plan.neat_area:
        inside = ((gxy[:, 0] > -1e-6) & (gxy[:, 0] < X0.max() + 1e-6) &
                  (gxy[:, 1] > -1e-6) & (gxy[:, 1] < Y0.max() + 1e-6))
        gxy, cols, rows = gxy[inside], cols[inside], rows[inside]
    ids = [f"{r:03d}{c:03d}" for r, c in zip((rows - rows.min() + 1).tolist(),
                                             (cols - cols.min() + 1).tolist(), strict=True)]
    size = max(X0.max(), Y0.max(), side)
    Z = _terrain(gxy[:, 0], gxy[:, 1], plan.relief_m, size)
    xyz = np.column_stack([gxy, Z])
    role = np.full(len(ids), "tie", dtype=object)
    sigma = np.full((len(ids), 3), np.nan)

    # control layout on the grid.  The outermost rows and columns of the grid can lie outside
    # every pattern window (always with an even pattern, whose nodes straddle the window
    # edges; with an odd one where floor and ceil round a ratio such as -7.000000000000001 to
    # -8): they are never measured and are dropped below, and control placed on them would be
    # lost with them.  So the borders are the outermost nodes inside the windows, and the
    # control is counted in steps of bases from the grid line at the window edge (odd
    # pattern: the border itself; even pattern: half a node spacing outside it)
    window = (ex + 0.2 * dx, ey + 0.2 * dy)  # half sides of the area a photo measures
    tol = 1e-6 * min(dx, dy)
    in_windows = ((xyz[:, 0] >= -ex - tol) & (xyz[:, 0] <= X0.max() + ex + tol) &
                  (xyz[:, 1] >= -ey - tol) & (xyz[:, 1] <= Y0.max() + ey + tol))
    ext = (xyz[in_windows, 0].min(), xyz[in_windows, 0].max(),
           xyz[in_windows, 1].min(), xyz[in_windows, 1].max())
    x0 = xyz[xyz[:, 0] >= -ex - dx / 2 - tol, 0].min()
    y0 = xyz[xyz[:, 1] >= -ey - dy / 2 - tol, 1].min()
    on_border = (np.isclose(xyz[:, 0], ext[0]) | np.isclose(xyz[:, 0], ext[1]) |
                  np.isclose(xyz[:, 1], ext[2]) | np.isclose(xyz[:, 1], ext[3]))
    seen = _seen(xyz, X0, Y0, window)  # which photo measures which node
    measured = _kept(seen, plan, len(ids))  # the nodes kept below
    kept = np.flatnonzero(measured)
    # the corner photos (first and last of the first and last strip) and their grid corners
    last, n_ph = plan.photos_per_strip - 1, len(X0)
    corners = [(0, ext[0], ext[2]), (last, ext[1], ext[2]),
               (n_ph - 1 - last, ext[0], ext[3]), (n_ph - 1, ext[1], ext[3])]
    full = np.zeros(len(ids), bool)
    if plan.control == "perimeter":
        step = plan.control_spacing * base
        kx = np.rint((xyz[:, 0] - x0) / step)
        ky = np.rint((xyz[:, 1] - y0) / step)
        on_x = np.isclose(xyz[:, 0] - x0, kx * step, atol=dx / 2 + 1e-6)
        on_y = np.isclose(xyz[:, 1] - y0, ky * step, atol=dy / 2 + 1e-6)
        # a node every step along the first and last rows and columns
        full = on_border & ((on_x & np.isin(np.rint(xyz[:, 1]), np.rint([ext[2], ext[3]]))) |
                            (on_y & np.isin(np.rint(xyz[:, 0]), np.rint([ext[0], ext[1]]))))
        # a corner photo that measures none of these (a block of few photos, 50 % forward
        # overlap, a spacing longer than the block) gets the measured node nearest its corner
        controlled = full & measured
        for photo, cx, cy in corners if kept.size else ():
            if not controlled[seen[photo]].any():
                full[_nearest(xyz, kept, cx, cy)] = True
    elif plan.control == "corners":
        # the measured node nearest each corner (the corner node is seen by one photo only)
        for _photo, cx, cy in corners if kept.size else ():
            full[_nearest(xyz, kept, cx, cy)] = True
    elif plan.control != "none":
        raise ValueError(f"unknown control layout '{plan.control}'")
    role[full] = "control"
    sigma[full] = plan.sigma_control_m
    if plan.height_chains > 0:  # a column of height points, those not full control already
        step = plan.height_chains * base
        k = np.rint((xyz[:, 0] - x0) / step)
        chain = np.isclose(xyz[:, 0] - x0, k * step, atol=dx / 2 + 1e-6) & ~full
        role[chain] = "control"
        sigma[chain, 2] = plan.sigma_control_m[2]

    if plan.twin_control:
        ctrl = np.flatnonzero(role == "control")
        offset = np.array([0.1 * dx, 0.1 * dy, 0.0])
        twin_xyz = xyz[ctrl] + offset
        twin_xyz[:, 2] = _terrain(twin_xyz[:, 0], twin_xyz[:, 1], plan.relief_m, size)
        xyz = np.vstack([xyz, twin_xyz])
        ids += [ids[j] + "T" for j in ctrl]
        role = np.concatenate([role, role[ctrl]])
        sigma = np.vstack([sigma, sigma[ctrl]])
        seen = _seen(xyz, X0, Y0, window)  # with the twins
    return BlockGeometry(X0, Y0, s_idx, p_idx, height + np.mean(Z), ids, xyz, role, sigma,
                         on_border, seen)


def _seen(xyz: np.ndarray, X0: np.ndarray, Y0: np.ndarray,
          window: tuple[float, float]) -> list[np.ndarray]:
    """The points (sorted indices) inside the pattern window around each photo's nadir: a k-d
    tree in coordinates scaled by the window, Chebyshev distance <= 1 (no photos x points
    matrix)."""
    wx, wy = window
    tree = cKDTree(np.column_stack([xyz[:, 0] / wx, xyz[:, 1] / wy]))
    return [np.sort(np.asarray(ix, dtype=np.int64)) for ix in
            tree.query_ball_point(np.column_stack([X0 / wx, Y0 / wy]), r=1.0, p=np.inf)]


def _kept(seen: list[np.ndarray], plan: FlightPlan, n_points: int) -> np.ndarray:
    """The points simulate_block keeps: seen by two photos (stereo: by both photos of a
    model)."""
    if not plan.stereo:
        return np.bincount(np.concatenate(seen), minlength=n_points) >= 2
    kept = np.zeros(n_points, bool)
    for st in range(plan.strips):
        for j in range(plan.photos_per_strip - 1):
            a = st * plan.photos_per_strip + j
            kept[np.intersect1d(seen[a], seen[a + 1])] = True
    return kept


def _nearest(xyz: np.ndarray, candidates: np.ndarray, x: float, y: float) -> int:
    """The candidate point nearest (x, y) in plan (the first of equals)."""
    return int(candidates[np.argmin(np.hypot(xyz[candidates, 0] - x, xyz[candidates, 1] - y))])

