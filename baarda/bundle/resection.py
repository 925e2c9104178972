"""Approximate exterior orientations by space resection, for inputs that give none.

`resect` orients one photo from points with known object coordinates: a direct solution
(DLT for six or more points in general position, a plane homography for four or more
points near a plane, a vertical-photo similarity otherwise) refined by Gauss-Newton on the
collinearity equations.  `orient_block` orients every photo of a block: photos that see
enough control first, then, alternately, intersection of tie points and resection of the
photos still missing.
"""

from __future__ import annotations

import numpy as np

from baarda.adjustment.dense import DenseLeastSquares
from baarda.adjustment.solve import solve
from baarda.block.camera import ideal_image_coordinates
from baarda.block.photo_block import Block
from baarda.block.rotation import angles_from_matrix
from baarda.bundle.collinearity import camera_depth, project_with_jacobians
from baarda.errors import GeometryError
from baarda.options import SolveOptions

FLIP = np.diag([1.0, 1.0, -1.0])
# unweighted least squares, column-scaled; done when an accepted step lowers the sum of
# squares by less than 1e-14 (relative) or no step (down to 1e-6) lowers it
REFINE = SolveOptions(max_iterations=50, tolerance=0.0, flat_cost=1e-14, min_step=1e-6,
                      cost_rtol=0.0)


def _orthogonal(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m)
    return u @ vt


