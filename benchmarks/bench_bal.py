"""baarda vs pycolmap (COLMAP's bundle adjustment on Ceres) on BAL problems, same run.

    PYTHONPATH=. python benchmarks/bench_bal.py [--intrinsics] [--repeat N] [FILE.bz2 ...]

Both solve the same least-squares problem: the observations of the BAL file (those of points
behind a camera at the "pre" values left out in both, as baarda keeps points in front),
sigma 1 px, the BAL radial model with f, k1, k2 held fixed at the file's values (with
--intrinsics estimated per camera by both), trivial loss, all poses and points free
(baarda: minimal-constraint datum; COLMAP: its two-camera gauge).  Printed: final cost
0.5 * sum(r^2) [px^2] of each, iterations and wall time (the median of N solves of each engine,
after one untimed solve in which numba loads its kernels).  Not a test (it takes minutes);
the files are read from ../shared/data/bal/ by default.
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from baarda.bundle.bundle_problem import SOLVE
from baarda.bundle.free_network import adjust_free, drop_points_behind
from baarda.io.bal import bal_to_block, read_bal, rodrigues

DEFAULT = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "bal"
FILES = ["problem-49-7776-pre.txt.bz2", "problem-21-11315-pre.txt.bz2",
         "problem-16-22106-pre.txt.bz2"]


def run_pycolmap(bal, cam_idx, pt_idx, xy, max_iterations=200, refine=False):
    """COLMAP BA of the given observations; returns (initial cost, final cost, iters, s)."""
    import pycolmap

    rec = pycolmap.Reconstruction()
    flip = np.diag([1.0, -1.0, -1.0])  # BAL camera (y up, looks along -z) -> COLMAP
    used_cams = np.unique(cam_idx)
    rot = rodrigues(bal.cameras[:, :3])
    half = np.abs(xy).max() + 10
    per_image: dict[int, list[int]] = {int(c): [] for c in used_cams}
    for k, c in enumerate(cam_idx.tolist()):
        per_image[c].append(k)
    point2d_of = np.empty(len(cam_idx), np.int64)
    for c in used_cams.tolist():
        f, k1, k2 = bal.cameras[c, 6:9]
        cam = pycolmap.Camera(camera_id=c + 1, model="RADIAL", width=int(2 * half),
                              height=int(2 * half), params=[f, 0.0, 0.0, k1, k2])
        rec.add_camera_with_trivial_rig(cam)
        rows = per_image[c]
        point2d_of[rows] = np.arange(len(rows))
        pts2d = [pycolmap.Point2D(np.array([xy[k, 0], -xy[k, 1]])) for k in rows]
        image = pycolmap.Image(name=f"{c}", points2D=pycolmap.Point2DList(pts2d),
                               camera_id=c + 1, image_id=c + 1)
        pose = pycolmap.Rigid3d(pycolmap.Rotation3d(flip @ rot[c]), flip @ bal.cameras[c, 3:6])
        rec.add_image_with_trivial_frame(image, pose)
    order = np.argsort(pt_idx, kind="stable")
    bounds = np.flatnonzero(np.diff(pt_idx[order])) + 1
    for group in np.split(order, bounds):
        if len(group) < 2:
            continue
        track = pycolmap.Track()
        for k in group.tolist():
            track.add_element(int(cam_idx[k]) + 1, int(point2d_of[k]))
        rec.add_point3D(bal.points[pt_idx[group[0]]], track)
    opts = pycolmap.BundleAdjustmentOptions()
    opts.refine_focal_length = refine
    opts.refine_principal_point = False
    opts.refine_extra_params = refine
    opts.print_summary = False
    opts.ceres.loss_function_type = pycolmap.LossFunctionType.TRIVIAL
    so = opts.ceres.solver_options
    so.max_num_iterations = max_iterations
    so.function_tolerance = 1e-12
    so.gradient_tolerance = 1e-12
    so.parameter_tolerance = 1e-12
    cfg = pycolmap.BundleAdjustmentConfig()
    for iid in rec.reg_image_ids():
        cfg.add_image(iid)
    cfg.fix_gauge(pycolmap.BundleAdjustmentGauge.TWO_CAMS_FROM_WORLD)
    t0 = time.perf_counter()
    ba = pycolmap.create_default_ceres_bundle_adjuster(opts, cfg, rec)
    summary = ba.solve()
    dt = time.perf_counter() - t0
    cs = summary.ceres_summary
    return cs.initial_cost, cs.final_cost, cs.num_successful_steps + cs.num_unsuccessful_steps, \
        dt, cs.termination_type


def measure(path: Path, refine: bool = False, repeat: int = 1, warm: bool = True) -> dict:
    """One BAL problem solved by both engines in this process: the median of `repeat` solves
    of each (`warm`: one untimed baarda solve first, in which numba loads its kernels)."""
    bal = read_bal(path)
    block, dropped = drop_points_behind(bal_to_block(bal, name=path.name, calibrate=refine))
    # the observations both solvers use: points with two or more rays
    rays = np.bincount(block.image.point, minlength=len(block.points))
    keep = rays[block.image.point] >= 2
    block = block.select_image(keep)
    im = block.image
    if warm:
        adjust_free(block, options=replace(SOLVE, max_iterations=100))
    times, times_col = [], []
    for _ in range(repeat):  # the median of `repeat` solves of each engine
        t0 = time.perf_counter()
        res = adjust_free(block, options=replace(SOLVE, max_iterations=100))
        times.append(time.perf_counter() - t0)
        ini, fin, its, t_col, term = run_pycolmap(bal, im.photo, im.point,
                                                  im.xy_mm / 0.001, refine=refine)
        times_col.append(t_col)
    return {"file": path.name, "obs": len(im), "dropped": dropped, "initial": ini,
            "cost": 0.5 * res.vtpv,  # sigma 1 px: residuals in px
            "iterations": res.iterations, "seconds": float(np.median(times)),
            "colmap_cost": fin, "colmap_iterations": its,
            "colmap_seconds": float(np.median(times_col)), "termination": str(term),
            "converged": bool(res.converged)}


def main(paths: list[str]) -> int:
    refine = "--intrinsics" in paths
    repeat = 1
    if "--repeat" in paths:
        k = paths.index("--repeat")
        repeat = int(paths[k + 1])
        del paths[k:k + 2]
    paths = [p for p in paths if p != "--intrinsics"]
    files = [Path(p) for p in paths] or [DEFAULT / f for f in FILES]
    rows = []
    for path in files:
        if not path.is_file():
            print(f"{path}: not found (BAL files are not in the repository)")
            continue
        rows.append(measure(path, refine, repeat, warm=not rows))
    print(f"{'file':32s} {'obs':>7s} {'drop':>5s} {'initial':>12s} {'baarda cost':>14s} "
          f"{'it':>3s} {'time s':>7s} {'COLMAP cost':>14s} {'it':>3s} {'time s':>7s} "
          f"{'rel.diff':>9s} {'t ratio':>7s}")
    for r in rows:
        rel = (r["cost"] - r["colmap_cost"]) / r["colmap_cost"]
        print(f"{r['file']:32s} {r['obs']:7d} {r['dropped']:5d} {r['initial']:12.6g} "
              f"{r['cost']:14.8g} {r['iterations']:3d} {r['seconds']:7.2f} "
              f"{r['colmap_cost']:14.8g} {r['colmap_iterations']:3d} {r['colmap_seconds']:7.2f} "
              f"{rel:9.1e} {r['seconds'] / r['colmap_seconds']:7.2f}"
              f"{'' if r['converged'] else '  (baarda NOT converged)'}  [{r['termination']}]")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
