"""The bundle block adjustment as a least-squares problem of the one solver.

A BundleProblem is the block in the form of the adjustment: which image points and control
coordinates are observations, their a-priori standard deviations, the flat observation
vector of the quality layer and the structure of the reduced normal equations.  It never
changes: `reweighted(active, factors)` is a new problem with other components switched off
(data snooping) or re-weighted (robust estimation), sharing everything else, and `fit()`
returns a new BundleResult.
"""

from __future__ import annotations

import copy
import time
from typing import cast

import numpy as np

from baarda.adjustment.schur_model import FlatLayout
from baarda.adjustment.schur_problem import SchurProblem, read_only
from baarda.adjustment.schur_system import HOLD, Linearization, SchurSystem
from baarda.adjustment.solve import solve_continued, solve_notes
from baarda.block.photo_block import Block
from baarda.block.rotation import rotation_and_derivatives, rotation_matrix
from baarda.bundle.bundle_result import BundleResult
from baarda.bundle.calibration import Calibration
from baarda.bundle.collinearity import camera_depth
from baarda.bundle.geometry import approximate_points, check_datum, usable_points
from baarda.bundle.image_rows import ImageRows
from baarda.bundle.kind_gnss_imu import GnssImuRows
from baarda.bundle.kind_image import BorderImageRows
from baarda.bundle.observation_kinds import Context, GlobalLayout, ObservationKind, State
from baarda.bundle.registered_kinds import registered_kinds
from baarda.bundle.result_text import photo_unknown_names
from baarda.errors import GeometryError
from baarda.kinds import CONTROL, IMAGE, KINDS
from baarda.options import Progress, SolveOptions

# converged when the correction is below 1e-7 of the flying height (positions and points)
# and 1e-10 rad (angles): correction_size weighs angles by 1000 / rad; or, when no step
# along a correction below 1e-6 lowers v'Pv any more, at the rounding floor of v'Pv (a
# block of 1 µm image sigmas: a 5e-7 correction changes v'Pv by less than its rounding)
SOLVE = SolveOptions(max_iterations=50, tolerance=1e-7, min_step=1e-3, stall_tolerance=1e-6)
SOLVE_LM = SolveOptions(max_iterations=100, tolerance=1e-7, min_step=1e-3, damping=1e-3,
                        stall_tolerance=1e-6)
