"""What a pycolmap user writes to adjust a BAL file: read it, build a Reconstruction, solve.

    python benchmarks/pycolmap_bal_user.py problem-49-7776-pre.txt.bz2

The peer of `baarda adjust FILE -o OUT -q --calibrate none` in bench_issue16.py (timed as a
whole process).  Intrinsics fixed, trivial loss, points with two or more rays, COLMAP's
two-camera gauge, the same solver settings as bench_bal.py.  Prints the final cost.
"""

from __future__ import annotations

import bz2
import sys

import numpy as np


def rodrigues(aa: np.ndarray) -> np.ndarray:
    theta = np.linalg.norm(aa, axis=1)
    k = aa / np.where(theta > 0, theta, 1.0)[:, None]
    kx = np.zeros((len(aa), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx -= kx.transpose(0, 2, 1)
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def reconstruction(cams: np.ndarray, pts: np.ndarray, cam_idx: np.ndarray,
                   pt_idx: np.ndarray, xy: np.ndarray):
    """A pycolmap Reconstruction of a BAL problem: a RADIAL camera (f, k1, k2) and an image
    per BAL camera (BAL's camera looks down -z with y up: flipped to COLMAP's), a track per
    point."""
    import pycolmap

    nc = len(cams)
    rec = pycolmap.Reconstruction()
    flip = np.diag([1.0, -1.0, -1.0])
    rot = rodrigues(cams[:, :3])
    half = np.abs(xy).max() + 10
    point2d_of = np.empty(len(cam_idx), np.int64)
    order = np.argsort(cam_idx, kind="stable")
    bounds = np.searchsorted(cam_idx[order], np.arange(nc + 1))
    for c in range(nc):
        rows = order[bounds[c]:bounds[c + 1]]
        if not len(rows):
            continue
        f, k1, k2 = cams[c, 6:9]
        rec.add_camera_with_trivial_rig(pycolmap.Camera(
            camera_id=c + 1, model="RADIAL", width=int(2 * half), height=int(2 * half),
            params=[f, 0.0, 0.0, k1, k2]))
        point2d_of[rows] = np.arange(len(rows))
        pts2d = pycolmap.Point2DList([pycolmap.Point2D(np.array([x, -y])) for x, y in xy[rows]])
        rec.add_image_with_trivial_frame(
            pycolmap.Image(name=str(c), points2D=pts2d, camera_id=c + 1, image_id=c + 1),
            pycolmap.Rigid3d(pycolmap.Rotation3d(flip @ rot[c]), flip @ cams[c, 3:6]))
    order = np.argsort(pt_idx, kind="stable")
    for group in np.split(order, np.flatnonzero(np.diff(pt_idx[order])) + 1):
        track = pycolmap.Track()
        for k in group.tolist():
            track.add_element(int(cam_idx[k]) + 1, int(point2d_of[k]))
        rec.add_point3D(pts[pt_idx[group[0]]], track)
    return rec


def adjuster_options(refine: bool, max_iterations: int):
    """Bundle-adjustment options and config of both benchmarks: trivial loss, tolerances
    1e-12, the two-camera gauge; `refine`: f, k1, k2 too (never the principal point)."""
    import pycolmap

    opts = pycolmap.BundleAdjustmentOptions()
    opts.refine_focal_length = opts.refine_extra_params = refine
    opts.refine_principal_point = False
    opts.print_summary = False
    opts.ceres.loss_function_type = pycolmap.LossFunctionType.TRIVIAL
    so = opts.ceres.solver_options
    so.max_num_iterations = max_iterations
    so.function_tolerance = so.gradient_tolerance = so.parameter_tolerance = 1e-12
    return opts


def adjust(rec, opts):
    """The solve of a reconstruction (every image, the two-camera gauge): Ceres' summary."""
    import pycolmap

    cfg = pycolmap.BundleAdjustmentConfig()
    for iid in rec.reg_image_ids():
        cfg.add_image(iid)
    cfg.fix_gauge(pycolmap.BundleAdjustmentGauge.TWO_CAMS_FROM_WORLD)
    return pycolmap.create_default_ceres_bundle_adjuster(opts, cfg, rec).solve()


def main(path: str) -> None:
    with bz2.open(path, "rt") as fh:
        nc, npt, nobs = (int(v) for v in fh.readline().split())
        obs = np.loadtxt(fh, max_rows=nobs)
        rest = np.loadtxt(fh).ravel()
    cams, pts = rest[: 9 * nc].reshape(nc, 9), rest[9 * nc:].reshape(npt, 3)
    cam_idx, pt_idx, xy = obs[:, 0].astype(int), obs[:, 1].astype(int), obs[:, 2:]
    rays = np.bincount(pt_idx, minlength=npt)
    keep = rays[pt_idx] >= 2
    rec = reconstruction(cams, pts, cam_idx[keep], pt_idx[keep], xy[keep])
    summary = adjust(rec, adjuster_options(False, 100))
    print(f"final cost {summary.ceres_summary.final_cost:.9f}")


if __name__ == "__main__":
    main(sys.argv[1])
