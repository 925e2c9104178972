"""The bundle block adjustment as a least-squares problem of the one solver.

A BundleProblem is the block in the form of the adjustment: which image points and control
coordinates are observations, their a-priori standard deviations, the flat observation
vector of the quality layer and the structure of the reduced normal equations.  It never
changes: `reweighted(active, factors)` is a new problem with other components switched off
(data snooping) or re-weighted (robust estimation), sharing everything else, and `fit()`
returns a new BundleResult.
"""

from __future__ import annotations

import time

import numpy as np

from baarda.adjustment.schur import HOLD, Linearization, SchurSystem
from baarda.adjustment.schur_model import FlatLayout
from baarda.adjustment.schur_problem import SchurProblem, read_only
from baarda.adjustment.solve import solve
from baarda.block.camera import corrected_observations, forward_coefficients
from baarda.block.photo_block import Block
from baarda.bundle.bundle_result import BundleResult
from baarda.bundle.collinearity import camera_depth, project_with_jacobians
from baarda.bundle.geometry import approximate_points, check_datum, usable_points
from baarda.errors import GeometryError
from baarda.options import Progress, SolveOptions

# converged when the correction is below 1e-7 of the flying height (positions and points)
# and 1e-10 rad (angles): correction_size weighs angles by 1000 / rad
SOLVE = SolveOptions(max_iterations=50, tolerance=1e-7, min_step=1e-3)
XY = np.array(["x", "y"], dtype=object)
XYZ = np.array(["X", "Y", "Z"], dtype=object)


def _spread(values: np.ndarray) -> str:
    """'5' or '3 to 8 (median 5)' for a list of standard deviations."""
    lo, hi = float(values.min()), float(values.max())
    if np.isclose(lo, hi, rtol=1e-6):
        return f"{lo:.3g}"
    return f"{lo:.3g} to {hi:.3g} (median {float(np.median(values)):.3g})"


