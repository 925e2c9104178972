"""Models formed from image coordinates: relative orientation of consecutive photos.

Independent relative orientation of a stereo pair with the collinearity equations of the
bundle (baarda.bundle.collinearity): the left photo is the model frame (projection centre
at the origin, no rotation), the right photo has the base component bx fixed and by, bz,
omega, phi, kappa free; the model points are intersected at the same time (a small dense
least-squares problem per model).  bx is the base at image scale (mm), so the model
coordinates are in mm at image scale (z negative below the left projection centre).
Both projection centres become points of the model.

Standard deviations of the model coordinates: FOTEF's diagonal ones by default, from the
image sigma sx: sigma_xy = sx and sigma_z = sqrt(2) sx c / bx (normal case); or, with
`covariance=True`, the 3 x 3 covariance of each point propagated from the relative
orientation and S-transformed to the inner datum of the similarity (the part that only
moves the model as a whole, which the block adjustment absorbs, removed); the adjustment
decorrelates it per row.  The correlations between the points of a model (the random
model deformation caused by errors of the relative orientation) are not kept.
"""

from __future__ import annotations

import numpy as np

from baarda.adjustment.dense import DenseLeastSquares
from baarda.adjustment.solve import solve
from baarda.block.model_block import ModelBlock, ModelSettings
from baarda.block.photo_block import Block
from baarda.block.rotation import angles_from_matrix, rotation_matrix
from baarda.bundle.collinearity import project_with_jacobians
from baarda.bundle.geometry import approximate_points
from baarda.errors import GeometryError
from baarda.options import SolveOptions

# converged when the points move by less than 1e-9 of the base and the angles by less than
# 1e-12 rad (correction weighs angles by 1000), or at the rounding floor (no step lowers
# v'Pv any more) with corrections below 1e-6
RO_SOLVE = SolveOptions(max_iterations=30, tolerance=1e-9, stall_tolerance=1e-6, min_step=1e-3,
                        final_step=True)


def model_pairs(block: Block) -> list[tuple[str, int, int]]:
    """(model id, left photo, right photo) for consecutive photos of every strip."""
    im = block.image
    pairs = []
    if im.model is not None:
        for label in dict.fromkeys(im.model.tolist()):
            ph: list[int] | np.ndarray = sorted(set(im.photo[im.model == label].tolist()))
            if len(ph) != 2:
                raise GeometryError(f"model '{label}' has {len(ph)} photos, not 2")
            pairs.append((str(label), ph[0], ph[1]))
        return pairs
    strips = block.photos.strip.astype(str)
    for s in dict.fromkeys(strips.tolist()):
        ph = np.flatnonzero(strips == s)
        for a, b in zip(ph[:-1], ph[1:], strict=True):
            pairs.append((f"{block.photos.ids[a]}-{block.photos.ids[b]}", int(a), int(b)))
    return pairs


def _intersect(x1, x2, r2, b, c1, c2, pp1, pp2):
    """Midpoint intersection of rays from 0 (left, R = I) and b (right, R = r2)."""
    d1 = np.column_stack([x1 - pp1, -np.full(len(x1), c1)])
    d2 = np.column_stack([x2 - pp2, -np.full(len(x2), c2)]) @ r2.T
    a = np.stack([d1, -d2], axis=2)  # (n, 3, 2): lam1 d1 - lam2 d2 = b
    lam = np.linalg.solve(np.einsum("nki,nkj->nij", a, a),
                          np.einsum("nki,k->ni", a, b)[:, :, None])[:, :, 0]
    return 0.5 * (lam[:, :1] * d1 + b + lam[:, 1:2] * d2)


