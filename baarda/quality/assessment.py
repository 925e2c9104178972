"""The assessment of an adjustment: one results family for every method.

An Assessment holds an adjustment result, the quality layer's view of it (AdjustedModel)
and every statistic (QualityResult), with the snooping log and tested hypotheses.  Like a
statsmodels results object it gives arrays, `table()` (one row per observation component,
the one schema of observations.csv for every method), `to_dict()` (summary.json) and
`summary()`, built from `sections()` that the reports render too.

Units in tables and summaries: each model says how its kinds of observation are shown
(`AdjustedModel.units`: image and model coordinates in µm, control in m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Generic, Protocol, TypeVar

import numpy as np
import pandas as pd

from baarda.quality.adjusted_model import AdjustedModel
from baarda.quality.distributions import GlobalTest
from baarda.quality.hypotheses import (
    HypothesisTest,
    block_tests,
    group_test,
    hypothesis_test,
    image_point_tests,
)
from baarda.quality.iterative import SnoopingRun, joined_labels, labels
from baarda.quality.separability_report import separability_dict, separability_lines
from baarda.quality.statistics import QualityResult
from baarda.schema import OBSERVATION_COLUMNS
from baarda.sections import MAX_LISTED, Section, at_most, render, section


class AdjustmentResult(Protocol):
    """What an Assessment needs of a method's result (BundleResult, ModelResult,
    Orientation, ...): its summary.json fields and its text sections."""

    def to_dict(self) -> dict: ...

    def sections(self) -> list[Section]: ...


A = TypeVar("A", bound=AdjustmentResult)

# the columns of observations.csv, in this order, for every method (docs/format.md)
COLUMNS = OBSERVATION_COLUMNS  # observations.csv (baarda/schema.py)


def sigma0_interval(gt: GlobalTest) -> tuple[float, float]:
    """The two-sided confidence interval (level 1 - alpha) of sigma0 (a posteriori, in
    units of the a-priori sigma0): sqrt(omega / chi2 quantiles)."""
    return math.sqrt(gt.statistic / gt.upper), math.sqrt(gt.statistic / gt.lower)


def global_test_lines(q: QualityResult) -> list[str]:
    """The global test of the variance factor in words (the one place that says it): the
    headline test at the conventional level alpha_global (one-sided: sigma0 too large), the
    interval of sigma0 and a note when sigma0 is significantly below one; then the B-method's
    test, its alpha coupled to the w-tests' power."""
    gt, h = q.global_test, q.headline_test
    if gt is None or h is None:
        return ["global test: no redundancy"]
    lo, hi = sigma0_interval(h)
    low = hi < 1.0
    head = (f"global test at alpha {q.alpha_global:g}: sigma0^2 = {h.statistic:.4f}, critical "
            f"{h.critical:.4f}, p = {h.p_value:.3g}; sigma0 {math.sqrt(h.statistic):.4f}, "
            f"{100 * (1 - q.alpha_global):g} % interval [{lo:.4f}, {hi:.4f}] -> "
            f"{'accepted' if h.passed else 'REJECTED'}"
            + ("; sigma0 is significantly below 1: the a-priori sigmas are too pessimistic"
               if low else ""))
    b = (f"global test by the B-method (alpha {q.b_method_alpha:.3g}, coupled to the w-test's "
         f"power {q.beta0:g}): critical {gt.critical:.4f} -> "
         f"{'accepted' if gt.passed else 'REJECTED'}")
    if gt.passed != h.passed:
        b += (f" (not the verdict: the test at alpha {q.alpha_global:g} decides; coupled to "
              "the w-tests, this one looks for the variance factor of one error of MDB size"
              + (": see the largest |w|)" if not gt.passed else
                 ": the excess is spread over many observations)"))
    return [head, b]