class BundleProblem(SchurProblem):
    """The block in the form of the adjustment: index arrays, weights, the Schur structure.

    Observation vector (flat, the quality layer's): x and y of every adjusted image point
    (rows `obs` of block.image, mm), then every observed control coordinate (m).
    held: (n_photos, 6) bool of orientation unknowns held by datum constraints (a free
    network, bundle/free_network.py); None: the control fixes the datum (checked here).
    diagnosis: findings about the inputs (bundle/diagnostics.py), printed as notes and added
    to the message when the adjustment fails.
    """

    def __init__(self, block: Block, *, held: np.ndarray | None = None,
                 notes: tuple[str, ...] = (), diagnosis: tuple[str, ...] = ()):
        self.block = block
        self.diagnosis = tuple(diagnosis)
        ok, point_notes = usable_points(block)
        im, pts = block.image, block.points
        self.obs = np.flatnonzero(ok[im.point])  # rows of block.image in the adjustment
        self.point_ids = np.flatnonzero(ok)  # block point index of each adjusted point
        remap = np.full(len(pts), -1)
        remap[self.point_ids] = np.arange(len(self.point_ids))
        self.remap = remap
        self.control = np.flatnonzero((pts.role == "control") & ok)  # block point indices
        sig_c = pts.sigma[self.control]
        m, nc = len(self.obs), len(self.control)
        self.layout = FlatLayout(m, 2, nc, 3, np.flatnonzero(np.isfinite(sig_c).ravel()))
        sel = self.layout.ctrl_sel
        self.sigma_apriori = read_only(np.concatenate([im.sigma_xy[self.obs].ravel(),
                                                        sig_c.ravel()[sel]]))
        self.held = None if held is None else read_only(np.asarray(held, bool))
        warnings = [] if self.held is not None else check_datum(
            block, ok & np.isin(np.arange(len(pts)), self.control))
        self.notes = self.diagnosis + tuple(warnings) + tuple(point_notes) + tuple(notes)
        self._labels(block, m, sel)
        # observations corrected for backward (observation-side) distortion; forward model
        # rows as observed (the projection applies that model)
        self.xy_obs = corrected_observations(block)[self.obs]
        ph = im.photo[self.obs]
        self.distortion = forward_coefficients(block.cameras, block.photos.camera[ph])
        self.system = SchurSystem(
            len(block.photos), 6, len(self.point_ids), 3, ph, remap[im.point[self.obs]],
            remap[self.control], frame_names=[f"photo {p}" for p in block.photos.ids],
            point_names=[pts.ids[j] for j in self.point_ids],
            n_fixed=0 if self.held is None else int(self.held.sum()))
        eo = block.photos.eo
        keep = np.isin(np.arange(len(pts)), self.point_ids)
        xyz = approximate_points(block, keep)[self.point_ids]
        self.approximations = (read_only(eo.copy()), read_only(xyz))
        # the size of the block for the convergence test: the flying height
        self.scale = max(float(np.median(np.abs(eo[:, 2] - np.median(xyz[:, 2])))), 1.0)
        n = self.layout.n
        self._set_weights(np.ones(n, bool), np.ones(n))

    def _labels(self, block: Block, m: int, sel: np.ndarray) -> None:
        im = block.image
        nc = len(sel)
        photos = np.asarray(block.photos.ids, dtype=object)
        pids = np.asarray(block.points.ids, dtype=object)
        self.kind = read_only(np.array(["image"] * (2 * m) + ["control"] * nc, dtype=object))
        self.component = read_only(np.concatenate(
            [np.tile(XY, m), np.tile(XYZ, len(self.control))[sel]]))
        self.frame = read_only(np.concatenate([np.repeat(photos[im.photo[self.obs]], 2),
                                                np.full(nc, "", dtype=object)]))
        self.point = read_only(np.concatenate([np.repeat(pids[im.point[self.obs]], 2),
                                                np.repeat(pids[self.control], 3)[sel]]))
        self.group = read_only(np.concatenate([np.repeat(np.arange(m), 2), np.full(nc, -1)]))
        # index of each component back into block tables
        self.image_row = read_only(np.concatenate([np.repeat(self.obs, 2), np.full(nc, -1)]))
        self.control_index = read_only(np.concatenate(
            [np.full(2 * m, -1), np.repeat(self.control, 3)[sel]]))

    def datum_text(self) -> str:
        """What fixes the datum, in words (the summary's second line)."""
        c = self.block.points.controlled[self.control]
        return (f"datum: the control, {int((c[:, 0] & c[:, 1]).sum())} planimetric and "
                f"{int(c[:, 2].sum())} height control point(s)")

    def apriori_text(self) -> str:
        """The a-priori standard deviations in use (image µm, control m), in words."""
        sig = self.sigma_apriori
        img = sig[self.kind == "image"] * 1e3
        parts = [f"image {_spread(img)} µm"] if len(img) else []
        for c in "XYZ":
            s = sig[(self.kind == "control") & (self.component == c)]
            if len(s):
                parts.append(f"control {c} {_spread(s)} m")
        return "a-priori sigmas: " + ", ".join(parts)

    # ------------------------------------------------- the solver's protocol
    def linearize(self, state: tuple[np.ndarray, np.ndarray]) -> Linearization:
        eo, xyz = state
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
        jc = np.broadcast_to(np.eye(3), (len(self.control), 3, 3)).copy()
        wf = ef = None
        if self.held is not None:
            je = np.where(self.held[ph][:, None, :], 0.0, je)
            wf = np.where(self.held, HOLD, 0.0)
            ef = np.zeros_like(wf)
        return Linearization(je, jp, self.w, e, jc, self.wc, ec, wf, ef)

    def _sizes(self, step, t: float = 1.0) -> tuple[float, float]:
        dxf, dxp = step
        dpos = max(np.max(np.abs(dxf[:, :3]), initial=0.0), np.max(np.abs(dxp), initial=0.0))
        return t * float(dpos), t * float(np.max(np.abs(dxf[:, 3:]), initial=0.0))

    def correction_size(self, state, step) -> float:
        dpos, dang = self._sizes(step)
        return max(dpos / self.scale, 1e3 * dang)

    def describe(self, state, step, t: float) -> str:
        dpos, dang = self._sizes(step, t)
        return f"{dpos:.3g} m, {dang:.3g} rad"

    def admissible(self, state) -> bool:
        eo, xyz = state
        im = self.block.image
        return bool(np.all(camera_depth(eo, xyz[self.remap[im.point[self.obs]]],
                                        im.photo[self.obs]) > 0))

    # ------------------------------------------------------------ fit
    def fit(self, start: tuple[np.ndarray, np.ndarray] | None = None,
            options: SolveOptions = SOLVE, progress: Progress | None = None) -> BundleResult:
        """Adjust; returns a BundleResult (arrays plus summary()).

        start: (eo (n_photos, 6), xyz (n_adjusted_points, 3)); default the approximations
        (the photos' EO and intersected points).
        """
        t0 = time.perf_counter()
        start = self.approximations if start is None else start
        try:
            sol = solve(self, (np.array(start[0], float), np.array(start[1], float)),
                        options, progress)
            if sol.reason == "inadmissible":
                raise GeometryError("the adjustment diverged: no step along the Gauss-Newton "
                                    "direction keeps the points in front of the cameras; check "
                                    "the approximate orientations and the identification of "
                                    "points")
        except GeometryError as e:
            if not self.diagnosis:
                raise
            raise GeometryError(f"{e}. Likely cause: " + "; ".join(self.diagnosis)) from None
        notes = list(self.notes) + ([] if sol.converged else [sol.message])
        eo, xyz = sol.state
        return BundleResult(self, eo, xyz, sol.lin, sol.factor, sol.iterations, sol.converged,
                            tuple(notes), time.perf_counter() - t0)