def relative_orientation(block: Block, left: int, right: int, eo_approx: np.ndarray,
                         ground: np.ndarray):
    """Relative orientation of one pair; returns (point indices, model xyz (n, 3) mm,
    covariance (n, 3, 3) mm^2, right photo (bx, by, bz, omega, phi, kappa), sigma0)."""
    im, cams = block.image, block.cameras
    rows_l = {int(p): i for i, p in zip(np.flatnonzero(im.photo == left),
                                       im.point[im.photo == left], strict=True)}
    rows_r = {int(p): i for i, p in zip(np.flatnonzero(im.photo == right),
                                       im.point[im.photo == right], strict=True)}
    pts = np.array(sorted(set(rows_l) & set(rows_r)), dtype=int)
    if len(pts) < 6:
        raise GeometryError(f"photos {block.photos.ids[left]} and {block.photos.ids[right]} "
                            f"share {len(pts)} points; a relative orientation needs 6")
    il, ir = np.array([rows_l[p] for p in pts]), np.array([rows_r[p] for p in pts])
    cl, cr = block.photos.camera[left], block.photos.camera[right]
    c = cams.focal_mm[[cl, cr]]
    pp = cams.principal_point_mm[[cl, cr]]
    rl = rotation_matrix(*eo_approx[left, 3:])
    rr = rotation_matrix(*eo_approx[right, 3:])
    base_t = rl.T @ (eo_approx[right, :3] - eo_approx[left, :3])
    g = ground[pts]
    height = np.nanmedian(eo_approx[[left, right], 2].mean() - g[:, 2]) if \
        np.isfinite(g[:, 2]).any() else eo_approx[left, 2]
    k = c[0] / max(float(height), 1e-9)  # mm of the model per m: image scale
    b = k * base_t
    bx = float(np.linalg.norm(b))
    r_rel = rl.T @ rr
    ang = angles_from_matrix(r_rel)
    # unknowns: by, bz, omega, phi, kappa of the right photo (bx fixed), then the points
    b = b * bx / np.linalg.norm(b)
    rot = rotation_matrix(*ang)
    xyz = _intersect(im.xy_mm[il], im.xy_mm[ir], rot, b, c[0], c[1], pp[0], pp[1])
    eo_r = np.concatenate([b, ang])
    sig = np.concatenate([im.sigma_xy[il].ravel(), im.sigma_xy[ir].ravel()])  # as obs
    obs = np.concatenate([im.xy_mm[il].ravel(), im.xy_mm[ir].ravel()])
    n = len(pts)
    zero6 = np.zeros((n, 6))

    def func(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x = (by, bz, omega, phi, kappa of the right photo, points): image coordinates."""
        eo = np.concatenate([[bx], x[:5]])
        p = x[5:].reshape(n, 3)
        xl, _, jpl = project_with_jacobians(zero6, p, np.full(n, c[0]), np.tile(pp[0], (n, 1)))
        xr, jer, jpr = project_with_jacobians(np.tile(eo, (n, 1)), p, np.full(n, c[1]),
                                              np.tile(pp[1], (n, 1)))
        a = np.zeros((4 * n, 5 + 3 * n))
        for i in range(n):
            a[2 * i:2 * i + 2, 5 + 3 * i:8 + 3 * i] = jpl[i]
            a[2 * n + 2 * i:2 * n + 2 * i + 2, :5] = jer[i][:, 1:]
            a[2 * n + 2 * i:2 * n + 2 * i + 2, 5 + 3 * i:8 + 3 * i] = jpr[i]
        return np.concatenate([xl.ravel(), xr.ravel()]), a

    def correction(x: np.ndarray, dx: np.ndarray) -> float:
        # points relative to the base, angles in rad times 1000
        return max(float(np.max(np.abs(dx[5:]))) / bx, 1e3 * float(np.max(np.abs(dx[2:5]))))

    pair = f"photos {block.photos.ids[left]} and {block.photos.ids[right]}"
    problem = DenseLeastSquares(func, obs, 1.0 / sig**2, method="lstsq", correction=correction,
                                what=f"relative orientation of {pair}")
    sol = solve(problem, np.concatenate([eo_r[1:], xyz.ravel()]), RO_SOLVE)
    if not sol.converged:
        raise GeometryError(f"relative orientation of {pair} did not converge")
    eo_r = np.concatenate([[bx], sol.state[:5]])
    xyz = sol.state[5:].reshape(n, 3)
    e = sol.lin.e
    aw = sol.lin.a / sig[:, None]
    red = 4 * n - 5 - 3 * n
    s0 = float(np.sqrt(np.sum((e / sig) ** 2) / red)) if red > 0 else np.nan
    nrm = aw.T @ aw
    try:  # numerically singular (condition beyond 1 / eps): no covariance to give
        if not np.isfinite(nrm).all() or np.linalg.cond(nrm) * np.finfo(float).eps > 1.0:
            raise np.linalg.LinAlgError
        qxx = np.linalg.inv(nrm)[5:, 5:]
    except np.linalg.LinAlgError:
        raise GeometryError(f"relative orientation of {pair}: the normal equations are "
                            "singular (check the image points and the cameras of both "
                            "photos)") from None
    cov = datum_free(qxx, xyz)
    return pts, xyz, cov, eo_r, s0


def datum_free(q: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """Per-point 3 x 3 blocks of the covariance q (3n x 3n) of model points xyz after an
    S-transformation to the inner (minimum-trace) datum of the 7-parameter similarity.

    The block adjustment absorbs any similarity of a model, so the part of the relative
    orientation's covariance that only moves the model as a whole (the datum of the left
    photo) is removed: Q_S = S Q S^T, S = I - G (G^T G)^-1 G^T with G the changes of the
    point coordinates under translation, rotation and scale about the centroid.
    """
    n = len(xyz)
    c = xyz - xyz.mean(axis=0)
    g: np.ndarray = np.zeros((n, 3, 7))
    g[:, [0, 1, 2], [0, 1, 2]] = 1.0
    g[:, 1, 3], g[:, 2, 3] = -c[:, 2], c[:, 1]  # rotation about x
    g[:, 0, 4], g[:, 2, 4] = c[:, 2], -c[:, 0]  # about y
    g[:, 0, 5], g[:, 1, 5] = -c[:, 1], c[:, 0]  # about z
    g[:, :, 6] = c  # scale
    g = g.reshape(3 * n, 7)
    s = np.eye(3 * n) - g @ np.linalg.solve(g.T @ g, g.T)
    qs = s @ q @ s.T
    return np.array([qs[3 * i:3 * i + 3, 3 * i:3 * i + 3] for i in range(n)])


def form_models(block: Block, covariance: bool = False) -> ModelBlock:
    """Form independent models from the photos of `block` (see the module text)."""
    s = block.settings
    keep = np.ones(len(block.points), bool)
    try:
        ground = approximate_points(block, keep)
    except GeometryError:
        ground = block.points.xyz.copy()
    eo = block.photos.eo
    pairs = model_pairs(block)
    n_pts = len(block.points)
    pc_names = [f"PC{p}" for p in block.photos.ids]
    om: list[int] | np.ndarray
    op: list[int] | np.ndarray
    om, op, ox, osig, ocov, strips, notes = [], [], [], [], [], [], []
    sx = s.sigma_image_um * 1e-3
    for m, (name, a, b) in enumerate(pairs):
        pts, xyz, cov, eo_r, s0 = relative_orientation(block, a, b, eo, ground)
        bx = float(eo_r[0])
        c = float(block.cameras.focal_mm[block.photos.camera[a]])
        sz = np.sqrt(2.0) * sx * c / bx
        if s0 > 3:
            notes.append(f"model {name}: relative orientation sigma0 {s0:.2f} (check its "
                         "image points)")
        ids = list(pts) + [n_pts + a, n_pts + b]
        x = np.vstack([xyz, [0.0, 0.0, 0.0], eo_r[:3]])
        om += [m] * len(ids)
        op += ids
        ox.append(x)
        osig.append(np.tile([sx, sx, sz], (len(ids), 1)))
        cv = np.vstack([cov, np.tile(np.diag([sx, sx, sz]) ** 2, (2, 1, 1))])
        ocov.append(cv)
        strips.append(str(block.photos.strip[a]))
    om, op = np.array(om), np.array(op)
    used = np.bincount(op, minlength=n_pts + len(pc_names)) > 0
    remap = np.cumsum(used) - 1
    names = [p for p, u in zip(list(block.points.ids) + pc_names, used, strict=True) if u]
    pc = np.concatenate([np.zeros(n_pts, bool), np.ones(len(pc_names), bool)])[used]
    role = np.concatenate([block.points.role, np.full(len(pc_names), "tie", dtype=object)])
    xyz = np.vstack([block.points.xyz, np.full((len(pc_names), 3), np.nan)])
    sig = np.vstack([block.points.sigma, np.full((len(pc_names), 3), np.nan)])
    settings = ModelSettings(name=s.name, sigma_model_um=(s.sigma_image_um, float(
        np.median(np.vstack(osig)[:, 2])) * 1e3), sigma_control_m=s.sigma_control_m,
        alpha0=s.alpha0, beta0=s.beta0)
    return ModelBlock(settings, [p[0] for p in pairs], np.array(strips, dtype=object), names,
                      role[used].astype(object), pc, xyz[used], sig[used], om, remap[op],
                      np.vstack(ox), np.vstack(osig),
                      np.concatenate(ocov) if covariance else None,
                      source=block.source + " (models formed by relative orientation)",
                      notes=notes)
