"""A baarda Block as a pycolmap.Reconstruction, and pycolmap's bundle adjustment of it.

Conventions (baarda/block/rotation.py, baarda/bundle/collinearity.py):

    baarda:  u = R^T (X - X0),  x = x0 - c u1/u3,  y = y0 - c u2/u3   (mm, camera looks down -z)
    COLMAP:  p = R_cw X + t,    col = cx + f p1/p3,  row = cy + f p2/p3 (px, looks along +z, y down)

With D = diag(1, -1, -1): R_cw = D R^T, t = -R_cw X0, so p = D u and
col = cx + (x - x0)/s, row = cy - (y - y0)/s for a pixel size s (mm).  The image centre
(x, y) = (0, 0) mm is the pixel (W/2, H/2), so cx = W/2 + x0/s and cy = H/2 - y0/s.

Control: pycolmap has no weighted ground control; with pyceres installed each control point
gets a Ceres NormalPrior residual block (weighted control, as in baarda), otherwise the fully
controlled points are held constant (fixed control) and height-only points are free.
Control residuals are scaled by the image sigma in pixels so that the Ceres cost is
0.5 * sigma_px^2 * v^T P v of baarda (the same objective, in pixel units).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pycolmap

from baarda.block.photo_block import Block
from baarda.block.rotation import angles_from_matrix, rotation_matrix
from baarda.bundle.collinearity import project

try:  # weighted control needs pyceres (pip install pyceres), see pycolmap_example.py
    import pyceres
except ImportError:  # pragma: no cover - depends on the environment
    pyceres = None

D = np.diag([1.0, -1.0, -1.0])
UNOBSERVED_SIGMA_M = 1e6  # a control coordinate that is not observed: weight 1e-12 m^-2


@dataclass
class ColmapBlock:
    rec: pycolmap.Reconstruction
    pixel_mm: float
    sigma_px: float
    image_ids: np.ndarray  # (n_photos,) pycolmap image id of each baarda photo
    point3d_ids: np.ndarray  # (n_adjusted_points,) pycolmap point id of each adjusted point
    control_rows: np.ndarray  # rows of the adjusted points that are control points
    control_xyz: np.ndarray  # (nc, 3) given coordinates (NaN: not observed)
    control_sigma: np.ndarray  # (nc, 3) m (NaN: not observed)
    centre_px: np.ndarray  # (n_cameras, 2) pixel of the image centre (W/2, H/2)


def mm_to_px(xy_mm: np.ndarray, centre_px: np.ndarray, pixel_mm: float) -> np.ndarray:
    """Image coordinates in mm (x right, y up) to COLMAP pixels (col right, row down)."""
    return np.column_stack([centre_px[:, 0] + xy_mm[:, 0] / pixel_mm,
                            centre_px[:, 1] - xy_mm[:, 1] / pixel_mm])


def pose_to_colmap(eo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """baarda EO (n, 6) -> COLMAP cam_from_world rotations (n, 3, 3) and translations (n, 3)."""
    r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
    r_cw = D[None] @ np.swapaxes(r, 1, 2)
    t = -np.einsum("nij,nj->ni", r_cw, eo[:, :3])
    return r_cw, t


def pose_from_colmap(r_cw: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Inverse of pose_to_colmap: (n, 6) X0, Y0, Z0, omega, phi, kappa."""
    r = np.swapaxes(r_cw, 1, 2) @ D[None]
    x0 = -np.einsum("nji,nj->ni", r_cw, t)
    return np.column_stack([x0, angles_from_matrix(r)])


