"""BAL with f, k1, k2 free per camera (issue 13): baarda's self-calibrating bundle reaches the
cost that pycolmap (COLMAP's bundle adjustment on Ceres) reaches with refined intrinsics, in
the same run (benchmarks/bench_bal.py --intrinsics does the real BAL files)."""

import numpy as np
import pytest

from baarda.bundle.free_network import adjust_free
from baarda.io.bal import BalProblem, bal_to_block, bal_with_block, rodrigues

pycolmap = pytest.importorskip("pycolmap")


def colmap_cost(bal: BalProblem, refine: bool) -> float:
    """Final cost 0.5 sum r^2 [px^2] of COLMAP's BA of a BAL problem (RADIAL cameras, one
    per image, gauge: two cameras)."""
    rec = pycolmap.Reconstruction()
    flip = np.diag([1.0, -1.0, -1.0])  # BAL camera (y up, looks along -z) -> COLMAP
    rot = rodrigues(bal.cameras[:, :3])
    xy = bal.obs_xy
    half = float(np.abs(xy).max() + 10)
    rows_of = {c: np.flatnonzero(bal.obs_camera == c) for c in range(len(bal.cameras))}
    point2d = np.empty(len(xy), np.int64)
    for c, rows in rows_of.items():
        f, k1, k2 = bal.cameras[c, 6:9]
        cam = pycolmap.Camera(camera_id=c + 1, model="RADIAL", width=int(2 * half),
                              height=int(2 * half), params=[f, 0.0, 0.0, k1, k2])
        rec.add_camera_with_trivial_rig(cam)
        point2d[rows] = np.arange(len(rows))
        pts = [pycolmap.Point2D(np.array([xy[k, 0], -xy[k, 1]])) for k in rows]
        image = pycolmap.Image(name=str(c), points2D=pycolmap.Point2DList(pts),
                               camera_id=c + 1, image_id=c + 1)
        rec.add_image_with_trivial_frame(image, pycolmap.Rigid3d(
            pycolmap.Rotation3d(flip @ rot[c]), flip @ bal.cameras[c, 3:6]))
    for j in range(len(bal.points)):
        track = pycolmap.Track()
        for k in np.flatnonzero(bal.obs_point == j).tolist():
            track.add_element(int(bal.obs_camera[k]) + 1, int(point2d[k]))
        rec.add_point3D(bal.points[j], track)
    opts = pycolmap.BundleAdjustmentOptions()
    opts.refine_focal_length = refine
    opts.refine_principal_point = False
    opts.refine_extra_params = refine
    opts.print_summary = False
    opts.ceres.loss_function_type = pycolmap.LossFunctionType.TRIVIAL
    so = opts.ceres.solver_options
    so.max_num_iterations = 200
    so.function_tolerance = so.gradient_tolerance = so.parameter_tolerance = 1e-15
    cfg = pycolmap.BundleAdjustmentConfig()
    for iid in rec.reg_image_ids():
        cfg.add_image(iid)
    cfg.fix_gauge(pycolmap.BundleAdjustmentGauge.TWO_CAMS_FROM_WORLD)
    summary = pycolmap.create_default_ceres_bundle_adjuster(opts, cfg, rec).solve()
    return float(summary.ceres_summary.final_cost)


@pytest.mark.parametrize("refine", [True, False])
def test_final_cost_equals_colmap(refine):
    from bal_reference import _synthetic, bal_residuals

    p = _synthetic(seed=7, ncam=8, npt=80)
    rng = np.random.default_rng(1)
    start = BalProblem(p.cameras.copy(), p.points + rng.normal(0, 0.02, p.points.shape),
                       p.obs_camera, p.obs_point, p.obs_xy)
    start.cameras[:, 6] *= 1.01  # intrinsics off a little: something to refine
    res = adjust_free(bal_to_block(start, calibrate=refine))
    assert res.converged
    ours = 0.5 * res.vtpv  # sigma 1 px: residuals in px
    out = bal_with_block(start, res.eo, res.points_xyz(), res.cameras)
    assert np.isclose(0.5 * np.sum(bal_residuals(out) ** 2), ours, rtol=1e-10)
    theirs = colmap_cost(start, refine)
    assert abs(ours - theirs) <= 1e-8 * theirs, (ours, theirs)
