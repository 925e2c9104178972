"""The inner-constraint datum of a free network (Baarda's S-transformation).

A free network is adjusted with minimal constraints (bundle/free_network.py); its residuals,
redundancy numbers, w-tests and MDBs do not depend on that choice, its coordinates and their
covariances do.  The inner datum is the one in which the chosen datum points (default all
adjusted points) move least: their coordinates best fit (7-parameter similarity, 6 when
distances fix the scale) the approximate ones, and their covariance has the smallest trace.

With G (u x d) the datum directions of every unknown (a translation, a small rotation about
the datum points' centroid and, without distances, a scale change: points and projection
centres move by t + w x (X - c) + s (X - c), a photo's angles follow the rotation, camera
parameters do not move) and Gp its rows of the datum points,

    S = I - G (Gp' Gp)^-1 Gp',    Sigma_inner = S Sigma S'

(Baarda 1973, S-transformations).  Only the 3 x 3 blocks of every point are formed: with
Z = Sigma Gp (d columns of N^-1, one solve each),

    Sigma_inner,jj = Sigma_jj - G_j K Z_j' - Z_j K G_j' + G_j K (Gp' Z) K G_j',  K = (Gp' Gp)^-1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.block.rotation import angles_from_matrix, rotation_matrix, similarity


def _cross(v: np.ndarray) -> np.ndarray:
    """[v]x (n, 3, 3): [v]x w = v x w."""
    out = np.zeros((len(v), 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -v[:, 2], v[:, 1]
    out[:, 1, 0], out[:, 1, 2] = v[:, 2], -v[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -v[:, 1], v[:, 0]
    return out


def position_directions(xyz: np.ndarray, centre: np.ndarray, scale: bool) -> np.ndarray:
    """(n, 3, d) datum directions of positions: translation, rotation w (dX = w x (X - c)),
    scale (dX = s (X - c))."""
    v = xyz - centre
    g = [np.broadcast_to(np.eye(3), (len(v), 3, 3)), -_cross(v)]
    if scale:
        g.append(v[:, :, None])
    return np.concatenate(g, axis=2)


def angle_directions(angles: np.ndarray, h: float = 1e-7) -> np.ndarray:
    """(n, 3, 3) derivatives of omega, phi, kappa of each photo when the object frame turns
    by a small rotation w (R -> (I + [w]x) R), by central differences of the angles."""
    r = rotation_matrix(angles[:, 0], angles[:, 1], angles[:, 2])
    out = np.zeros((len(angles), 3, 3))
    for k in range(3):
        w = np.zeros(3)
        w[k] = h
        plus = angles_from_matrix(rotation_matrix(*w) @ r)
        minus = angles_from_matrix(rotation_matrix(*(-w)) @ r)
        d = plus - minus
        d = (d + np.pi) % (2 * np.pi) - np.pi  # across the +-pi seam
        out[:, :, k] = d / (2 * h)
    return out


@dataclass(frozen=True)
class InnerDatum:
    """A free network's coordinates and cofactors in the inner datum of its datum points.

    xyz (n_adjusted_points, 3) m, order of problem.point_ids; point_cofactors (n, 3, 3);
    eo (n_photos, 6) m and rad; frame_cofactors (n_photos, 6, 6); n_datum_points; scale
    (whether the datum includes the scale: False when distances fix it); similarity
    (s, R (3, 3), t (3,)) from the adjusted datum onto the inner one, X' = s R X + t.
    Cofactors are unscaled (multiply by sigma0^2)."""

    xyz: np.ndarray
    point_cofactors: np.ndarray
    eo: np.ndarray
    frame_cofactors: np.ndarray
    n_datum_points: int
    scale: bool
    similarity: tuple[float, np.ndarray, np.ndarray]


def _angle_jacobian(r: np.ndarray, angles: np.ndarray, h: float = 1e-7) -> np.ndarray:
    """(n, 3, 3) d angles(r R(a)) / d a by central differences."""
    out = np.zeros((len(angles), 3, 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        plus = angles_from_matrix(r @ rotation_matrix(*(angles + e).T))
        minus = angles_from_matrix(r @ rotation_matrix(*(angles - e).T))
        d = (plus - minus + np.pi) % (2 * np.pi) - np.pi
        out[:, :, k] = d / (2 * h)
    return out


def inner_datum(result, points: np.ndarray | None = None) -> InnerDatum:
    """A free-network result in the inner datum of `points` (indices of adjusted points in
    the order of problem.point_ids, default all).  Coordinates and orientations: the
    adjusted ones moved by the similarity that best fits the datum points onto their
    approximations (the nonlinear form of the inner constraints); cofactors: the
    S-transformation (module docstring), then carried through that similarity."""
    pb, factor = result.problem, result.factor
    s = factor.system
    scale = not np.any(pb.kind == "distance")  # distances fix the scale
    d = 7 if scale else 6
    xyz = result.xyz
    sel = np.arange(len(xyz)) if points is None else np.asarray(points)
    centre = xyz[sel].mean(axis=0)
    # G of every unknown in the order of the Schur system: frames, eliminated points, globals
    gf = np.zeros((s.nf, s.b, d))  # a camera in its photo's block does not move
    gf[:, :3] = position_directions(result.eo[:, :3], centre, scale)
    gf[:, 3:, 3:6] = angle_directions(result.eo[:, 3:])
    elim_rows = pb.remap[pb.elim_ids]
    gp = position_directions(xyz[elim_rows], centre, scale)
    gg = np.zeros((s.ng, d))
    pcols = pb.global_layout.columns("points")  # the border points' coordinates
    if len(pb.border_ids):
        border_rows = pb.remap[pb.border_ids]
        gg[pcols] = position_directions(xyz[border_rows], centre, scale).reshape(-1, d)
    # Gp: the rows of the datum points only
    is_datum = np.zeros(len(xyz), bool)
    is_datum[sel] = True
    gp_sel = np.where(is_datum[elim_rows][:, None, None], gp, 0.0)
    gg_sel = gg.copy()
    if len(pb.border_ids):
        mask = np.repeat(is_datum[pb.remap[pb.border_ids]], 3)
        gg_sel[pcols] = np.where(mask[:, None], gg[pcols], 0.0)
    gtg = np.einsum("pdi,pdj->ij", gp_sel, gp_sel) + gg_sel.T @ gg_sel
    k = np.linalg.inv(gtg)
    zs = factor.solve_normal(np.zeros((s.nf, s.b, d)), gp_sel, gg_sel) if s.ng else \
        factor.solve_normal(np.zeros((s.nf, s.b, d)), gp_sel)
    zf, zp = zs[0], zs[1]
    zg = zs[2] if s.ng else np.zeros((0, d))
    gz = np.einsum("pdi,pdj->ij", gp_sel, zp) + gg_sel.T @ zg
    # cofactor blocks of every adjusted point
    q = result.point_covariance()
    g_all = np.zeros((len(xyz), 3, d))
    z_all = np.zeros((len(xyz), 3, d))
    g_all[elim_rows], z_all[elim_rows] = gp, zp
    if len(pb.border_ids):
        g_all[pb.remap[pb.border_ids]] = gg[pcols].reshape(-1, 3, d)
        z_all[pb.remap[pb.border_ids]] = zg[pcols].reshape(-1, 3, d)
    gk = g_all @ k
    q_inner = (q - gk @ np.swapaxes(z_all, 1, 2) - z_all @ np.swapaxes(gk, 1, 2)
               + gk @ gz @ np.swapaxes(gk, 1, 2))
    # coordinates: the best-fitting similarity onto the approximations of the datum points
    approx = np.empty_like(xyz)
    approx[elim_rows] = pb.approximations[1]
    if len(pb.border_ids):
        approx[pb.remap[pb.border_ids]] = \
            pb.approximations[2][pcols].reshape(-1, 3)
    sc, r, t = similarity(xyz[sel], approx[sel])
    if not scale:
        sc = 1.0
        t = approx[sel].mean(axis=0) - r @ xyz[sel].mean(axis=0)
    # cofactor blocks of every photo, then through the similarity (positions turn and scale,
    # angles change by the Jacobian of the rotated attitude)
    fk = gf[:, :6] @ k
    zf = zf[:, :6]
    qf = result.frame_covariance()
    qf_inner = (qf - fk @ np.swapaxes(zf, 1, 2) - zf @ np.swapaxes(fk, 1, 2)
                + fk @ gz @ np.swapaxes(fk, 1, 2))
    eo = result.eo.copy()
    eo[:, :3] = sc * eo[:, :3] @ r.T + t
    eo[:, 3:] = angles_from_matrix(r @ rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5]))
    tf = np.zeros((len(eo), 6, 6))
    tf[:, :3, :3] = sc * r
    tf[:, 3:, 3:] = _angle_jacobian(r, result.eo[:, 3:])
    return InnerDatum(xyz=sc * xyz @ r.T + t, point_cofactors=sc**2 * r @ q_inner @ r.T, eo=eo,
                      frame_cofactors=tf @ qf_inner @ np.swapaxes(tf, 1, 2),
                      n_datum_points=len(sel), scale=scale, similarity=(float(sc), r, t))