DAMPING = {"gn": SOLVE, "lm": SOLVE_LM}  # --damping: Gauss-Newton or Levenberg-Marquardt
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

    Unknowns: the photos' orientations (frames: X0, Y0, Z0, omega, phi, kappa, then the
    free parameters of a camera that only this photo uses, bundle/calibration.py), the
    ground points eliminated point by point, and the global unknowns
    (adjustment/schur_system.py): the free parameters of the cameras that several photos
    share, then the coordinates of the points that distance observations tie together
    (border points).

    Observation vector (flat, the quality layer's): x and y of every adjusted image point of
    an eliminated point (rows `obs` of block.image, mm), every observed control coordinate of
    an eliminated point (m), then the extra rows of every observation kind in turn
    (bundle/observation_kinds.py: the x and y of the image points of border points, their
    observed control coordinates, the distances (m), GNSS positions and IMU attitudes, then
    the `kinds` given); `extra_rows` their ranges among the extra rows (`extra_range` and
    `rows_of` by the kind's name).
    Control with sigma 0 is fixed: held exactly, not an unknown, not an observation.
    held: (n_photos, 6) bool of orientation unknowns held by datum constraints (a free
    network, bundle/free_network.py); None: the control fixes the datum (checked here).
    held_frame: (n_photos, b) every held column of the photos' blocks (held, and the camera
    columns of photos without a camera of their own), or None.
    diagnosis: findings about the inputs (bundle/diagnostics.py), printed as notes and added
    to the message when the adjustment fails.  intersected: the block's points intersected
    from its approximate orientations (geometry.intersected_points), when known.
    """

    def __init__(self, block: Block, *, held: np.ndarray | None = None,
                 notes: tuple[str, ...] = (), diagnosis: tuple[str, ...] = (),
                 intersected: np.ndarray | None = None,
                 kinds: tuple[ObservationKind, ...] = ()):
        self.block = block
        self.solve_options = SOLVE  # every fit of this problem and its re-weightings
        self.diagnosis = tuple(diagnosis)
        ok, point_notes = usable_points(block)
        im, pts = block.image, block.points
        self.point_ids = np.flatnonzero(ok)  # block point index of each adjusted point
        remap = np.full(len(pts), -1)
        remap[self.point_ids] = np.arange(len(self.point_ids))
        self.remap = remap
        # the observation kinds of the extra rows (bundle/registered_kinds.py: the image
        # points and control of the border points, distances, GNSS/IMU), and `kinds`
        self.kinds = (*registered_kinds(ok), *kinds)
        names = [kind.name for kind in self.kinds]
        if len(set(names)) < len(names) or {"camera", "points"} & set(names):
            raise ValueError(f"observation kinds need names of their own: {names}")
        # points that a kind ties together (distances) are border (global) unknowns
        border = np.zeros(len(pts), bool)
        for kind in self.kinds:
            border[kind.tied_points(block)] = True
        border &= ok
        self.border_ids = np.flatnonzero(border)  # block indices, global points
        self.elim_ids = np.flatnonzero(ok & ~border)  # block indices, eliminated points
        self.eremap = np.full(len(pts), -1)
        self.eremap[self.elim_ids] = np.arange(len(self.elim_ids))
        self.bremap = np.full(len(pts), -1)
        self.bremap[self.border_ids] = np.arange(len(self.border_ids))
        rows = np.flatnonzero(ok[im.point])
        self.obs = rows[~border[im.point[rows]]]  # rows of block.image, eliminated points
        is_control = (pts.role == "control") & ok
        self.control = np.flatnonzero(is_control & ~border)  # block indices
        self.border_control = border_control = np.flatnonzero(is_control & border)
        sig_c, sig_b = pts.sigma[self.control], pts.sigma[border_control]
        observed_c = np.isfinite(sig_c) & (sig_c > 0)
        # fixed control (sigma 0): held exactly
        self.held_points = np.zeros((len(self.elim_ids), 3), bool)
        self.held_points[self.eremap[self.control]] = np.isfinite(sig_c) & (sig_c == 0)
        self.held_border = np.zeros((len(self.border_ids), 3), bool)
        self.held_border[self.bremap[border_control]] = np.isfinite(sig_b) & (sig_b == 0)
        # global unknowns, a named layout: free camera parameters, the border points'
        # coordinates, then each kind's own (GNSS shifts and drifts, IMU boresight)
        self.calibration = cal = Calibration(block.cameras, block.photos.camera,
                                             free=block.settings.calibration_free)
        self.b = 6 + cal.photo_width  # unknowns of a photo (its camera's, if its own)
        own = [(kind.name, kind.global_labels(block)) for kind in self.kinds]
        own = [(name, labels) for name, labels in own if labels or name == "gnss_imu"]
        self.global_layout = GlobalLayout(
            ("camera", "points", *(name for name, _ in own)),
            (cal.n_global, 3 * len(self.border_ids), *(len(la) for _, la in own)),
            tuple(cal.global_labels + [f"coordinate {c} of point {pts.ids[j]}"
                                       for j in self.border_ids for c in "XYZ"]
                  + [label for _, labels in own for label in labels]))
        ng = self.global_layout.n
        context = Context(block, self.calibration, self.global_layout, self.border_ids,
                          self.bremap)
        self.extra = tuple(kind.bind(context) for kind in self.kinds)
        ends = np.cumsum([0] + [r.m for r in self.extra])
        self.extra_rows = tuple(slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:],
                                                                      strict=True))
        # each kind's rows and their range among the extra rows, by the kind's name
        self.rows_of = dict(zip(names, self.extra, strict=True))
        self.extra_range = dict(zip(names, self.extra_rows, strict=True))
        self.border_images = cast(BorderImageRows, self.rows_of["border_images"])
        self.gnss_imu = cast(GnssImuRows, self.rows_of["gnss_imu"]).gnss_imu
        m, nc = len(self.obs), len(self.control)
        self.layout = FlatLayout(m, 2, nc, 3, np.flatnonzero(observed_c.ravel()),
                                 int(ends[-1]), 1)
        sel = self.layout.ctrl_sel
        self.sigma_apriori = read_only(np.concatenate([
            im.sigma_xy[self.obs].ravel(), sig_c.ravel()[sel],
            *(r.sigma for r in self.extra)]))
        self.held = None if held is None else read_only(np.asarray(held, bool))
        held_frame: np.ndarray | None = None
        if self.held is not None or cal.held_photo_columns.any():
            held_frame = np.zeros((len(block.photos), self.b), bool)
            if self.held is not None:
                held_frame[:, :6] = self.held
            held_frame[:, 6:] = cal.held_photo_columns
        self.held_frame = None if held_frame is None else read_only(held_frame)
        # of each image row of an eliminated point: photo, point (eliminated index), xy
        self.obs_photo = read_only(im.photo[self.obs])
        self.obs_point = read_only(self.eremap[im.point[self.obs]])
        self.obs_xy = read_only(im.xy_mm[self.obs])
        self.held_rows = read_only(np.zeros(0, np.int64) if held_frame is None else
                                   np.flatnonzero(np.any(held_frame, axis=1)[self.obs_photo]))
        # GNSS positions carry the datum (with shifts as unknowns: scale and orientation,
        # the position then from a control point)
        full_control = bool(pts.controlled[np.concatenate(
            [self.control, border_control])].all(axis=1).any())
        by_gnss = len(block.gnss) >= 3 and (block.settings.gnss_offsets == "none"
                                            or full_control)
        warnings = [] if self.held is not None or by_gnss else check_datum(
            block, ok & np.isin(np.arange(len(pts)), np.concatenate(
                [self.control, border_control])))
        self.notes = self.diagnosis + tuple(warnings) + tuple(point_notes) + tuple(notes)
        self._labels(block, sel)
        ph = im.photo[self.obs]
        self.camera_of = block.photos.camera  # camera of each photo
        # what the linearisation needs of each row set that no iteration changes
        self.image_rows = ImageRows(block, self.calibration, self.obs)
        cam = self.camera_of[ph]
        table = np.full((len(block.cameras), cal.width), -1, np.int64)  # columns per camera
        for i, cols in enumerate(cal.columns):
            table[i, :len(cols)] = cols
        gcol = table[cam]
        x_frame = np.concatenate([r.photo for r in self.extra]).astype(np.int64)
        n_fixed = (0 if self.held_frame is None else int(self.held_frame.sum())) + \
            int(self.held_points.sum()) + int(self.held_border.sum())
        self.system = SchurSystem(
            len(block.photos), self.b, len(self.elim_ids), 3, ph, self.eremap[im.point[self.obs]],
            self.eremap[self.control], frame_names=[f"photo {p}" for p in block.photos.ids],
            point_names=[pts.ids[j] for j in self.elim_ids], n_fixed=n_fixed, ng=ng,
            gcol=gcol, x_frame=x_frame, global_names=list(self.global_layout.labels),
            column_names=self._column_names)
        # held global columns (fixed control of border points) and their held values
        self.held_globals = self.global_layout.start("points") + np.flatnonzero(
            self.held_border.ravel())
        eo = block.photos.eo
        keep = np.isin(np.arange(len(pts)), self.point_ids)
        xyz = approximate_points(block, keep, intersected)
        frames = np.hstack([eo, cal.photo_start()]) if cal.photo_width else eo.copy()
        start: tuple[np.ndarray, ...] = (read_only(frames), read_only(xyz[self.elim_ids]))
        if ng:
            g0 = np.zeros(ng)
            g0[self.global_layout.columns("camera")] = self.calibration.start()
            g0[self.global_layout.columns("points")] = xyz[self.border_ids].ravel()
            start += (read_only(g0),)
        self.approximations = start
        # the size of the block for the convergence test: the flying height
        self.scale = max(float(np.median(np.abs(eo[:, 2] - np.median(xyz[keep, 2])))), 1.0)
        n = self.layout.n
        self._set_weights(np.ones(n, bool), np.ones(n))
        self._parameter_scale, self._photo_scale = self._camera_effect()

    def _column_names(self, k: int) -> list[str]:
        """The names of photo k's unknowns: its orientation, then the free parameters of
        the camera in its block (held columns named as such)."""
        names = photo_unknown_names(self.block, self.calibration, k)
        return names + ["(held)"] * (self.b - len(names))

    @property
    def units(self) -> dict[str, tuple[float, str]]:
        """How each kind is shown: kind -> (factor to the shown unit, unit)."""
        out = {IMAGE.name: IMAGE.shown(), CONTROL.name: CONTROL.shown()}
        for r in self.extra:
            out.update(r.units)
        return out

    def _labels(self, block: Block, sel: np.ndarray) -> None:
        im = block.image
        m, nc = len(self.obs), len(sel)
        photos = np.asarray(block.photos.ids, dtype=object)
        pids = np.asarray(block.points.ids, dtype=object)
        x = self.extra
        mx = sum(r.m for r in x)
        self.kind = read_only(np.concatenate([np.array(
            ["image"] * (2 * m) + ["control"] * nc, dtype=object), *(r.kind for r in x)]))
        self.component = read_only(np.concatenate(
            [np.tile(XY, m), np.tile(XYZ, len(self.control))[sel], *(r.component for r in x)]))
        self.frame = read_only(np.concatenate([
            np.repeat(photos[im.photo[self.obs]], 2), np.full(nc, "", dtype=object),
            *(r.frame for r in x)]))
        self.point = read_only(np.concatenate([
            np.repeat(pids[im.point[self.obs]], 2), np.repeat(pids[self.control], 3)[sel],
            *(r.point for r in x)]))
        # components measured together: x and y of an image point
        group = np.full(mx, -1)
        bi = self.border_images
        group[self.extra_range["border_images"]] = np.repeat(m + np.arange(bi.m // 2), 2)
        self.group = read_only(np.concatenate([np.repeat(np.arange(m), 2), np.full(nc, -1),
                                               group]))
        # index of each component back into block tables
        self.image_row = read_only(np.concatenate([
            np.repeat(self.obs, 2), np.full(nc, -1), *(r.image_row for r in x)]))
        self.control_index = read_only(np.concatenate([
            np.full(2 * m, -1), np.repeat(self.control, 3)[sel],
            *(r.control_index for r in x)]))

    def datum_text(self) -> str:
        """What fixes the datum, in words (the summary's second line)."""
        pts = self.block.points
        ctrl = np.concatenate([self.control, self.border_control])
        c = pts.controlled[ctrl]
        fixed = int((pts.sigma[ctrl] == 0).any(axis=1).sum())
        gnss = self.gnss_imu.n_gnss
        return (f"datum: the control, {int((c[:, 0] & c[:, 1]).sum())} planimetric and "
                f"{int(c[:, 2].sum())} height control point(s)"
                + (f", {fixed} of them fixed" if fixed else "")
                + (f", and {gnss} GNSS projection centre(s)" if gnss else ""))

    def apriori_text(self) -> str:
        """The a-priori standard deviations in use (image µm, control m), in words."""
        sig, parts = self.sigma_apriori, []
        for k in KINDS.values():  # by axis where its axes are groups of their own
            f, unit = k.shown(self.block.settings.angle_unit)
            of_kind = self.kind == k.name
            for c in k.components if k.by_axis else ("",):
                s = sig[of_kind & (self.component == c)] if c else sig[of_kind]
                if len(s):
                    parts.append(f"{k.words}{' ' + c if c else ''} {_spread(s * f)} {unit}")
        return "a-priori sigmas: " + ", ".join(parts)

    # ------------------------------------------------- the solver's protocol
    def _split(self, state):
        """(eo, eliminated points, camera parameters per camera, border points (nb, 3))."""
        frames, xyz = state[0], state[1]
        g = state[2] if len(state) == 3 else np.zeros(0)
        return (frames[:, :6], xyz, self.calibration.current(g, frames[:, 6:]),
                g[self.global_layout.columns("points")].reshape(-1, 3))

    def linearize(self, state) -> Linearization:
        eo, xyz, params, bxyz = self._split(state)
        pts = self.block.points
        rot = rotation_and_derivatives(eo[:, 3], eo[:, 4], eo[:, 5])  # once, every row set
        f, je, jp, jpar = self.image_rows.evaluate(eo, xyz[self.obs_point], params, rot)
        e = self.obs_xy - f
        given = pts.xyz[self.control]
        cur = xyz[self.eremap[self.control]]
        ec = np.where(np.isfinite(given), given, 0.0) - cur
        jc = np.broadcast_to(np.eye(3), (len(self.control), 3, 3)).copy()
        wf = ef = wp = ep = None
        if self.held_frame is not None:  # zero columns in the rows of the photos concerned
            hr = self.held_rows
            je[hr] = np.where(self.held_frame[self.obs_photo[hr]][:, None, :], 0.0, je[hr])
            wf = np.where(self.held_frame, HOLD, 0.0)
            ef = np.zeros_like(wf)
        if self.held_points.any():  # fixed control: not unknowns (zero columns, held)
            jp = np.where(self.held_points[self.obs_point][:, None, :], 0.0, jp)
            wp = np.where(self.held_points, HOLD, 0.0)
            ep = np.zeros_like(wp)
            rows = self.eremap[self.control]
            ep[rows] = np.where(self.held_points[rows], ec, 0.0)
        lin = dict(jg=self.image_rows.free_columns(jpar) if self.system.ng else None)
        if self.system.ng or self.system.mx:
            g = state[2] if len(state) == 3 else np.zeros(0)
            lin.update(self._extra_rows(State(eo, g, params, bxyz, rot)))
        return Linearization(je, jp, self.w, e, jc, self.wc, ec, wf, ef, wp=wp, ep=ep, **lin)

    def _extra_rows(self, state: State) -> dict:
        """The extra rows of every observation kind (bundle/observation_kinds.py), with the
        held unknowns' columns zeroed (a free network's datum, fixed border coordinates),
        and the held global unknowns."""
        ng = self.system.ng
        parts = [r.linearize(state, ng) for r in self.extra]
        ex = np.concatenate([p[0] for p in parts])
        # d/d(photo's unknowns): the camera columns of a photo's block are zero in the rows
        # of kinds that do not depend on them (GNSS, IMU)
        jxf = np.concatenate([np.pad(p[1], ((0, 0), (0, self.b - p[1].shape[1])))
                              for p in parts])
        jxg = np.concatenate([p[2] for p in parts])
        if self.held_frame is not None:
            xf = self.system.x_frame
            has = xf >= 0
            jxf[has] = np.where(self.held_frame[xf[has]], 0.0, jxf[has])
        jxg[:, self.held_globals] = 0.0
        wg = np.zeros(ng)
        eg = np.zeros(ng)
        wg[self.held_globals] = HOLD
        pts = self.block.points
        full = np.where(np.isfinite(pts.xyz[self.border_ids]), pts.xyz[self.border_ids], 0.0)
        eg[self.global_layout.columns("points")] = np.where(self.held_border,
                                                            full - state.bxyz, 0.0).ravel()
        return dict(jxf=jxf[:, None, :], jxg=jxg[:, None, :], wx=self.wx, ex=ex[:, None],
                    wg=wg, eg=eg)

    def _camera_effect(self) -> tuple[np.ndarray, np.ndarray]:
        """Size in the image (mm) of a unit change of each global unknown, for the
        convergence test: camera parameters by their largest effect, points by the image
        scale (a change dX moves the image by about c dX / flying height); and (n_photos,
        photo_width) that of the camera parameters in the photos' blocks."""
        ng, kp = self.system.ng, self.b - 6
        out = np.zeros(ng)
        photo = np.zeros((len(self.block.photos), kp))
        if not ng and not kp:
            return out, photo
        lin = self.linearize(self.approximations)
        if kp:
            np.maximum.at(photo, self.system.frame, np.abs(lin.jf[:, :, 6:]).max(axis=1))
        if not ng:
            return out, photo
        if lin.jg is not None and self.system.gcol.shape[1]:
            mi, ai = np.nonzero(self.system.gcol >= 0)
            np.maximum.at(out, self.system.gcol[mi, ai], np.abs(lin.jg[mi, :, ai]).max(axis=1))
        c = float(np.median(self.block.cameras.focal_mm))
        out[self.global_layout.start("points"):] = c / self.scale
        gi = self.gnss_imu
        if gi.boresight_col >= 0:
            out[gi.boresight_col:gi.boresight_col + 3] = c  # an angle moves the image c da
        return out, photo

    def _sizes(self, step, t: float = 1.0) -> tuple[float, float]:
        dxf, dxp = step[0], step[1]
        dpos = max(np.max(np.abs(dxf[:, :3]), initial=0.0), np.max(np.abs(dxp), initial=0.0))
        dang = np.max(np.abs(dxf[:, 3:6]), initial=0.0)
        if len(step) == 3:
            gi = self.gnss_imu
            end = gi.boresight_col if gi.boresight_col >= 0 else len(step[2])
            first = self.global_layout.start("points")
            dpos = max(dpos, np.max(np.abs(step[2][first:end]), initial=0.0))
            dang = max(dang, np.max(np.abs(step[2][end:]), initial=0.0))
        return t * float(dpos), t * float(dang)

    def correction_size(self, state, step) -> float:
        dpos, dang = self._sizes(step)
        size = max(dpos / self.scale, 1e3 * dang)
        if len(step) == 3 and self.calibration.n_global:
            c = float(np.median(self.block.cameras.focal_mm))
            cols = self.global_layout.columns("camera")
            cam = np.abs(step[2][cols]) * self._parameter_scale[cols]
            size = max(size, float(np.max(cam, initial=0.0)) / c)
        if self.b > 6:  # camera parameters in the photos' blocks
            c = float(np.median(self.block.cameras.focal_mm))
            cam = np.abs(step[0][:, 6:]) * self._photo_scale
            size = max(size, float(np.max(cam, initial=0.0)) / c)
        return size

    def describe(self, state, step, t: float) -> str:
        dpos, dang = self._sizes(step, t)
        return f"{dpos:.3g} m, {dang:.3g} rad"

    def admissible(self, state) -> bool:
        from baarda.bundle.projection_kernel import all_in_front

        eo, xyz, _, bxyz = self._split(state)
        im = self.block.image
        rot = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
        ok = bool(all_in_front(rot, np.ascontiguousarray(eo[:, :3]), self.obs_photo,
                               self.obs_point, xyz))
        rows = self.border_images.rows
        if len(rows):
            ok &= bool(np.all(camera_depth(eo, bxyz[self.bremap[im.point[rows]]],
                                           im.photo[rows]) > 0))
        return ok

    # ------------------------------------------------------------ fit
    def with_solve_options(self, options: SolveOptions) -> BundleProblem:
        """The same problem, fitted (and re-fitted by snooping and variance components) with
        `options` (e.g. SOLVE_LM: Levenberg-Marquardt)."""
        new = copy.copy(self)
        new.solve_options = options
        return new

    def fit(self, start: tuple[np.ndarray, ...] | None = None,
            options: SolveOptions | None = None,
            progress: Progress | None = None) -> BundleResult:
        """Adjust; returns a BundleResult (arrays plus summary()).  options: default the
        problem's `solve_options` (SOLVE unless with_solve_options set others).

        start: (eo (n_photos, 6), xyz (n_adjusted_points, 3)) or the state of an earlier
        result (`BundleResult.state`); default the approximations (the photos' EO,
        intersected points and the cameras' nominal parameters).  A start of (n_photos, 6)
        orientations takes the nominal values of the camera parameters in the photos'
        blocks.
        """
        t0 = time.perf_counter()
        options = options or self.solve_options
        start = self.approximations if start is None else self._start(start)
        try:
            sol, gn = solve_continued(self, tuple(np.array(s, float) for s in start), options,
                                      progress, damped=SOLVE_LM)
            if sol.reason == "inadmissible":
                raise GeometryError("the adjustment diverged: no step along the Gauss-Newton "
                                    "direction keeps the points in front of the cameras; check "
                                    "the approximate orientations and the identification of "
                                    "points")
        except GeometryError as e:
            if not self.diagnosis:
                raise
            raise GeometryError(f"{e}. Likely cause: " + "; ".join(self.diagnosis),
                                frame=e.frame) from None
        notes = list(self.notes) + solve_notes(sol, gn)
        if sol.reason == "diverged" and self.calibration.n:
            notes.append(f"{self.calibration.n} camera parameter(s) are estimated "
                         "(self-calibration): with little depth in the block or far points "
                         "they let points drift; hold them (--calibrate none, or [calibration] "
                         "in project.toml) or give better approximations")
        if not sol.converged:
            notes += self._not_converged_notes()
        return BundleResult(self, sol.state, sol.lin, sol.factor, sol.iterations,
                            sol.converged, tuple(notes), time.perf_counter() - t0)

    def _not_converged_notes(self) -> list[str]:
        """Why the datum may keep the adjustment from converging, and what to do."""
        return []

    def _start(self, start) -> tuple[np.ndarray, ...]:
        """A start given as (eo, xyz of every adjusted point) in this problem's state."""
        eo = np.asarray(start[0])
        if eo.shape[1] != self.b:  # orientations only: the camera parameters' nominal values
            eo = np.hstack([eo[:, :6], self.approximations[0][:, 6:]])
        if len(start) == len(self.approximations) and len(start[1]) == len(self.elim_ids):
            return (eo, *start[1:])
        xyz = np.asarray(start[1])
        out: tuple[np.ndarray, ...] = (eo, xyz[self.remap[self.elim_ids]])
        if self.system.ng:
            g0 = np.zeros(self.system.ng)
            g0[self.global_layout.columns("camera")] = self.calibration.start()
            g0[self.global_layout.columns("points")] = xyz[self.remap[self.border_ids]].ravel()
            out += (g0,)
        return out
