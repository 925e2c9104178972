"""Data snooping, reliability and hypothesis tests of an independent-model block.

Glue between the adjustment (adjust.py) and the quality layer (baarda.quality): every
statistic comes from quality.statistics.analyse, quality.hypotheses and
quality.iterative; this module only builds the models and tables.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from baarda.block.model_block import ModelBlock
from baarda.independent.external import ExternalReliability, external_reliability
from baarda.independent.independent_model import IndependentModel
from baarda.independent.model_hypotheses import decision
from baarda.independent.model_problem import ModelProblem
from baarda.independent.model_result import ModelResult
from baarda.options import Progress, TestOptions
from baarda.quality.hypotheses import HypothesisTest, image_point_tests
from baarda.quality.iterative import SnoopingRun, iterative_snooping
from baarda.quality.statistics import QualityResult, analyse


@dataclass
class ModelQuality:
    """One adjustment (3d, 2d or height) with every observation's statistics."""

    adjustment: ModelResult
    model: IndependentModel
    quality: QualityResult
    run: SnoopingRun | None = None
    external: ExternalReliability | None = None
    hypotheses: list[HypothesisTest] = field(default_factory=list)

    @property
    def mode(self) -> str:
        return self.adjustment.mode

    def table(self) -> pd.DataFrame:
        """One row per observation component: model µm, control m; FOTEF columns in m."""
        m, q = self.model, self.quality
        model_rows = m.kind == "model"
        scale = np.where(model_rows, 1e3, 1.0)
        _, tg, _, _, _ = image_point_tests(m, q.tests)
        group_t = np.full(m.n, np.nan)
        group_t[: m.m * m.k] = np.repeat(tg, m.k) if len(tg) else np.nan
        df = pd.DataFrame({
            "adjustment": self.mode, "kind": m.kind, "model": m.frame, "point": m.point,
            "component": m.component, "residual": q.residual * scale, "sigma": q.sigma * scale,
            "sigma_residual": q.sigma_residual * scale, "redundancy": q.redundancy_number,
            "w": q.w, "tau": q.tau, "p_value": q.p_value, "mdb": q.mdb * scale,
            "mdb_terrain": q.mdb * m.terrain_per_unit, "lambda_bar": q.lambda_bar,
            "external_max": q.external_max, "external_point": q.external_point,
            "point_test": group_t, "rejected": ~q.active, "flagged": q.flagged})
        if self.external is not None:
            e = self.external
            for name, vals in (("ext_detail", e.point), ("ext_dist_same", e.dist_same),
                               ("ext_dist_diff", e.dist_diff), ("prop_detail", e.point_prop),
                               ("prop_dist_same", e.same_prop), ("prop_dist_diff", e.diff_prop)):
                col = np.full(m.n, np.nan)
                col[e.index] = vals
                df[name] = col
            where = np.full(m.n, "", dtype=object)
            where[e.index] = e.point_where
            df["ext_detail_where"] = where
        return df

    def hypotheses_table(self) -> pd.DataFrame:
        return pd.DataFrame([{
            "adjustment": self.mode, "hypothesis": t.name, "q": t.q, "statistic": t.statistic,
            "critical": t.critical, "p_value": t.p_value, "rejected": t.rejected,
            "w": t.w, "mdb": t.mdb,
            "nabla": " ".join(f"{v:.6g}" for v in np.atleast_1d(t.nabla))}
            for t in self.hypotheses])

    def to_dict(self) -> dict:
        q = self.quality
        gt = q.global_test
        d = {
            "adjustment": self.adjustment.to_dict(),
            "global_test": None if gt is None else {
                "statistic": gt.statistic, "critical": gt.critical, "alpha": q.global_alpha,
                "p_value": gt.p_value, "passed": bool(gt.passed)},
            "alpha0": q.alpha0, "beta0": q.beta0, "delta0": q.delta0, "k_w": q.k_w,
            "sum_redundancy_numbers": q.sum_redundancy_numbers,
            "n_rejected": int(np.sum(~q.active)), "n_flagged": int(np.sum(q.flagged)),
            "n_uncontrolled": int(np.sum(q.active & ~q.controlled)),
            "rejection_log": [] if self.run is None else [s.to_dict() for s in self.run.log],
            "hypotheses": [{"name": t.name, "q": t.q, "statistic": t.statistic,
                            "critical": t.critical, "rejected": t.rejected,
                            "nabla": np.atleast_1d(t.nabla).tolist()} for t in self.hypotheses],
            "notes": q.notes,
        }
        if self.hypotheses:
            d["decision"] = decision(self.hypotheses)
        if self.external is not None:
            e = self.external
            d["external_max"] = {"detail_prop": float(np.max(e.point_prop, initial=0)),
                                 "dist_same_prop": float(np.max(e.same_prop, initial=0)),
                                 "dist_diff_prop": float(np.max(e.diff_prop, initial=0))}
        return d

    def summary(self) -> str:
        q, m = self.quality, self.model
        gt = q.global_test
        lines = [self.adjustment.summary(), "", f"Quality control ({self.mode})", "=" * 60,
                 f"alpha0 {q.alpha0}, beta0 {q.beta0}: delta0 {q.delta0:.3f}, critical |w| "
                 f"{q.k_w:.3f}"]
        if gt is not None:
            lines.append(f"global test: sigma0^2 = {gt.statistic:.4f}, critical "
                         f"{gt.critical:.4f} (alpha {q.global_alpha:.3g}) -> "
                         f"{'accepted' if gt.passed else 'REJECTED'}")
        lines.append(f"sum of redundancy numbers {q.sum_redundancy_numbers:.3f} = redundancy "
                     f"{q.redundancy}")
        act = q.active & q.controlled
        for kind, u, unit in (("model", 1e3, "µm"), ("control", 1.0, "m")):
            sel = act & (m.kind == kind)
            if sel.any():
                lines.append(f"{kind}: r mean {np.mean(q.redundancy_number[sel]):.3f} min "
                             f"{np.min(q.redundancy_number[sel]):.3f}; MDB max "
                             f"{np.max(q.mdb[sel]) * u:.4g} {unit} "
                             f"({np.max((q.mdb * m.terrain_per_unit)[sel]):.4g} m in the "
                             f"terrain); max |w| {np.nanmax(np.abs(q.w[sel])):.2f}")
        if self.external is not None:
            e = self.external
            lines.append("external reliability (effect of an error of the size of its MDB, "
                         "as a fraction of it): detail points max "
                         f"{np.max(e.point_prop, initial=0):.2f}, distances in one model "
                         f"{np.max(e.same_prop, initial=0):.2f}, between adjacent models "
                         f"{np.max(e.diff_prop, initial=0):.2f}")
        if self.run is not None:
            lines += self.run.summary_lines()
        if self.hypotheses:
            lines.append("alternative hypotheses:")
            lines += ["  " + t.summary() for t in self.hypotheses]
            lines.append(decision(self.hypotheses))
        lines += [f"note: {n}" for n in q.notes]
        return "\n".join(lines)