def quality_lines(model: AdjustedModel, q: QualityResult,
                  suffix=lambda kind, sel: "") -> list[str]:
    """Test settings, global test, redundancy and per-kind reliability for people;
    suffix(kind, selection) adds a method's words to a kind's line."""
    lines = [f"alpha0 {q.alpha0}, beta0 {q.beta0}: delta0 {q.delta0:.3f}, critical |w| "
             f"{q.k_w:.3f}", *global_test_lines(q),
             f"sum of redundancy numbers {q.sum_redundancy_numbers:.3f} = redundancy "
             f"{q.redundancy}"]
    act = q.active & q.controlled
    for kind in dict.fromkeys(model.kind):
        sel = act & (model.kind == kind)
        if not sel.any():
            continue
        u, unit = model.units.get(kind, (1.0, ""))
        lines.append(f"{kind}: r mean {np.mean(q.redundancy_number[sel]):.3f} min "
                     f"{np.min(q.redundancy_number[sel]):.3f}; MDB max "
                     f"{np.max(q.mdb[sel]) * u:.4g} {unit}".rstrip() + "; max |w| "
                     f"{np.nanmax(np.abs(q.w[sel])):.2f}" + suffix(kind, sel))
    return lines


def observation_table(model: AdjustedModel, q: QualityResult | None = None,
                      name: str = "bundle") -> pd.DataFrame:
    """The observation table (COLUMNS) of a model: residuals, and the statistics of `q`
    (NaN without them: an adjustment written without quality control)."""
    return pd.DataFrame(observation_columns(model, q, name), columns=list(COLUMNS))


def observation_columns(model: AdjustedModel, q: QualityResult | None = None,
                        name: str = "bundle") -> dict[str, Any]:
    """`observation_table`'s columns (COLUMNS, in order) as arrays of one row per component
    (a text the same in every row as one str), without a DataFrame: the writers format
    them chunk by chunk (output/tables.py), so that a table of millions of rows is never
    held as a whole a second time."""
    m = model
    kinds, which = np.unique(np.asarray(m.kind, dtype=str), return_inverse=True)
    scale = np.array([m.units.get(str(k), (1.0, ""))[0] for k in kinds], float)[which]
    frame = np.asarray(m.frame, dtype=object)
    empty = np.full(m.n, "", dtype=object)
    xy = m.image_xy()
    nan = np.full(m.n, np.nan)
    cols = {"adjustment": name, "kind": m.kind,
            "photo": frame if m.frame_kind == "photo" else empty,
            "model": frame if m.frame_kind == "model" else empty,
            "point": m.point, "component": m.component, "x_mm": xy[:, 0], "y_mm": xy[:, 1],
            "residual": m.residuals * scale, "sigma": m.sigma * scale, "rejected": ~m.active,
            "flagged": np.zeros(m.n, bool), "external_point": empty}
    if q is not None:
        _, t2, _, _, _ = image_point_tests(m, q.tests)
        point_t = nan.copy()
        idx, _ = m.adjusted_cofactor_blocks()
        if len(t2):
            point_t[idx] = t2[:, None]
        for gidx, gq in m.other_cofactor_blocks():  # e.g. GNSS positions as a whole
            _, tg, _, _, _ = block_tests(m, gidx, gq, q.tests)
            if len(tg):
                point_t[gidx] = tg[:, None]
        cols.update({
            "sigma_residual": q.sigma_residual * scale, "redundancy": q.redundancy_number,
            "w": q.w, "tau": q.tau, "p_value": q.p_value, "mdb": q.mdb * scale,
            "lambda_bar": q.lambda_bar, "external_max": q.external_max,
            "external_point": q.external_point, "point_test": point_t, "flagged": q.flagged})
        if q.rho_max is not None:  # separability (quality/separability.py)
            assert q.rho_partner is not None and q.msb is not None  # computed with rho_max
            cols.update({"rho_max": q.rho_max, "msb": q.msb * scale,
                         "rho_partner": partner_labels(m, q.rho_partner)})
    cols.setdefault("rho_partner", empty)
    return {c: cols.get(c, nan) for c in COLUMNS}


def partner_labels(model: AdjustedModel, partner: np.ndarray):
    """(n,) the snooping log's label of each component's most correlated partner, or "":
    a pyarrow string array where the labels are joined by pyarrow (quality/iterative.py:
    pandas and the writers take it as the same text), else an object array."""
    has = partner >= 0
    if not has.any():
        return np.full(model.n, "", dtype=object)
    joined = joined_labels(model, np.where(has, partner, 0), keep=has)
    if joined is not None:
        return joined
    out = np.full(model.n, "", dtype=object)
    uniq, inv = np.unique(partner[has], return_inverse=True)
    out[has] = np.array(labels(model, uniq), dtype=object)[inv]
    return out


