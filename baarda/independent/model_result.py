"""The result of an independent-model adjustment: arrays plus a summary for people."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.adjustment.counts import AdjustmentCounts
from baarda.adjustment.schur import SchurFactor
from baarda.adjustment.schur_system import Linearization
from baarda.independent.model_problem import ModelProblem
from baarda.sections import Section, render, section

TITLE = {"3d": "Independent-model block adjustment, spatial (7 parameters per model)",
         "2d": "Independent-model block adjustment, planimetric (4 parameters per model)",
         "height": "Independent-model height adjustment (3 parameters per model)"}


@dataclass(frozen=True)
class ModelResult(AdjustmentCounts):
    """Adjusted model transformations and terrain points.

    `params` (nm, b): 3d (TX, TY, TZ [m], omega, phi, kappa [rad], mu [mm/m]); 2d (TX, TY,
    kappa, mu); height (a0, a1, a2 [mm]).  T is the terrain position of the model centroid
    (with the origin added back).  Standard deviations are scaled by the a-posteriori sigma0.
    """

    problem: ModelProblem
    params: np.ndarray  # reduced: T relative to problem.origin
    pts: np.ndarray  # (np_used, d) reduced terrain coordinates
    lin: Linearization
    factor: SchurFactor  # normal equations factored at the solution
    iterations: int
    converged: bool
    notes: tuple[str, ...] = ()
    seconds: float = 0.0

    def refit(self, active: np.ndarray, factors: np.ndarray | None = None) -> ModelResult:
        """Adjust again with only the `active` components (and weight factors), starting
        from this solution; this result is unchanged."""
        return self.problem.reweighted(active, factors).fit(start=(self.params, self.pts))

    @property
    def block(self):
        return self.problem.block

    @property
    def mode(self) -> str:
        return self.problem.mode

    # ------------------------------------------------------------ values
    @property
    def terrain_params(self) -> np.ndarray:
        """params with T in terrain coordinates (origin added)."""
        p = self.params.copy()
        if self.mode == "3d":
            p[:, :3] += self.problem.origin
        elif self.mode == "2d":
            p[:, :2] += self.problem.origin[:2]
        return p

    @property
    def xyz(self) -> np.ndarray:
        """(np_used, d) adjusted terrain coordinates [m]."""
        return self.pts + self.problem.origin[self.problem.comps]

    @property
    def model_residuals(self) -> np.ndarray:
        """v = adjusted - observed model coordinates (m_rows, k) [mm] (decorrelated if C)."""
        return -self.lin.e

    @property
    def control_residuals(self) -> np.ndarray:
        """v = adjusted - given control (nc, k) [m]; NaN where not observed."""
        return np.where(self.problem.wc_full > 0, -self.lin.ec, np.nan)

    @property
    def param_std(self) -> np.ndarray:
        return self.scaled_std(self.factor.frame_covariance())

    @property
    def xyz_std(self) -> np.ndarray:
        return self.scaled_std(self.factor.point_covariance())

    def check_points(self) -> tuple[list[str], np.ndarray]:
        """Ids and discrepancies adjusted - given (n, k) [m] of the check points."""
        bl, pb = self.block, self.problem
        idx = np.flatnonzero((bl.role == "check") & (pb.remap >= 0))
        d = self.xyz[pb.remap[idx]] - bl.xyz[idx][:, pb.comps]
        return [bl.points[j] for j in idx], d

    def to_dict(self) -> dict:
        _, d = self.check_points()
        rms = np.sqrt(np.mean(d**2, axis=0)) if len(d) else np.full(self.problem.k, np.nan)
        names = ["X", "Y", "Z"]
        out = {"mode": self.mode, "sigma0": self.sigma0, "redundancy": self.redundancy,
               "n_observations": self.n_observations, "n_unknowns": self.n_unknowns,
               "iterations": self.iterations, "converged": self.converged, "vtpv": self.vtpv,
               "n_check_points": len(d), "seconds": self.seconds, "notes": list(self.notes)}
        for c, r in zip(self.problem.comps, rms, strict=True):
            out[f"check_rms_{names[c]}"] = None if np.isnan(r) else float(r)
        return out

    def sections(self) -> list[Section]:
        d = self.to_dict()
        v = np.where(self.lin.w > 0, self.model_residuals * 1e3, np.nan)
        names = ("z",) if self.mode == "height" else ("x", "y", "z")[: v.shape[1]]
        comp = ", ".join(f"{c} {np.sqrt(np.nanmean(v[:, i] ** 2)):.2f} µm"
                         for i, c in enumerate(names))
        status = "converged" if d["converged"] else "NOT converged"
        lines = [] if self.converged else [
            f"NOT CONVERGED after {self.iterations} iterations: the results are not a "
            "least-squares solution (see the notes)"]
        lines += [self.block.summary(),
                  self.observations_text(),
                  f"iterations {d['iterations']} ({status}), {d['seconds']:.2f} s",
                  f"sigma0 a posteriori {d['sigma0']:.4f}",
                  f"RMS model residuals {comp} (rejected ones left out)"]
        if d["n_check_points"]:
            rms = ", ".join(f"{k[-1]} {d[k]:.3f} m" for k in d if k.startswith("check_rms"))
            lines.append(f"check points {d['n_check_points']}: RMS {rms}")
        lines += [f"note: {n}" for n in self.notes]
        return [section(TITLE[self.mode], lines)]

    def summary(self) -> str:
        return render(self.sections())
