"""Data snooping and reliability of a bundle adjustment: glue between bundle and quality."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from baarda.block.photo_block import Block
from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.bundle_result import BundleResult
from baarda.options import Progress, TestOptions
from baarda.quality.hypotheses import (
    HypothesisTest,
    group_test,
    hypothesis_test,
    image_point_tests,
)
from baarda.quality.iterative import SnoopingRun, iterative_snooping
from baarda.quality.robust import danish_method
from baarda.quality.statistics import QualityResult, analyse

UNIT = {"image": 1e3, "control": 1.0}  # output units: µm for image, m for control


@dataclass
class BundleQuality:
    """A bundle adjustment with every observation's statistics (and the snooping log)."""

    adjustment: BundleResult
    model: BundleModel
    quality: QualityResult
    run: SnoopingRun | None = None

    @property
    def rejected(self) -> np.ndarray:
        return ~self.quality.active

    def table(self) -> pd.DataFrame:
        """One row per observation component (observations.csv): image µm, control m."""
        m, q = self.model, self.quality
        scale = np.where(m.kind == "image", UNIT["image"], UNIT["control"])
        _, t2, _, _, _ = image_point_tests(m, q.tests)
        point_t = np.full(m.n, np.nan)
        point_t[: len(t2) * 2] = np.repeat(t2, 2)
        img = m.image_row >= 0  # observed image coordinates (mm) for plotting
        xy = np.full((m.n, 2), np.nan)
        xy[img] = self.adjustment.block.image.xy_mm[m.image_row[img]]
        return pd.DataFrame({
            "kind": m.kind, "photo": m.frame, "point": m.point, "component": m.component,
            "x_mm": xy[:, 0], "y_mm": xy[:, 1], "residual": q.residual * scale,
            "sigma": q.sigma * scale,
            "sigma_residual": q.sigma_residual * scale, "redundancy": q.redundancy_number,
            "w": q.w, "tau": q.tau, "p_value": q.p_value, "mdb": q.mdb * scale,
            "lambda_bar": q.lambda_bar, "external_max": q.external_max,
            "external_point": q.external_point, "point_test": point_t,
            "rejected": ~q.active, "flagged": q.flagged,
        })

    def point_test(self, point: str) -> HypothesisTest:
        """All observations of a ground point in error together (image and control)."""
        rows = np.flatnonzero(self.model.point == point)
        if not len(rows):
            raise KeyError(f"no observations of point {point}")
        return group_test(self.model, rows, f"point {point}", self.quality.tests)

    def photo_test(self, photo: str) -> HypothesisTest:
        """All image observations of a photo in error together."""
        rows = np.flatnonzero(self.model.frame == photo)
        if not len(rows):
            raise KeyError(f"no observations on photo {photo}")
        return group_test(self.model, rows, f"photo {photo}", self.quality.tests)

    def hypothesis_test(self, h: np.ndarray, name: str = "H") -> HypothesisTest:
        """A non-conventional alternative hypothesis: h (n, q) over the observation vector."""
        return hypothesis_test(self.model, h, name, self.quality.tests)

    def to_dict(self) -> dict:
        q = self.quality
        gt = q.global_test
        d = {
            "global_test": None if gt is None else {
                "statistic": gt.statistic, "critical": gt.critical, "alpha": q.global_alpha,
                "p_value": gt.p_value, "passed": bool(gt.passed)},
            "alpha0": q.alpha0, "beta0": q.beta0, "delta0": q.delta0, "k_w": q.k_w,
            "k_tau": q.k_tau, "sum_redundancy_numbers": q.sum_redundancy_numbers,
            "n_rejected": int(np.sum(~q.active)),
            "n_flagged": int(np.sum(q.flagged)),
            "n_uncontrolled": int(np.sum(q.active & ~q.controlled)),
            "rejection_log": [] if self.run is None else [s.to_dict() for s in self.run.log],
            "snooping_converged": None if self.run is None else self.run.converged,
            "notes": q.notes,
        }
        return d

    def summary(self) -> str:
        q = self.quality
        gt = q.global_test
        lines = [self.adjustment.summary(), "", "Quality control", "=" * 60,
                 f"alpha0 {q.alpha0}, beta0 {q.beta0}: delta0 {q.delta0:.3f}, critical |w| "
                 f"{q.k_w:.3f}"]
        if gt is not None:
            lines.append(f"global test: sigma0^2 = {gt.statistic:.4f}, critical "
                         f"{gt.critical:.4f} (alpha {q.global_alpha:.3g} by the B-method, "
                         f"p = {gt.p_value:.3g}) -> {'accepted' if gt.passed else 'REJECTED'}")
        act = q.active & q.controlled
        lines.append(f"sum of redundancy numbers {q.sum_redundancy_numbers:.3f} = redundancy "
                     f"{q.redundancy}")
        for kind in np.unique(self.model.kind):
            sel = act & (self.model.kind == kind)
            if not sel.any():
                continue
            u, unit = (1e3, "µm") if kind == "image" else (1.0, "m")
            lines.append(f"{kind}: r mean {np.mean(q.redundancy_number[sel]):.3f} min "
                         f"{np.min(q.redundancy_number[sel]):.3f}; MDB max "
                         f"{np.max(q.mdb[sel]) * u:.4g} {unit}; max |w| "
                         f"{np.nanmax(np.abs(q.w[sel])):.2f}")
        if self.run is not None:
            lines += self.run.summary_lines()
        lines += [f"note: {n}" for n in q.notes]
        return "\n".join(lines)


def assess(result: BundleResult, tests: TestOptions | None = None) -> BundleQuality:
    """Statistics of every observation of an adjusted block, without rejecting any.

    tests: alpha0 and beta0 (default: the project's settings)."""
    model = BundleModel(result)
    q = analyse(model, tests or TestOptions.resolve(result.block.settings))
    return BundleQuality(result, model, q)


def snoop(block: Block | BundleProblem, tests: TestOptions | None = None, *,
          statistic: str = "w", by_point: bool = False, max_iterations: int = 200,
          robust: bool = False, progress: Progress | None = None) -> BundleQuality:
    """Iterative data snooping of a bundle block (re-adjusting after each rejection).

    `block`: a Block with control or a BundleProblem (e.g. a free network,
    bundle/free_network.py).  With `robust`, the Danish method first down-weights large
    errors; the components it leaves with (almost) no weight start out rejected and are
    tested again by snooping.
    """
    problem = block if isinstance(block, BundleProblem) else BundleProblem(block)
    tests = tests or TestOptions.resolve(problem.block.settings)
    first = BundleModel(problem.fit(progress=progress))
    active = first.active.copy()
    if robust:
        rob = danish_method(first)
        active &= ~rob.rejected
        if progress:
            progress(f"Danish method: {rob.iterations} re-weightings, "
                     f"{int(rob.rejected.sum())} component(s) down-weighted to rejection")
    run = iterative_snooping(first, tests, active=active, statistic=statistic,
                             by_group=by_point, max_iterations=max_iterations,
                             progress=progress)
    return BundleQuality(run.model.result, run.model, run.quality, run)