def assess(result: ModelResult, tests: TestOptions | None = None,
           external: bool = False) -> ModelQuality:
    """Statistics of every observation of an adjusted model block (nothing rejected)."""
    model = IndependentModel(result)
    q = analyse(model, tests or TestOptions.resolve(result.block.settings))
    ext = external_reliability(model, q) if external else None
    return ModelQuality(result, model, q, external=ext)


def snoop(block: ModelBlock | ModelResult, mode: str = "3d", tests: TestOptions | None = None,
          *, statistic: str = "w", by_point: bool = False,
          obs_keep: np.ndarray | None = None, control_keep: np.ndarray | None = None,
          mu: np.ndarray | None = None, start=None, external: bool = False,
          max_iterations: int = 200, progress: Progress | None = None) -> ModelQuality:
    """Iterative data snooping of one adjustment of the model block (or of an adjusted one).

    `obs_keep`/`control_keep` give the components that start rejected (e.g. those the
    pre-adjustment set aside); snooping restores those that prove innocent.
    """
    if isinstance(block, ModelResult):
        result = block
    else:
        problem = ModelProblem(block, mode, obs_keep=obs_keep, control_keep=control_keep,
                               mu=mu)
        result = problem.fit(start, progress=progress)
    tests = tests or TestOptions.resolve(result.block.settings)
    run = iterative_snooping(IndependentModel(result), tests, statistic=statistic,
                             by_group=by_point, max_iterations=max_iterations,
                             progress=progress)
    ext = external_reliability(run.model, run.quality) if external else None
    return ModelQuality(run.model.result, run.model, run.quality, run, ext)