def build(block: Block, obs: np.ndarray, point_ids: np.ndarray, xyz0: np.ndarray,
          eo0: np.ndarray, control: np.ndarray, pixel_mm: float = 0.01) -> ColmapBlock:
    """Reconstruction with the adjusted observations `obs` (rows of block.image), the
    adjusted points `point_ids` (block point indices) at `xyz0` and photos at `eo0`.

    `control` holds the block indices of the control points (BundleProblem.control).
    """
    cams, im = block.cameras, block.image
    fmt_mm = 230.0
    size = int(round(fmt_mm / pixel_mm))
    centre = np.zeros((len(cams), 2))
    rec = pycolmap.Reconstruction()
    for k in range(len(cams)):
        centre[k] = (size / 2.0, size / 2.0)
        f = cams.focal_mm[k] / pixel_mm
        cx = centre[k, 0] + cams.principal_point_mm[k, 0] / pixel_mm
        cy = centre[k, 1] - cams.principal_point_mm[k, 1] / pixel_mm
        cam = pycolmap.Camera(camera_id=k + 1, model="PINHOLE", width=size, height=size,
                              params=[f, f, cx, cy])
        rec.add_camera_with_trivial_rig(cam)
    sig = np.unique(im.sigma_mm[obs])
    if len(sig) != 1:
        raise ValueError("this comparison needs one image sigma (pycolmap cannot weight them)")
    sigma_px = float(sig[0] / pixel_mm)
    photo = im.photo[obs]
    cam_of_obs = block.photos.camera[photo]
    xy_px = mm_to_px(im.xy_mm[obs], centre[cam_of_obs], pixel_mm)
    r_cw, t = pose_to_colmap(eo0)
    order = np.argsort(photo, kind="stable")
    starts = np.searchsorted(photo[order], np.arange(len(block.photos) + 1))
    p2d_index = np.empty(len(obs), np.int64)
    image_ids = np.arange(1, len(block.photos) + 1)
    for i in range(len(block.photos)):
        rows = order[starts[i]:starts[i + 1]]
        p2d_index[rows] = np.arange(len(rows))
        image = pycolmap.Image(
            name=f"{block.photos.ids[i]}.jpg",
            points2D=pycolmap.Point2DList([pycolmap.Point2D(xy) for xy in xy_px[rows]]),
            camera_id=int(block.photos.camera[i]) + 1, image_id=int(image_ids[i]))
        pose = pycolmap.Rigid3d(pycolmap.Rotation3d(r_cw[i]), t[i])
        rec.add_image_with_trivial_frame(image, pose)
    remap = np.full(len(block.points), -1)
    remap[point_ids] = np.arange(len(point_ids))
    row_of_obs = remap[im.point[obs]]
    order = np.argsort(row_of_obs, kind="stable")
    starts = np.searchsorted(row_of_obs[order], np.arange(len(point_ids) + 1))
    p3d = np.empty(len(point_ids), np.int64)
    for j in range(len(point_ids)):
        track = pycolmap.Track()
        for o in order[starts[j]:starts[j + 1]]:
            track.add_element(int(image_ids[photo[o]]), int(p2d_index[o]))
        p3d[j] = rec.add_point3D(xyz0[j], track)
    pts = block.points
    return ColmapBlock(rec, pixel_mm, sigma_px, image_ids, p3d, remap[control],
                       pts.xyz[control], pts.sigma[control], centre)


def verify_projection(cb: ColmapBlock, block: Block, obs: np.ndarray, xyz: np.ndarray,
                      eo: np.ndarray, point_ids: np.ndarray) -> float:
    """Largest difference (px) between pycolmap's and baarda's projections of the
    reconstruction's current points into its current images (all observations)."""
    im = block.image
    remap = np.full(len(block.points), -1)
    remap[point_ids] = np.arange(len(point_ids))
    photo, row = im.photo[obs], remap[im.point[obs]]
    cam = block.photos.camera[photo]
    xy = project(eo[photo], xyz[row], block.cameras.focal_mm[cam],
                 block.cameras.principal_point_mm[cam])
    ours = mm_to_px(xy, cb.centre_px[cam], cb.pixel_mm)
    theirs = np.empty_like(ours)
    for i in np.unique(photo):
        sel = np.flatnonzero(photo == i)
        image = cb.rec.image(int(cb.image_ids[i]))
        pc = image.cam_from_world() * np.ascontiguousarray(xyz[row[sel]])
        theirs[sel] = image.camera.img_from_cam(pc, check_cheirality=False)
    return float(np.max(np.abs(ours - theirs)))


