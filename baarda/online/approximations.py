"""Approximations for what enters the growing bundle block (online/bundle.py): the block
prepared for its first adjustment, the photos and points that determine each other, a new
point intersected from its rays, and the new photos and points refined alone with the
block held (a good linearisation point for the low-rank update)."""

from __future__ import annotations

import numpy as np

from baarda.adjustment.dense import DenseLeastSquares
from baarda.adjustment.solve import solve
from baarda.block.camera import ideal_image_coordinates
from baarda.block.photo_block import Block
from baarda.block.rotation import rotation_matrix
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.geometry import intersected_points
from baarda.bundle.resection import resect
from baarda.errors import GeometryError
from baarda.online.lowrank import UNDETERMINED
from baarda.online.measurements import MIN_PHOTO_POINTS, REMOVED, Measurements
from baarda.online.rows import image_rows
from baarda.options import SolveOptions

# the new unknowns alone, damped (weak directions stay near the approximations)
REFINE = SolveOptions(max_iterations=50, tolerance=1e-9, min_step=1e-6, damping=1e-3)
SPREAD = 0.1  # points on a photo spread less than this across their line: on one line
MISFIT = 10.0  # a resection's RMS above this many image sigmas: the points fit no orientation
FAR_POINT = 10.0  # an image point this many times farther out than the others: far outside


def prepared(block: Block) -> Block:
    """The block in the local frame of its CRS, with approximate orientations where they can
    be had by resection now (pipeline.localized, pipeline.with_approximations); photos that
    cannot keep none (they are resected from the block's points when they come in)."""
    from baarda.pipeline import localized, with_approximations

    block = localized(block)
    if np.isfinite(block.photos.eo).all() or not len(block.image):
        return block
    try:
        return with_approximations(block)
    except GeometryError:
        return block


def prune(m: Measurements, photos: set, points: set, photo_in=None, point_in=None
           ) -> tuple[set, set]:
    """The photos and points of the sets that determine each other and the block (photo_in,
    point_in: what is in it): points with two rays on those photos (or one and full
    control), not set aside waiting for their next ray; photos with MIN_PHOTO_POINTS of
    those points that are not on one line in the image."""
    photo_in = photo_in if photo_in is not None else [False] * len(m.photo_ids)
    point_in = point_in if point_in is not None else [False] * len(m.point_ids)
    photos, points = set(photos), set(points)
    changed = True
    while changed:
        changed = False
        for j in sorted(points):
            rays = [r for r in m.live_rays(j) if photo_in[m.im_photo[r]] or m.im_photo[r] in photos]
            if m.waiting(j) or not (len(rays) >= 2 or (rays and m.full_control(j))):
                points.discard(j)
                changed = True
        for i in sorted(photos):
            rows = [r for r in m.rows_of_photo[i] if m.im_status[r] != REMOVED
                    and (point_in[m.im_point[r]] or m.im_point[r] in points)]
            if not spread(np.array([m.im_xy[r] for r in rows]).reshape(-1, 2)):
                photos.discard(i)
                changed = True
    return photos, points


def spread(xy: np.ndarray) -> bool:
    """MIN_PHOTO_POINTS image points or more, not on one line (the second singular value of
    their spread at least SPREAD of the first)."""
    if len(xy) < MIN_PHOTO_POINTS:
        return False
    s = np.linalg.svd(xy - xy.mean(axis=0), compute_uv=False)
    return bool(s[1] >= SPREAD * s[0])


def intersect(m: Measurements, j: int, eo: np.ndarray, group: dict) -> np.ndarray:
    """A point from its rays (no lens model: a start for the refinement), or its
    control coordinates."""
    if m.full_control(j):
        return m.point_xyz[j].copy()
    rows = [r for r in group["image"] if m.im_point[r] == j]
    cams = [m.photo_cam[m.im_photo[r]] for r in rows]
    e = eo[[m.im_photo[r] for r in rows]]
    rot = rotation_matrix(e[:, 3], e[:, 4], e[:, 5])
    xy = np.array([m.im_xy[r] for r in rows]) - m.cameras.principal_point_mm[cams]
    d = np.einsum("mij,mj->mi", rot, np.column_stack([xy, -m.cameras.focal_mm[cams]]))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    proj = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    a = proj.sum(axis=0)
    b = np.einsum("mij,mj->i", proj, e[:, :3])
    return np.linalg.solve(a, b)