@dataclass(frozen=True)
class Assessment(Generic[A]):
    """An adjustment with the statistics of every observation (and the snooping log).

    adjustment: the method's result (BundleResult, ModelResult): arrays, counts and its own
    `sections()` and `to_dict()`; name: the adjustment in tables ("bundle", "3d", "2d",
    "height").
    """

    adjustment: A
    model: AdjustedModel
    quality: QualityResult
    run: SnoopingRun | None = None
    hypotheses: tuple[HypothesisTest, ...] = ()
    name: str = "bundle"
    variance_components: tuple = ()  # quality/variance_components.py (--vce)

    @property
    def rejected(self) -> np.ndarray:
        return ~self.quality.active

    # ------------------------------------------------------------ tests
    def point_test(self, point: str) -> HypothesisTest:
        """All observations of a point in error together (image or model, and control)."""
        rows = np.flatnonzero(self.model.point == point)
        if not len(rows):
            raise KeyError(f"no observations of point {point}")
        return group_test(self.model, rows, f"point {point}", self.quality.tests)

    def frame_test(self, frame: str) -> HypothesisTest:
        """All observations of a photo (bundle) or a model (independent models) in error."""
        rows = np.flatnonzero(self.model.frame == frame)
        if not len(rows):
            raise KeyError(f"no observations on {self.model.frame_kind} {frame}")
        return group_test(self.model, rows, f"{self.model.frame_kind} {frame}",
                          self.quality.tests)

    def photo_test(self, photo: str) -> HypothesisTest:
        """All image observations of a photo in error together."""
        return self.frame_test(photo)

    def hypothesis_test(self, h: np.ndarray, name: str = "H") -> HypothesisTest:
        """A non-conventional alternative hypothesis: h (n, q) over the observation vector."""
        return hypothesis_test(self.model, h, name, self.quality.tests)

    @cached_property
    def separability(self) -> dict:
        """summary.json's "separability" (quality/separability_report.py; {} without the
        separability), computed once: the summary and summary.json both state it."""
        return separability_dict(self.model, self.quality)

    # ------------------------------------------------------------ tables
    def table(self) -> pd.DataFrame:
        """One row per observation component (observations.csv), in the model's units."""
        cols = self.columns()
        return pd.DataFrame(cols, columns=list(cols))

    def columns(self) -> dict[str, Any]:
        """`table()`'s columns as arrays (observation_columns), the method's own after the
        common ones: what the writers format, chunk by chunk."""
        return {**observation_columns(self.model, self.quality, self.name),
                **self.extra_columns()}

    def extra_columns(self) -> dict[str, np.ndarray]:
        """Method-specific columns after the common ones (none by default)."""
        return {}

    def hypotheses_table(self) -> pd.DataFrame:
        return pd.DataFrame([{
            "adjustment": self.name, "hypothesis": t.name, "q": t.q, "statistic": t.statistic,
            "critical": t.critical, "p_value": t.p_value, "rejected": t.rejected,
            "w": t.w, "mdb": t.mdb,
            "nabla": " ".join(f"{v:.6g}" for v in np.atleast_1d(t.nabla))}
            for t in self.hypotheses], columns=["adjustment", "hypothesis", "q", "statistic",
                                                "critical", "p_value", "rejected", "w", "mdb",
                                                "nabla"])

    # ------------------------------------------------------------ summaries
    def quality_dict(self) -> dict:
        """The statistics' part of summary.json."""
        q = self.quality
        gt, h = q.global_test, q.headline_test
        return {
            "global_test": None if h is None else {
                "statistic": h.statistic, "critical": h.critical, "alpha": q.alpha_global,
                "p_value": h.p_value, "passed": bool(h.passed),
                "sigma0_interval": list(sigma0_interval(h)),
                "sigma0_below_one": bool(sigma0_interval(h)[1] < 1.0)},
            "global_test_b_method": None if gt is None else {
                "statistic": gt.statistic, "critical": gt.critical, "alpha": q.b_method_alpha,
                "p_value": gt.p_value, "passed": bool(gt.passed)},
            "alpha0": q.alpha0, "beta0": q.beta0, "delta0": q.delta0, "k_w": q.k_w,
            "k_tau": q.k_tau, "sum_redundancy_numbers": q.sum_redundancy_numbers,
            "n_rejected": int(np.sum(~q.active)),
            "n_flagged": int(np.sum(q.flagged)),
            "n_uncontrolled": int(np.sum(q.active & ~q.controlled)),
            **({"separability": self.separability} if q.rho_max is not None else {}),
            "rejection_log": [] if self.run is None else
            [self._log_entry(s) for s in self.run.log],
            "snooping_converged": None if self.run is None else self.run.converged,
            "snooping_incomplete": (self.run.incomplete or None) if self.run else None,
            "hypotheses": [{"name": t.name, "q": t.q, "statistic": t.statistic,
                            "critical": t.critical, "rejected": t.rejected,
                            "nabla": np.atleast_1d(t.nabla).tolist()} for t in self.hypotheses],
            **({"variance_components": [c.to_dict(*self.group_unit(c.group))
                                        for c in self.variance_components]}
               if self.variance_components else {}),
        }

    def group_unit(self, group: str) -> tuple[float, str]:
        """(scale, unit) of a variance-component group's sigmas: those of its kind (the
        group's first word) in observations.csv, the same in summary.json, the text and the
        HTML report."""
        return self.model.units.get(group.split()[0], (1.0, ""))

    def _log_entry(self, step) -> dict:
        """A snooping step for summary.json, its MDB in the units of observations.csv
        (image and model coordinates µm, control m)."""
        scale, unit = self.model.units.get(str(self.model.kind[step.rows[0]]), (1.0, ""))
        return dict(step.to_dict(), mdb=step.mdb * scale, mdb_unit=unit,
                    adjustment=self.name)

    def to_dict(self) -> dict:
        """summary.json of this adjustment: the adjustment's fields, then the statistics';
        `notes` are the adjustment's and the statistics' notes."""
        adj = self.adjustment.to_dict()
        notes = list(adj.pop("notes", [])) + list(self.quality.notes)
        units = {str(k): u for k, (_, u) in self.model.units.items()}
        return {"adjustment": self.name, **adj, **self.quality_dict(), "units": units,
                "notes": notes}

    def quality_sections(self) -> list[Section]:
        q = self.quality
        lines = (quality_lines(self.model, q, self.kind_suffix)
                 + separability_lines(self.separability, self.model.frame_kind)
                 + self.extra_quality_lines())
        if self.run is not None:
            lines += self.run.summary_lines()
        params = [t for t in self.hypotheses if t.parameters]
        others = [t for t in self.hypotheses if not t.parameters]
        if params:
            lines.append("significance of the estimated parameters at the 5 % level (H0: no "
                         "effect; the interior orientation against its given values):")
            rest = params[MAX_LISTED:] if len(params) > MAX_LISTED + 1 else []
            sig = sum(bool(t.rejected) for t in rest)
            lines += ["  " + x for x in at_most(
                [t.summary() for t in params], f"test(s): {sig} significant, "
                f"{len(rest) - sig} not (every test in summary.json's \"hypotheses\")")]
        if others:
            lines.append("alternative hypotheses:")
            lines += ["  " + t.summary() for t in others]
            lines += self.conclusion_lines()
        if self.variance_components:
            lines.append("variance components per group (Foerstner; the tests and snooping "
                         "use the estimated sigmas):")
            for c in self.variance_components:
                lines.append("  " + c.summary(*self.group_unit(c.group)))
        lines += [f"note: {n}" for n in q.notes]
        title = "Quality control" + ("" if self.name == "bundle" else f" ({self.name})")
        return [section(title, lines)]

    def kind_suffix(self, kind: str, sel: np.ndarray) -> str:
        """Method-specific words after a kind's reliability line (none by default)."""
        return ""

    def extra_quality_lines(self) -> list[str]:
        """Method-specific lines of the quality section (none by default)."""
        return []

    def conclusion_lines(self) -> list[str]:
        """A method's conclusion from the tested hypotheses (none by default)."""
        return []

    def sections(self) -> list[Section]:
        return list(self.adjustment.sections()) + self.quality_sections()

    def summary(self) -> str:
        return render(self.sections())
