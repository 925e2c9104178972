"""Data snooping, reliability and hypothesis tests of an independent-model block.

Glue between the adjustment (model_problem.py) and the quality layer (baarda.quality): every
statistic comes from quality.statistics.analyse, quality.hypotheses and quality.iterative;
this module adds the FOTEF columns and lines to the common Assessment.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import cast

import numpy as np

from baarda.block.model_block import ModelBlock
from baarda.independent.external import ExternalReliability, external_reliability
from baarda.independent.independent_model import IndependentModel
from baarda.independent.model_hypotheses import decision
from baarda.independent.model_problem import ModelProblem
from baarda.independent.model_result import ModelResult
from baarda.options import Progress, TestOptions
from baarda.quality.assessment import Assessment
from baarda.quality.iterative import iterative_snooping
from baarda.quality.statistics import analyse


@dataclass(frozen=True)
class ModelQuality(Assessment[ModelResult]):
    """One adjustment (3d, 2d or height) with every observation's statistics, the FOTEF
    external reliability on detail points and distances, and the tested hypotheses."""

    model: IndependentModel  # the Assessment's model, of an independent-model block

    external: ExternalReliability | None = None

    @property
    def mode(self) -> str:
        return self.adjustment.mode

    def extra_columns(self) -> dict[str, np.ndarray]:
        """MDB in the terrain [m] and the FOTEF columns of external reliability [m]."""
        m, q = self.model, self.quality
        cols = {"mdb_terrain": q.mdb * m.terrain_per_unit}
        if self.external is not None:
            e = self.external
            for name, vals in (("ext_detail", e.point), ("ext_dist_same", e.dist_same),
                               ("ext_dist_diff", e.dist_diff), ("prop_detail", e.point_prop),
                               ("prop_dist_same", e.same_prop), ("prop_dist_diff", e.diff_prop)):
                col = np.full(m.n, np.nan)
                col[e.index] = vals
                cols[name] = col
            where = np.full(m.n, "", dtype=object)
            where[e.index] = e.point_where
            cols["ext_detail_where"] = where
        return cols

    def quality_dict(self) -> dict:
        d = super().quality_dict()
        if self.hypotheses:
            d["decision"] = decision(self.hypotheses)
        if self.external is not None:
            e = self.external
            d["external_max"] = {"detail_prop": float(np.max(e.point_prop, initial=0)),
                                 "dist_same_prop": float(np.max(e.same_prop, initial=0)),
                                 "dist_diff_prop": float(np.max(e.diff_prop, initial=0))}
        return d

    def kind_suffix(self, kind: str, sel: np.ndarray) -> str:
        mdb = (self.quality.mdb * self.model.terrain_per_unit)[sel]
        return f"; MDB in the terrain max {np.max(mdb):.4g} m"

    def extra_quality_lines(self) -> list[str]:
        if self.external is None:
            return []
        e = self.external
        return ["external reliability (effect of an error of the size of its MDB, as a "
                f"fraction of it): detail points max {np.max(e.point_prop, initial=0):.2f}, "
                f"distances in one model {np.max(e.same_prop, initial=0):.2f}, between "
                f"adjacent models {np.max(e.diff_prop, initial=0):.2f}"]

    def conclusion_lines(self) -> list[str]:
        return [decision(self.hypotheses)]


def assess(result: ModelResult, tests: TestOptions | None = None,
           external: bool = False) -> ModelQuality:
    """Statistics of every observation of an adjusted model block (nothing rejected)."""
    model = IndependentModel(result)
    q = analyse(model, tests or TestOptions.resolve(result.block.settings))
    ext = external_reliability(model, q) if external else None
    return ModelQuality(result, model, q, name=result.mode, external=ext)


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
    model = cast(IndependentModel, run.model)  # snooping refits the model it is given
    ext = external_reliability(model, run.quality) if external else None
    return ModelQuality(model.result, model, run.quality, run, name=result.mode,
                        external=ext)


def with_variance_components(result: ModelResult, tests: TestOptions | None = None, *,
                             do_snoop: bool = True, statistic: str = "w",
                             by_point: bool = False, external: bool = False,
                             progress: Progress | None = None) -> ModelQuality:
    """One adjustment with the variance component of every group (model XY, model Z,
    projection centres, control X, Y, Z; quality/variance_components.py): estimated and
    re-weighted until they converge, then the statistics (or, with `do_snoop`, estimation
    and snooping in turn, `alternate`) with the estimated sigmas."""
    from baarda.quality.variance_components import alternate, iterate

    tests = tests or TestOptions.resolve(result.block.settings)
    start = result.problem.active
    if do_snoop:
        qc, est = alternate(
            IndependentModel(result),
            lambda f: snoop(result.refit(start, f), tests=tests, statistic=statistic,
                            by_point=by_point, progress=progress),
            tests=tests, statistic=statistic, progress=progress)
        if external:
            qc = replace(qc, external=external_reliability(qc.model, qc.quality))
    else:
        est = iterate(IndependentModel(result), progress=progress)
        qc = assess(cast(IndependentModel, est.model).result, tests, external=external)
    return replace(qc, variance_components=est.components())