def refine(m: Measurements, problem: BundleProblem, g: np.ndarray, group: dict,
           eo: np.ndarray, xyz: np.ndarray) -> bool:
    """The group's new photos and points adjusted alone (everything else held at eo, xyz),
    in place: a good linearisation point for the low-rank update (the one solver on a
    small dense problem, Levenberg-Marquardt from the approximations); False when they are
    not determined (the undamped normal equations at the solution singular, scaled).
    problem: the block's factored bundle problem (its image rows); g: its global unknowns."""
    photos, points = group["photos"], group["points"]
    col = {("photo", i): 6 * n for n, i in enumerate(photos)}
    col.update({("point", j): 6 * len(photos) + 3 * n for n, j in enumerate(points)})
    nu = 6 * len(photos) + 3 * len(points)
    img = [r for r in group["image"]
           if ("photo", m.im_photo[r]) in col or ("point", m.im_point[r]) in col]
    if not img or not nu:
        return True
    cams = np.array([m.photo_cam[m.im_photo[r]] for r in img])
    sig = np.array([m.im_sigma[r] for r in img]).reshape(-1)
    xy = np.array([m.im_xy[r] for r in img])
    ph = np.array([m.im_photo[r] for r in img])
    pt = np.array([m.im_point[r] for r in img])
    pcol = np.array([col.get(("photo", i), -1) for i in ph])
    qcol = np.array([col.get(("point", j), -1) for j in pt])

    def unpack(y):
        e, x = eo.copy(), xyz.copy()
        for (what, u), c in col.items():
            if what == "photo":
                e[u] = y[c:c + 6]
            else:
                x[u] = y[c:c + 3]
        return e, x

    # control coordinates of the new points (a point with one ray and full control)
    ctrl = [(j, a) for j in group["control"] if ("point", j) in col
            for a in np.flatnonzero(np.isfinite(m.point_sigma[j]))]
    c_obs = np.array([m.point_xyz[j][a] for j, a in ctrl])
    c_sig = np.array([m.point_sigma[j][a] for j, a in ctrl])

    def func(y):
        e, x = unpack(y)
        mis, je, jp, _ = image_rows(problem.block, problem, cams, e[ph], x[pt], xy, g)
        a = np.zeros((len(img), 2, nu))
        for n in np.flatnonzero(pcol >= 0):
            a[n, :, pcol[n]:pcol[n] + 6] = je[n]
        for n in np.flatnonzero(qcol >= 0):
            a[n, :, qcol[n]:qcol[n] + 3] = jp[n]
        ac = np.zeros((len(ctrl), nu))
        for n, (j, k) in enumerate(ctrl):
            ac[n, col[("point", j)] + k] = 1.0
        fc = np.array([x[j][k] for j, k in ctrl])
        return (np.concatenate([(xy - mis).reshape(-1), fc]),
                np.vstack([a.reshape(-1, nu), ac]))

    y = np.zeros(nu)
    for (what, u), c in col.items():
        y[c:c + (6 if what == "photo" else 3)] = eo[u] if what == "photo" else xyz[u]
    sig = np.concatenate([sig, c_sig])
    p = 1.0 / sig**2
    small = DenseLeastSquares(func, np.concatenate([xy.reshape(-1), c_obs]), p,
                              method="lstsq", what="the new photos and points")
    try:
        sol = solve(small, y, REFINE)
    except GeometryError:
        return False
    # determined: the undamped normal equations at the solution are regular (scaled)
    a = sol.lin.a
    n = a.T @ (p[:, None] * a)
    d = np.sqrt(np.maximum(np.diag(n), 1e-300))
    lam = np.linalg.eigvalsh(n / np.outer(d, d))
    if not (sol.converged and lam[0] > UNDETERMINED):
        return False
    e, x = unpack(sol.state)
    eo[:], xyz[:] = e, x
    return True


