"""The whole FOTEF procedure on a model block.

pre-adjustment search (large errors first) -> rigorous adjustment (3D, or planimetry with a
separate height adjustment) -> data snooping -> non-conventional alternative hypotheses
(model deformations, control clusters, user H) -> external reliability on detail points and
distances.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from baarda.block.model_block import ModelBlock
from baarda.block.model_deformations import ALL
from baarda.independent.model_hypotheses import (
    UserHypotheses,
    cluster_tests,
    decision,
    deformation_tests,
)
from baarda.independent.model_problem import ModelProblem
from baarda.independent.model_quality import (
    ModelQuality,
    assess,
    snoop,
    with_variance_components,
)
from baarda.independent.planimetric import check_tilts, height_possible, level
from baarda.independent.preadjust import PreAdjustment, preadjust
from baarda.options import Progress, TestOptions
from baarda.sections import Section, render, section

EXTERNAL_LIMIT = 400  # models: external reliability on detail points by default up to this


@dataclass(frozen=True)
class BlockQuality:
    """Outcome of `process`: the pre-adjustment and one ModelQuality per adjustment."""

    block: ModelBlock
    mode: str  # '3d' or '2d'
    pre: PreAdjustment
    parts: list[ModelQuality]
    tilts: np.ndarray | None = None  # (nm,) tilt [rad] removed by levelling (2d)
    notes: list[str] = field(default_factory=list)

    @property
    def converged(self) -> bool:
        """Every adjustment converged."""
        return all(p.adjustment.converged for p in self.parts)

    def part(self, mode: str) -> ModelQuality | None:
        return next((p for p in self.parts if p.mode == mode), None)

    def decision(self) -> str:
        tests = [t for p in self.parts for t in p.hypotheses]
        return decision(tests) if tests else ""

    def preadjustment_dict(self) -> dict:
        return {"findings": [f.to_dict() for f in self.pre.findings],
                "connection_order": self.pre.order, "notes": self.pre.notes}

    def to_dict(self) -> dict:
        """The outcome as a dict: the pre-adjustment, each adjustment's to_dict()."""
        d: dict[str, object] = {"mode": self.mode, "block": self.block.summary(),
             "preadjustment": self.preadjustment_dict(),
             "adjustments": {p.name: p.to_dict() for p in self.parts},
             "notes": self.notes + list(self.block.notes)}
        if self.tilts is not None:
            d["levelling_max_tilt_rad"] = float(np.max(np.abs(self.tilts), initial=0))
        dec = self.decision()
        if dec:
            d["decision"] = dec
        return d

    def sections(self) -> list[Section]:
        lines = self.pre.lines()
        if self.tilts is not None:
            lines.append(f"models levelled by up to {np.max(self.tilts) * 1e3:.3g} mrad "
                         "(tilts of a spatial adjustment) before the planimetric adjustment")
        out = [section("Pre-adjustment", lines)]
        for p in self.parts:
            out += p.sections()
        end = []
        dec = self.decision()
        if dec:
            end.append("Decision: " + dec)
        end += [f"note: {n}" for n in self.notes + list(self.block.notes)]
        if end:
            out.append(section("Conclusion", end))
        return out

    def summary(self) -> str:
        return render(self.sections())


def process(block: ModelBlock, mode: str = "3d", *, do_snoop: bool = True,
            statistic: str = "w", by_point: bool = False, tests: TestOptions | None = None,
            external: bool | None = None,
            deformations: tuple[str, ...] | None = ALL,
            clusters: dict[str, list[str]] | None = None,
            user: UserHypotheses | None = None, level_models: bool = False,
            vce: bool = False, progress: Progress | None = None) -> BlockQuality:
    """Run the whole procedure; mode '3d' or '2d' (planimetry + height).

    level_models (2d): level the models by the tilts of a spatial adjustment first.
    vce: variance components per group (model_quality.with_variance_components); the
    tests and snooping then use the estimated sigmas.
    """
    say = progress or (lambda msg: None)
    tests = tests or TestOptions.resolve(block.settings)
    if external is None:
        external = block.n_models <= EXTERNAL_LIMIT
    notes: list[str] = []
    if not external:
        notes.append("external reliability on detail points and distances not computed "
                      f"(more than {EXTERNAL_LIMIT} models; use --external)")
    pre = preadjust(ModelProblem(block, mode))
    say(f"pre-adjustment: {len(pre.findings)} large error(s) set aside")
    obs_keep, control_keep = ~pre.obs_flag, ~pre.control_flag
    tilts = None
    runs: list[tuple[ModelBlock, str, dict]] = []
    if mode == "3d":
        runs.append((block, "3d", {"start": (pre.params, pre.pts)}))
    else:
        reason = height_possible(block, control_keep)
        if reason is None:
            if level_models:
                block, tilts = level(block, obs_keep, control_keep, progress=say)
            runs.append((block, "2d", {"start": (pre.params, pre.pts)}))
            runs.append((block, "height", {}))
        else:
            notes.append(reason)
            runs.append((block, "2d", {"start": (pre.params, pre.pts)}))
    parts: list[ModelQuality] = []
    for blk, m, extra in runs:
        mu = parts[0].adjustment.params[:, 3] if m == "height" else None
        problem = ModelProblem(blk, m, obs_keep=obs_keep, control_keep=control_keep, mu=mu)
        res = problem.fit(extra.get("start"), progress=say)
        if m == "height":
            check_tilts(res)
        if vce:
            qc = with_variance_components(res, tests, do_snoop=do_snoop, statistic=statistic,
                                          by_point=by_point, external=external, progress=say)
        elif do_snoop:
            qc = snoop(res, tests=tests, statistic=statistic, by_point=by_point,
                       external=external, progress=say)
        else:
            qc = assess(res, tests, external=external)
        hyp = []
        if deformations:
            hyp += deformation_tests(qc.model, deformations, tests)
        if clusters:
            hyp += cluster_tests(qc.model, clusters, tests)
        if user is not None:
            hyp += user.tests(qc.model, tests)
        qc = replace(qc, hypotheses=tuple(hyp))
        parts.append(qc)
    return BlockQuality(block, mode, pre, parts, tilts, notes)