def _from_m(m: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """EO (6,) from M = diag(1, 1, -1) R^T (det -1) and the projection centre."""
    r = (FLIP @ _orthogonal(m)).T
    if np.linalg.det(r) < 0:  # reflection left by a bad direct solution
        r = -r
    return np.concatenate([x0, angles_from_matrix(r)])


def _dlt(n: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """Direct linear transformation: normalised image coords n (k, 2) of points xyz (k, 3)."""
    o = xyz.mean(axis=0)
    s = np.sqrt(np.mean(np.sum((xyz - o) ** 2, axis=1))) or 1.0
    p = (xyz - o) / s
    rows = []
    for (a, b), q in zip(n, p, strict=True):
        h = np.concatenate([q, [1.0]])
        rows.append(np.concatenate([h, np.zeros(4), -a * h]))
        rows.append(np.concatenate([np.zeros(4), h, -b * h]))
    _, _, vt = np.linalg.svd(np.asarray(rows))
    pm = vt[-1].reshape(3, 4)
    m, t = pm[:, :3], pm[:, 3]
    lam = np.cbrt(np.linalg.det(m))  # M has det -1 up to the unknown scale
    m, t = -m / lam, -t / lam
    x0 = -np.linalg.solve(m, t)  # in normalised object coordinates
    return _from_m(m, o + s * x0)


def _homography(n: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """Plane homography from the best-fit plane of the points to normalised image coords."""
    o = xyz.mean(axis=0)
    _, _, vt = np.linalg.svd(xyz - o)
    e1, e2 = vt[0], vt[1]
    e3 = np.cross(e1, e2)
    ab = np.column_stack([(xyz - o) @ e1, (xyz - o) @ e2])
    s = np.sqrt(np.mean(np.sum(ab**2, axis=1))) or 1.0
    ab = ab / s
    rows = []
    for (a, b), (pa, pb) in zip(n, ab, strict=True):
        h = np.array([pa, pb, 1.0])
        rows.append(np.concatenate([h, np.zeros(3), -a * h]))
        rows.append(np.concatenate([np.zeros(3), h, -b * h]))
    _, _, vt = np.linalg.svd(np.asarray(rows))
    hm = vt[-1].reshape(3, 3)
    if np.mean(hm[2] @ np.column_stack([ab, np.ones(len(ab))]).T) < 0:
        hm = -hm
    lam = np.sqrt(np.linalg.norm(hm[:, 0]) * np.linalg.norm(hm[:, 1]))
    m1, m2 = hm[:, 0] / lam, hm[:, 1] / lam
    m3 = -np.cross(m1, m2)
    basis = np.column_stack([e1, e2, e3])
    m = _orthogonal(np.column_stack([m1, m2, m3])) @ basis.T
    x0 = o - s * (m.T @ (hm[:, 2] / lam))
    return _from_m(m, x0)


def _vertical(xy: np.ndarray, xyz: np.ndarray, c: float) -> np.ndarray:
    """Vertical photo: 2D similarity from image to ground gives kappa, scale and position."""
    a = xy - xy.mean(axis=0)
    b = xyz[:, :2] - xyz[:, :2].mean(axis=0)
    za = a[:, 0] + 1j * a[:, 1]
    zb = b[:, 0] + 1j * b[:, 1]
    k = np.vdot(za, zb) / max(np.vdot(za, za).real, 1e-300)  # zb ~ k za
    scale = abs(k)
    centre = xyz[:, :2].mean(axis=0) - np.array([(k * complex(*xy.mean(axis=0))).real,
                                                 (k * complex(*xy.mean(axis=0))).imag])
    z0 = xyz[:, 2].mean() + c * scale
    return np.array([centre[0], centre[1], z0, 0.0, 0.0, np.angle(k)])


def _refine(eo: np.ndarray, xy: np.ndarray, xyz: np.ndarray, c: float) -> tuple[np.ndarray, float]:
    """Least-squares refinement of a direct solution; (EO, RMS image residual [mm]), the RMS
    infinite when the points do not end in front of the camera."""
    m = len(xy)
    focal, pp = np.full(m, c), np.zeros((m, 2))

    def func(e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        proj, je, _ = project_with_jacobians(np.tile(e, (m, 1)), xyz, focal, pp)
        return proj.ravel(), je.reshape(2 * m, 6)

    def in_front(e: np.ndarray) -> bool:
        return bool(np.all(camera_depth(np.tile(e, (m, 1)), xyz) > 0))

    problem = DenseLeastSquares(func, xy.ravel(), np.ones(2 * m), method="lstsq",
                                admissible=in_front, what="space resection")
    sol = solve(problem, np.asarray(eo, float), REFINE)
    rms = np.sqrt(sol.cost / max(m, 1)) if in_front(sol.state) else np.inf
    return sol.state, float(rms)


def resect(xy: np.ndarray, xyz: np.ndarray, c: float) -> tuple[np.ndarray, float]:
    """EO (6,) of a photo from ideal image coords xy (k, 2) relative to pp [mm] of xyz (k, 3).

    Returns the orientation and the RMS image residual [mm].  Tries every applicable
    direct solution and keeps the one that refines to the smallest residual.
    """
    xy, xyz = np.asarray(xy, float), np.asarray(xyz, float)
    k = len(xy)
    if k < 3:
        raise GeometryError(f"space resection needs at least 3 points, got {k}")
    n = xy / c
    if not (np.isfinite(n).all() and np.isfinite(xyz).all()):
        raise GeometryError("space resection: image or object coordinates are not finite")
    methods = []
    with np.errstate(all="ignore"):
        sv = np.linalg.svd(xyz - xyz.mean(axis=0), compute_uv=False)
    if k >= 6 and sv[2] > 1e-3 * sv[0]:
        methods.append(lambda: _dlt(n, xyz))
    if k >= 4:
        methods.append(lambda: _homography(n, xyz))
    methods.append(lambda: _vertical(xy, xyz, c))
    best = None
    for method in methods:
        try:  # absurd numbers (a coordinate of 1e300) overflow a direct solution
            with np.errstate(all="ignore"):
                eo = method()
        except np.linalg.LinAlgError:
            continue
        if not np.all(np.isfinite(eo)):
            continue
        try:
            e, rms = _refine(eo, xy, xyz, c)
        except GeometryError:  # the start projects to infinity
            continue
        if np.isfinite(rms) and (best is None or rms < best[1]):
            best = (e, rms)
    if best is None:
        raise GeometryError("space resection failed: no direct solution puts the points in "
                            "front of the camera")
    return best


def orient_block(block: Block, min_points: int = 4, max_rms_mm: float | None = None) -> \
        np.ndarray:
    """Approximate EO (n_photos, 6) of every photo from the control points of `block`.

    Photos are resected from control points (and check points) with given coordinates,
    then tie points seen by two oriented photos are intersected and the remaining photos
    resected from them, until every photo is oriented.
    """
    from baarda.bundle.geometry import intersect

    im, pts = block.image, block.points
    cam = block.photos.camera
    xy_all = ideal_image_coordinates(block) - block.cameras.principal_point_mm[cam[im.photo]]
    known = np.isfinite(pts.xyz).all(axis=1) & (pts.role != "tie")
    xyz = np.where(known[:, None], pts.xyz, np.nan)
    eo = np.full((len(block.photos), 6), np.nan)
    for _ in range(len(block.photos) + 1):
        todo = np.flatnonzero(~np.isfinite(eo).all(axis=1))
        if not len(todo):
            return eo
        progress = False
        for i in todo:
            rows = np.flatnonzero((im.photo == i) & np.isfinite(xyz[im.point]).all(axis=1))
            if len(rows) < min_points:
                continue
            e, rms = resect(xy_all[rows], xyz[im.point[rows]],
                            float(block.cameras.focal_mm[cam[i]]))
            if max_rms_mm is not None and rms > max_rms_mm:
                continue
            eo[i] = e
            progress = True
        done = np.isfinite(eo).all(axis=1)
        seen = np.bincount(im.point[done[im.photo]], minlength=len(pts))
        new = np.flatnonzero((seen >= 2) & ~np.isfinite(xyz).all(axis=1))
        if len(new):
            sub = block.select_image(done[im.photo])
            xi = intersect(sub, np.where(np.isfinite(eo), eo, 0.0), new)
            xyz[new] = xi
            progress = progress or bool(np.isfinite(xi).any())
        if not progress:
            break
    missing = [block.photos.ids[i] for i in np.flatnonzero(~np.isfinite(eo).all(axis=1))]
    raise GeometryError(f"no approximate orientation for {len(missing)} photo(s) "
                        f"({', '.join(missing[:10])}): they see fewer than {min_points} points "
                        "with known coordinates")