def resected_again(block: Block, again: np.ndarray) -> np.ndarray:
    """The orientations (n_photos, 6) of the block's photos with those of `again` (mask)
    resected anew from the control and the points the other photos intersect (their rays
    only, none of `again`'s); a photo with fewer than MIN_PHOTO_POINTS + 1 such points
    keeps its orientation."""
    eo = block.photos.eo.copy()
    im, pts = block.image, block.points
    xyz = intersected_points(block.select_image(~again[im.photo]))
    known = np.isfinite(pts.xyz).all(axis=1) & (pts.role != "tie")
    xyz[known] = pts.xyz[known]
    cam = block.photos.camera
    xy = ideal_image_coordinates(block) - block.cameras.principal_point_mm[cam[im.photo]]
    for i in np.flatnonzero(again):
        rows = np.flatnonzero((im.photo == i) & np.isfinite(xyz[im.point]).all(axis=1))
        if len(rows) < MIN_PHOTO_POINTS + 1:
            continue
        try:
            eo[i] = resect(xy[rows], xyz[im.point[rows]], float(block.cameras.focal_mm[cam[i]]))[0]
        except GeometryError:
            continue
    return eo


def why_held(m: Measurements, i: int) -> str:
    """Why photo i, held, is not in the block, in words: too few of its points in the block,
    one point far outside where the others lie (named: outside the format, a mistyped
    coordinate), those points on one line in the image, or points that fit no one
    orientation (a resection's RMS above MISFIT image sigmas)."""
    name = m.photo_ids[i]
    rows = [r for r in m.rows_of_photo[i] if m.im_status[r] != REMOVED
            and m.point_in[m.im_point[r]]]
    n = len({m.im_point[r] for r in rows})
    if n < MIN_PHOTO_POINTS:
        return f"photo {name} is not determined yet ({n} of its points in the block, " \
               f"{MIN_PHOTO_POINTS} needed)"
    xy = np.array([m.im_xy[r] for r in rows]).reshape(-1, 2)
    far = _far_point(xy)
    if far is not None:
        k, times = far
        return (f"photo {name}: point {m.point_ids[m.im_point[rows[k]]]} at "
                f"({xy[k][0]:.6g}, {xy[k][1]:.6g}) mm lies {times:.0f} times as far from the "
                "middle of the photo's points as the others: outside the format, a mistyped "
                "coordinate? (remove it or measure it again)")
    if not spread(xy):
        return f"photo {name}: its {n} points in the block lie on one line in the image " \
               "(a photo is determined by points spread across it)"
    cam = m.photo_cam[i]
    c, pp = float(m.cameras.focal_mm[cam]), m.cameras.principal_point_mm[cam]
    xyz = np.array([m.point_xyz[m.im_point[r]] for r in rows]).reshape(-1, 3)
    sigma = float(np.median(np.array([m.im_sigma[r] for r in rows])))
    try:
        rms = resect(xy - pp, xyz, c)[1]
    except GeometryError:
        rms = np.inf
    if rms <= MISFIT * sigma:
        return f"photo {name}: its {n} points in the block fit an orientation, but the " \
               "new photo and points are not determined by them yet"
    how = "no resection puts them in front of the camera" if not np.isfinite(rms) else \
        f"resection RMS {rms:.4g} mm against an image sigma of {sigma * 1e3:.3g} µm"
    return f"photo {name}: its {n} points in the block fit no one orientation ({how})"


def _far_point(xy: np.ndarray) -> tuple[int, float] | None:
    """(index, how many times the others' median distance) of the one image point that
    lies FAR_POINT times farther from the points' median than the others lie, else None."""
    if len(xy) < MIN_PHOTO_POINTS + 1:
        return None
    d = np.hypot(*(xy - np.median(xy, axis=0)).T)
    k = int(np.argmax(d))
    typical = float(np.median(np.delete(d, k)))
    if typical > 0 and d[k] > FAR_POINT * typical:
        return k, float(d[k] / typical)
    return None