def solution(cb: ColmapBlock) -> tuple[np.ndarray, np.ndarray]:
    """(eo (n, 6) in baarda's convention, xyz (n_points, 3)) of the reconstruction."""
    r_cw, t = [], []
    for i in cb.image_ids:
        pose = cb.rec.image(int(i)).cam_from_world()
        r_cw.append(pose.rotation.matrix())
        t.append(pose.translation)
    eo = pose_from_colmap(np.array(r_cw), np.array(t))
    xyz = np.array([cb.rec.point3D(int(p)).xyz for p in cb.point3d_ids])
    return eo, xyz


def options(function_tolerance: float = 1e-10, max_iterations: int = 100,
            threads: int = -1) -> pycolmap.BundleAdjustmentOptions:
    o = pycolmap.BundleAdjustmentOptions()
    o.refine_focal_length = False
    o.refine_principal_point = False
    o.refine_extra_params = False
    o.print_summary = False
    o.ceres.loss_function_type = pycolmap.LossFunctionType.TRIVIAL
    so = o.ceres.solver_options
    so.max_num_iterations = max_iterations
    so.function_tolerance = function_tolerance
    if threads > 0:
        so.num_threads = threads
    return o


def adjust(cb: ColmapBlock, weighted: bool = True, function_tolerance: float = 1e-10,
           max_iterations: int = 100, threads: int = -1) -> dict:
    """pycolmap's bundle adjustment of `cb` (in place); timing covers building the Ceres
    problem (pycolmap), adding the control residual blocks and solving."""
    weighted = weighted and pyceres is not None
    t0 = time.perf_counter()
    o = options(function_tolerance, max_iterations, threads)
    cfg = pycolmap.BundleAdjustmentConfig()
    for i in cb.image_ids:
        cfg.add_image(int(i))
    for cam_id in cb.rec.cameras:
        cfg.set_constant_cam_intrinsics(int(cam_id))
    full = np.isfinite(cb.control_sigma).all(axis=1)
    if not weighted:  # fully controlled points constant (at their given XYZ, which are
        # their starting values), height-only points free
        for j in cb.control_rows[full]:
            cfg.add_constant_point(int(cb.point3d_ids[j]))
    ba = pycolmap.create_default_ceres_bundle_adjuster(o, cfg, cb.rec)
    if weighted:
        problem = ba.problem  # a pyceres.Problem (needs pyceres imported)
        s = np.where(np.isfinite(cb.control_sigma), cb.control_sigma, UNOBSERVED_SIGMA_M)
        mean = np.nan_to_num(cb.control_xyz)
        for k, j in enumerate(cb.control_rows):
            block = cb.rec.point3D(int(cb.point3d_ids[j])).xyz
            cov = np.diag((s[k] / cb.sigma_px) ** 2)
            problem.add_residual_block(pyceres.factors.NormalPrior(mean[k], cov), None, [block])
        so = o.ceres.create_solver_options(cfg, problem)
        so.function_tolerance = function_tolerance
        so.max_num_iterations = max_iterations
        if threads > 0:
            so.num_threads = threads
        summary = pyceres.SolverSummary()
        t_setup = time.perf_counter() - t0
        pyceres.solve(so, problem, summary)
        cs = summary
    else:
        t_setup = time.perf_counter() - t0
        cs = ba.solve().ceres_summary
    seconds = time.perf_counter() - t0
    return {
        "control": "weighted (NormalPrior)" if weighted else "fixed (constant XYZ points)",
        "seconds": seconds, "setup_seconds": t_setup,
        "ceres_seconds": cs.total_time_in_seconds,
        "iterations": cs.num_successful_steps + cs.num_unsuccessful_steps,
        "successful": cs.num_successful_steps,
        "initial_vtpv": 2 * cs.initial_cost / cb.sigma_px**2,
        "final_vtpv": 2 * cs.final_cost / cb.sigma_px**2,
        "termination": str(cs.termination_type).split(".")[-1],
        "linear_solver": str(cs.linear_solver_type_used).split(".")[-1],
        "threads": cs.num_threads_used,
        "residuals": cs.num_residuals_reduced,
        "parameters": cs.num_effective_parameters_reduced,
        "brief": cs.BriefReport(),
    }
