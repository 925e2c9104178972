"""Bundle block adjustment by the collinearity equations (Gauss-Newton, sparse Schur)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from baarda.adjustment.schur import Linearization, SchurSystem
from baarda.block.camera import corrected_observations, forward_coefficients
from baarda.block.photo_block import Block
from baarda.bundle.bundle_result import BundleResult
from baarda.bundle.collinearity import camera_depth, project_with_jacobians
from baarda.bundle.geometry import approximate_points, check_datum, usable_points
from baarda.errors import GeometryError

Progress = Callable[[str], None]


class BundleProblem:
    """The block in the form of the adjustment: index arrays, weights, the Schur structure.

    `image_keep` and `control_keep` switch single observation components off (data snooping
    rejects them) without changing the structure.  `needs_control` = False (free networks,
    bundle/free.py) skips the check that the control fixes the datum.
    """

    needs_control = True

    def __init__(self, block: Block, image_keep: np.ndarray | None = None,
                 control_keep: np.ndarray | None = None):
        self.block = block
        ok, self.notes = usable_points(block)
        im = block.image
        use_obs = ok[im.point]
        self.obs = np.flatnonzero(use_obs)  # rows of block.image in the adjustment
        self.point_ids = np.flatnonzero(ok)  # block point index of each adjusted point
        remap = np.full(len(block.points), -1)
        remap[self.point_ids] = np.arange(len(self.point_ids))
        self.remap = remap
        pts = block.points
        ctrl = np.flatnonzero((pts.role == "control") & ok)
        self.control = ctrl  # block point index of each control point
        sig = pts.sigma[ctrl]
        self.wc_full = np.where(np.isfinite(sig), 1.0 / np.where(np.isfinite(sig), sig, 1) ** 2,
                                0.0)
        s = im.sigma_mm[self.obs]
        self.w_full = np.repeat((1.0 / s**2)[:, None], 2, axis=1)
        self.image_keep = (np.ones((len(im), 2), bool) if image_keep is None
                           else np.asarray(image_keep, bool))
        self.control_keep = (np.ones((len(pts), 3), bool) if control_keep is None
                             else np.asarray(control_keep, bool))
        # weight factors of robust re-weighting (Danish method); 1 = a-priori weight
        self.image_factor = np.ones((len(im), 2))
        self.control_factor = np.ones((len(pts), 3))
        if self.needs_control:
            check_datum(block, ok & np.isin(np.arange(len(pts)), self.control)
                        & (self.control_keep.any(axis=1)))
        # observations corrected for backward (observation-side) distortion; forward model
        # rows as observed (the projection applies that model)
        self.xy_obs = corrected_observations(block)[self.obs]
        self.distortion = forward_coefficients(block.cameras,
                                               block.photos.camera[im.photo[self.obs]])
        self.system = SchurSystem(
            len(block.photos), 6, len(self.point_ids), 3,
            im.photo[self.obs], remap[im.point[self.obs]], remap[ctrl],
            frame_names=[f"photo {p}" for p in block.photos.ids],
            point_names=[pts.ids[j] for j in self.point_ids])

    @property
    def weights(self) -> tuple[np.ndarray, np.ndarray]:
        w = self.w_full * self.image_keep[self.obs] * self.image_factor[self.obs]
        wc = self.wc_full * self.control_keep[self.control] * self.control_factor[self.control]
        return w, wc

    def linearize(self, eo: np.ndarray, xyz: np.ndarray) -> Linearization:
        b = self.block
        im = b.image
        ph = im.photo[self.obs]
        cam = b.photos.camera[ph]
        xy, je, jp = project_with_jacobians(eo, xyz[self.remap[im.point[self.obs]]],
                                            b.cameras.focal_mm[cam],
                                            b.cameras.principal_point_mm[cam],
                                            self.distortion, photo=ph)
        e = self.xy_obs - xy
        given = b.points.xyz[self.control]
        ec = np.where(np.isfinite(given), given, 0.0) - xyz[self.remap[self.control]]
        w, wc = self.weights
        jc = np.broadcast_to(np.eye(3), (len(self.control), 3, 3)).copy()
        return Linearization(je, jp, w, e, jc, wc, ec)


def _cost(lin: Linearization) -> float:
    return float(np.sum(lin.w * lin.e**2) + np.sum(lin.wc * lin.ec**2))


def adjust(block: Block, *, max_iterations: int = 50,
           image_keep: np.ndarray | None = None, control_keep: np.ndarray | None = None,
           problem: BundleProblem | None = None, start: tuple | None = None,
           progress: Progress | None = None) -> BundleResult:
    """Adjust `block`; returns a BundleResult (arrays plus summary()).

    Gauss-Newton with step halving when the weighted sum of squares grows.  Converged when
    the next correction is below 1e-7 of the flying height (positions and points) and
    1e-10 rad (angles); the solution is then the last point of linearisation, so residuals,
    Jacobians and the factored normal equations used by the statistics belong together.
    """
    t0 = time.perf_counter()
    say = progress or (lambda msg: None)
    if problem is None:
        problem = BundleProblem(block, image_keep, control_keep)
    notes = list(problem.notes)
    if start is None:
        eo = block.photos.eo.copy()
        xyz = approximate_points(block, np.isin(np.arange(len(block.points)),
                                                problem.point_ids))[problem.point_ids]
    else:
        eo, xyz = (a.copy() for a in start)
    system = problem.system
    scale = max(float(np.median(np.abs(eo[:, 2] - np.median(xyz[:, 2])))), 1.0)
    lin = problem.linearize(eo, xyz)
    cost = _cost(lin)
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        system.factorize(lin)
        dxf, dxp = system.solve()
        dpos = max(np.max(np.abs(dxf[:, :3]), initial=0.0), np.max(np.abs(dxp), initial=0.0))
        dang = np.max(np.abs(dxf[:, 3:]), initial=0.0)
        if dpos < 1e-7 * scale and dang < 1e-10:
            # the correction is negligible: keep the point of linearisation, whose normal
            # equations are factored, as the solution (consistent for the quality analysis)
            say(f"iteration {it}: converged, vTPv = {cost:.6g}, remaining correction "
                f"{dpos:.3g} m, {dang:.3g} rad")
            converged = True
            break
        step = 1.0
        for _ in range(30):
            eo_new, xyz_new = eo + step * dxf, xyz + step * dxp
            if np.all(camera_depth(eo_new, xyz_new[problem.remap[block.image.point[problem.obs]]],
                                   block.image.photo[problem.obs]) > 0):
                lin_new = problem.linearize(eo_new, xyz_new)
                cost_new = _cost(lin_new)
                if cost_new <= cost * (1 + 1e-12) or step < 1e-3:
                    break
            step *= 0.5
        else:
            raise GeometryError("the adjustment diverged: no step along the Gauss-Newton "
                                "direction keeps the points in front of the cameras; check the "
                                "approximate orientations and the identification of points")
        eo, xyz, lin = eo_new, xyz_new, lin_new
        cost = cost_new
        say(f"iteration {it}: vTPv = {cost:.6g}, max correction {step * dpos:.3g} m, "
            f"{step * dang:.3g} rad" + ("" if step == 1 else f" (step {step:g})"))
        if not np.isfinite(cost):
            raise GeometryError("the adjustment diverged (non-finite residuals)")
    else:
        system.factorize(lin)  # normal equations at the last estimate, for the statistics
    if not converged:
        notes.append(f"not converged after {max_iterations} iterations")
    return BundleResult(block=block, problem=problem, eo=eo, xyz=xyz, lin=lin,
                        iterations=it, converged=converged, notes=notes,
                        seconds=time.perf_counter() - t0)
