"""The result of a bundle adjustment: arrays plus a summary for people (never changed)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from baarda.adjustment.counts import AdjustmentCounts
from baarda.adjustment.schur import SchurFactor
from baarda.adjustment.schur_problem import read_only
from baarda.adjustment.schur_system import Linearization
from baarda.block.photo_block import Block
from baarda.block.rotation import similarity
from baarda.bundle import result_text
from baarda.bundle.result_text import HIGH_CORRELATION
from baarda.sections import Section, render

if TYPE_CHECKING:
    from baarda.bundle.bundle_problem import BundleProblem



@dataclass(frozen=True)
class Coordinates:
    """Orientations and points in the datum the results are given in.

    eo (n_photos, 6) m and rad; frame_cofactors (n_photos, 6, 6); xyz (n_adjusted_points, 3)
    m in the order of problem.point_ids; point_cofactors (n_adjusted_points, 3, 3); datum:
    "adjusted" (the control, or a free network's minimal constraints) or "inner".
    Cofactors are unscaled (times sigma0^2: covariances)."""

    eo: np.ndarray
    frame_cofactors: np.ndarray
    xyz: np.ndarray
    point_cofactors: np.ndarray
    datum: str


@dataclass(frozen=True)
class BundleResult(AdjustmentCounts):
    """Adjusted orientations, points and camera parameters with their precision.

    Units: positions in m, angles in rad, image residuals in mm (µm in the outputs).
    Standard deviations are scaled by the a-posteriori sigma0.  `factor` holds the normal
    equations factored at the solution, from which every cofactor is computed.  `state`:
    (the photos' unknowns (n_photos, b): orientation, then the free parameters of a camera
    in the photo's block; eliminated points[, global unknowns]) of the problem
    (bundle/bundle_problem.py).
    """

    problem: BundleProblem
    state: tuple[np.ndarray, ...]
    lin: Linearization
    factor: SchurFactor
    iterations: int
    converged: bool
    notes: tuple[str, ...] = ()
    seconds: float = 0.0
    # after data snooping: (re-adjustments, iterations of the last one); `iterations` and
    # `seconds` are then those of the first adjustment and of all of them together
    refits: tuple[int, int] = (0, 0)

    @property
    def block(self) -> Block:
        return self.problem.block

    @property
    def eo(self) -> np.ndarray:
        """(n_photos, 6) adjusted orientations."""
        return self.state[0][:, :6]

    @property
    def xyz(self) -> np.ndarray:
        """(n_adjusted_points, 3) adjusted coordinates, order of problem.point_ids."""
        pb = self.problem
        out = np.empty((len(pb.point_ids), 3))
        out[pb.remap[pb.elim_ids]] = self.state[1]
        if len(pb.border_ids):
            out[pb.remap[pb.border_ids]] = \
                self.state[2][pb.global_layout.columns("points")].reshape(-1, 3)
        return out

    @property
    def _g(self) -> np.ndarray:
        return self.state[2] if len(self.state) == 3 else np.zeros(0)

    @property
    def cameras(self):
        """The cameras with their adjusted parameters (block.cameras where none is free)."""
        cal = self.problem.calibration
        return cal.adjusted_cameras(self._g, self.state[0][:, 6:]) if cal.n \
            else self.block.cameras

    def refit(self, active: np.ndarray, factors: np.ndarray | None = None) -> BundleResult:
        """Adjust again with only the `active` components of the observation vector (and
        weight factors), starting from this solution; this result is unchanged."""
        return self.problem.reweighted(active, factors).fit(start=self.state)

    # --------------------------------------------------------- residuals
    @property
    def image_residuals(self) -> np.ndarray:
        """v = adjusted - observed image coordinates of the eliminated points' image rows
        (problem.obs), (m, 2) in mm."""
        return -self.lin.e

    @property
    def control_residuals(self) -> np.ndarray:
        """v = adjusted - given control coordinates, (n_control, 3) in m (NaN: not observed)."""
        given = self.block.points.xyz[self.problem.control]
        return np.where(np.isfinite(given), -self.lin.ec, np.nan)

    @property
    def extra_residuals(self) -> np.ndarray:
        """v of the rows of border points and distances (mx,) (mm for image rows, m else)."""
        return np.zeros(0) if self.lin.ex is None else -self.lin.ex[:, 0]

    # --------------------------------------------------------- precision
    @property
    def eo_std(self) -> np.ndarray:
        return self.scaled_std(self.frame_covariance())

    def frame_covariance(self) -> np.ndarray:
        """(n_photos, 6, 6) cofactor blocks of the orientations."""
        return self._frame_cofactors[:, :6, :6]

    @cached_property
    def _frame_cofactors(self) -> np.ndarray:
        """(n_photos, b, b) cofactor blocks of the photos' unknowns (computed once)."""
        return read_only(self.factor.frame_covariance())

    @cached_property
    def coordinates(self) -> Coordinates:
        """Orientations and points with their cofactors as the results give them: as
        adjusted, or for a free network asked for in its inner datum (datum "inner")
        S-transformed to it (bundle/inner_datum.py).  `eo`, `xyz` and the other members of
        this result stay as adjusted (the state the statistics were computed at)."""
        if getattr(self.problem, "inner", False):
            from baarda.bundle.inner_datum import inner_datum

            i = inner_datum(self)
            return Coordinates(i.eo, i.frame_cofactors, i.xyz, i.point_cofactors, "inner")
        return Coordinates(self.eo, self.frame_covariance(), self.xyz,
                           self.point_covariance(), "adjusted")

    def point_covariance(self) -> np.ndarray:
        """(n_adjusted_points, 3, 3) cofactor blocks of every adjusted point."""
        pb = self.problem
        out = np.zeros((len(pb.point_ids), 3, 3))
        out[pb.remap[pb.elim_ids]] = self.factor.point_covariance()
        if len(pb.border_ids):
            q = self.factor.global_covariance()
            cols = pb.global_layout.start("points") + 3 * np.arange(len(pb.border_ids))[:, None] \
                + np.arange(3)
            out[pb.remap[pb.border_ids]] = q[cols[:, :, None], cols[:, None, :]]
        # coordinates of fixed control (sigma 0) are held, not estimated: cofactor 0 (the
        # factorisation leaves 1 / HOLD there)
        held = np.zeros((len(pb.point_ids), 3), bool)
        held[pb.remap[pb.elim_ids]] = pb.held_points
        held[pb.remap[pb.border_ids]] = pb.held_border
        if held.any():
            out = np.where(held[:, :, None] | held[:, None, :], 0.0, out)
        return out

    @property
    def xyz_std(self) -> np.ndarray:
        return self.scaled_std(self.point_covariance())

    def camera_covariance(self) -> np.ndarray:
        """(n, n) cofactor matrix of the estimated parameters of the cameras in the border,
        those that several photos share (order of problem.calibration.global_labels: every
        estimated camera parameter unless cameras are in their photo's block; read-only,
        computed once).  Cameras in a photo's block: `camera_cofactors`."""
        return self._camera_covariance

    @cached_property
    def _camera_covariance(self) -> np.ndarray:
        n = self.problem.calibration.n_global
        return read_only(np.ascontiguousarray(self.factor.global_covariance()[:n, :n]) if n
                         else np.zeros((0, 0)))

    def camera_cofactors(self, camera: int) -> np.ndarray:
        """(k, k) cofactor matrix of the k estimated parameters of one camera (order of its
        free parameters): from the border's, or from its photo's diagonal block of the
        selected inverse."""
        cal = self.problem.calibration
        photo = cal.owner[camera]
        if photo < 0:
            cols = cal.columns[camera]
            return self.camera_covariance()[np.ix_(cols, cols)]
        k = 6 + np.arange(len(cal.free_index[camera]))
        return self._frame_cofactors[photo][np.ix_(k, k)]

    def camera_parameters(self, camera: int) -> np.ndarray:
        """The estimated values of one camera's free parameters (order of its free
        parameters)."""
        cal = self.problem.calibration
        photo = cal.owner[camera]
        if photo < 0:
            return self._g[cal.columns[camera]]
        return self.state[0][photo, 6:6 + len(cal.free_index[camera])]

    def points_xyz(self) -> np.ndarray:
        """Adjusted coordinates for every block point, (n_points, 3); NaN if left out."""
        out = np.full((len(self.block.points), 3), np.nan)
        out[self.problem.point_ids] = self.xyz
        return out

    @property
    def free_network(self) -> bool:
        """The datum is not the control but minimal constraints (bundle/free_network.py)."""
        return self.problem.held is not None

    def check_points(self) -> tuple[list[str], np.ndarray]:
        """Ids and discrepancies adjusted - given (n, 3) in m of the check points; in a free
        network after the 7-parameter similarity that fits them best (`check_similarity`)."""
        pts = self.block.points
        idx = np.flatnonzero((pts.role == "check") & (self.problem.remap >= 0))
        if self.free_network and self.check_similarity() is None:
            return [], np.zeros((0, 3))  # an arbitrary datum: nothing to compare
        adjusted = self.compared_xyz()[self.problem.remap[idx]]
        return [pts.ids[j] for j in idx], adjusted - pts.xyz[idx]

    def compared_xyz(self) -> np.ndarray:
        """Adjusted coordinates as compared with given ones: in a free network mapped by
        `check_similarity` onto the check points, else as adjusted (n_adjusted_points, 3)."""
        sim = self.check_similarity()
        if sim is None:
            return self.xyz
        s, r, t = sim
        return s * self.xyz @ r.T + t

    def check_similarity(self) -> tuple[float, np.ndarray, np.ndarray] | None:
        """In a free network, (scale, R, t) of the similarity from the adjusted check points
        onto their given coordinates (None with control or fewer than 3 check points)."""
        if not self.free_network:
            return None
        pts = self.block.points
        idx = np.flatnonzero((pts.role == "check") & (self.problem.remap >= 0))
        if len(idx) < 3:
            return None
        adjusted = self.xyz[self.problem.remap[idx]]
        if np.linalg.matrix_rank(adjusted - adjusted.mean(axis=0), tol=1e-9 * max(
                float(np.ptp(adjusted)), 1e-12)) < 2:
            return None
        return similarity(adjusted, pts.xyz[idx])

    def check_rms(self) -> np.ndarray:
        _, d = self.check_points()
        return np.sqrt(np.mean(d**2, axis=0)) if len(d) else np.full(3, np.nan)

    def to_dict(self) -> dict:
        rms = self.check_rms()
        return {
            "sigma0": self.sigma0,
            "redundancy": self.redundancy,
            "n_observations": self.n_observations,
            "n_unknowns": self.n_unknowns,
            "iterations": self.iterations,
            "converged": self.converged,
            "vtpv": self.vtpv,
            "n_check_points": len(self.check_points()[0]),
            "check_rms_X": None if np.isnan(rms[0]) else float(rms[0]),
            "check_rms_Y": None if np.isnan(rms[1]) else float(rms[1]),
            "check_rms_Z": None if np.isnan(rms[2]) else float(rms[2]),
            "seconds": self.seconds,
            **({"readjustments": self.refits[0], "readjustment_iterations": self.refits[1]}
               if self.refits[0] else {}),
            "notes": list(self.notes),
            **({"calibration": self.camera_table(),
                "camera_correlations": self.camera_correlations(),
                "high_correlations": self.high_correlations()}
               if self.problem.calibration.n else {}),
        }

    def sections(self) -> list[Section]:
        return result_text.sections(self)

    def camera_table(self) -> list[dict]:
        return result_text.camera_table(self)

    def camera_correlations(self) -> list[dict]:
        return result_text.camera_correlations(self)

    def high_correlations(self, limit: float = HIGH_CORRELATION) -> list[str]:
        return result_text.high_correlations(self, limit)

    def calibration_lines(self) -> list[str]:
        return result_text.calibration_lines(self)

    def summary(self) -> str:
        return render(self.sections())
