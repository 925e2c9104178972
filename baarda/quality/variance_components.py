"""Variance components per observation group (Foerstner's / Helmert's estimate).

For a group k of observation components with weights P_k (from the a-priori sigmas), its
residuals v_k and its group redundancy r_k = sum of its redundancy numbers (r_i = (Qvv P)_ii),

    sigma_k^2 = v_k' P_k v_k / r_k

estimates the variance factor of that group (Foerstner 1979: unbiased when the other groups'
weights are right; iterated, the Helmert estimate).  Its standard deviation is about
sqrt(2 / r_k) sigma_k^2, and sigma_k^2 r_k ~ chi2(r_k) under H0 (the group's a-priori sigma
is right): the test of each factor against one, two-sided at `alpha`.  The r_k add up to
the redundancy, so the groups' v'Pv add up to the whole.

`estimate` computes them from any adjusted model of the quality layer; `iterate` re-weights
the groups by their factors and adjusts again until every factor is within `tolerance` of
one (with `tolerance` TOLERANCE: until the change still to come of each group's estimate,
from the geometric decrease of its factors, is below it, relative; the estimated sigmas are
then the a-priori sigma times the product of the factors' square roots).
Groups: the model's `variance_groups()` (a bundle: image per camera, control
X, Y, Z, GNSS X, Y, Z, IMU, distances; independent models: model XY, model Z, projection
centres, control X, Y, Z; a relative orientation: y-parallaxes, x'' of the tie points),
else kind (and component for control).

Weak groups: a group with r_k < MIN_REDUNDANCY is reported, not estimated (its estimate
could collapse to zero).  With `pool` (iterate's default), control (and GNSS) axes too weak
alone are estimated together: X and Y as planimetry XY when Z stands alone, else X, Y and
Z as one group (`pooling_plan`).  One rule, fixed by the first estimate (the adjustment
with the starting weights) and reported as applied: the pooling plan, and which groups are
estimated (r_k >= MIN_REDUNDANCY then).  A group not estimated then keeps its starting
weights in every iteration, even when re-weighting the others gives it more redundancy
later.  An estimated group whose r_k falls below MIN_REDUNDANCY in a later iteration is
frozen: its factor stays the product of the factors of the iterations before, and the
report says at which iteration (`VarianceComponent.frozen_at`).

Snooping with estimated sigmas (`alternate`): estimation and snooping in turn until the
rejections settle, then `challenge`: an observation is also tested against its group's
variance estimated without it (a gross error inflates its own group's estimate and can
hide behind it; in a small group one such error can double the estimate).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from baarda.errors import GeometryError
from baarda.kinds import BY_AXIS
from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.quality.adjusted_model import AdjustedModel
from baarda.quality.special_distributions import chi2_cdf
from baarda.quality.statistics import analyse, cofactors

if TYPE_CHECKING:
    from baarda.quality.assessment import Assessment

ALPHA = 0.05
# an iteration's factor f is the relative change of its group's cumulative factor, and
# |f - 1| shrinks geometrically (by rho per iteration, up to 0.93 for a weak group): iterate
# until the change still to come, |f - 1| / (1 - rho), is below TOLERANCE for every group,
# as Helmert's iteration is run to convergence (a stop at |f - 1| < 1 % left weak groups
# short by more than 1 %: GNSS XY 10.380 for 10.558)
TOLERANCE = 1e-5
MIN_REDUNDANCY = 5.0  # a group with less is reported, not re-weighted (it could collapse)
MAX_ITERATIONS = 200
POOLED = BY_AXIS  # families whose X, Y, Z groups are pooled when too weak (baarda/kinds.py)
AXES = ("X", "Y", "Z")


@dataclass(frozen=True)
class VarianceComponent:
    """One group: its number of active components, the a-priori sigma (median, in the
    model's units), the group redundancy r_k, v'Pv, the estimated factor sigma_k^2 and its
    standard deviation, the test of the factor against one."""

    group: str
    n: int
    sigma_apriori: float
    redundancy: float
    vtpv: float
    factor: float
    factor_std: float
    p_value: float
    rejected: bool
    estimated: float = float("nan")  # the iterated variance factor (--vce), sigma^2 ratio
    members: tuple[str, ...] = ()  # a pooled group: the groups estimated together
    pooled_into: str = ""  # a group too weak alone: the pooled group that estimates it
    frozen_at: int = 0  # iteration at which r_k fell below MIN_REDUNDANCY (0: never)
    frozen_redundancy: float = float("nan")  # its r_k then

    @property
    def sigma_estimated(self) -> float:
        f = self.estimated if np.isfinite(self.estimated) else self.factor
        return self.sigma_apriori * float(np.sqrt(f))

    def to_dict(self, scale: float = 1.0, unit: str = "") -> dict:
        """summary.json's entry; the sigmas times `scale`, in `unit` (the units of the
        group's kind in observations.csv)."""
        return {"group": self.group, "n": self.n, "sigma_apriori": self.sigma_apriori * scale,
                "unit": unit, "redundancy": self.redundancy, "vtpv": self.vtpv,
                "factor": _num(self.factor),
                "factor_std": _num(self.factor_std), "p_value": _num(self.p_value),
                "rejected": bool(self.rejected),
                "estimated_variance_factor": _num(self.estimated),
                "estimated_sigma_factor": _num(float(np.sqrt(self.estimated))
                                               if self.estimated >= 0 else float("nan")),
                "sigma_estimated": _num(self.sigma_estimated * scale),
                **({"frozen_at_iteration": self.frozen_at,
                    "frozen_redundancy": self.frozen_redundancy} if self.frozen_at else {}),
                **({"members": list(self.members)} if self.members else {}),
                **({"pooled_into": self.pooled_into} if self.pooled_into else {})}

    @property
    def groups(self) -> tuple[str, ...]:
        """The group names this component's factor applies to."""
        return self.members or (self.group,)

    @property
    def reweights(self) -> bool:
        """Its factor re-weights its groups (estimated, not pooled into another)."""
        return bool(np.isfinite(self.factor)) and not self.pooled_into

    def words(self) -> str:
        """What happened to a group that is not estimated by itself, in words."""
        if self.pooled_into:
            return (f"{self.group}: n {self.n}, r {self.redundancy:.2f}"
                    + (" (too little alone)" if self.redundancy < MIN_REDUNDANCY else "")
                    + f": estimated together with the other axes as {self.pooled_into}")
        if self.members:
            return (f"{self.group} ({', '.join(self.members)} together): n {self.n}, r "
                    f"{self.redundancy:.2f}: too little redundancy even together (< "
                    f"{MIN_REDUNDANCY:g}), not estimated")
        return (f"{self.group}: n {self.n}, r {self.redundancy:.2f}: too little redundancy "
                f"(< {MIN_REDUNDANCY:g}), not estimated")

    def line(self, scale: float = 1.0, unit: str = "") -> str:
        """The group in one line: first estimate (relative to the a-priori sigmas), its test,
        and the iterated estimate when there is one."""
        out = (f"{self.group}{' (' + ', '.join(self.members) + ')' if self.members else ''}: "
               f"n {self.n}, r {self.redundancy:.2f}, sigma a priori "
               f"{self.sigma_apriori * scale:.4g} {unit}, first estimate sigma^2 "
               f"{self.factor:.4f} +- {self.factor_std:.4f} (sigma x "
               f"{np.sqrt(self.factor):.4f}), p = {self.p_value:.3g} -> "
               + ("differs from 1" if self.rejected else "1 accepted"))
        if np.isfinite(self.estimated):
            out += (f"; iterated sigma^2 {self.estimated:.4f}: sigma x "
                    f"{np.sqrt(self.estimated):.4f} = {self.sigma_estimated * scale:.4g} {unit}")
        if self.frozen_at:
            out += (f" (frozen at iteration {self.frozen_at}: its redundancy fell to "
                    f"{self.frozen_redundancy:.2f} < {MIN_REDUNDANCY:g}; the factor of the "
                    "iterations before is kept)")
        return out.replace("  ", " ").rstrip()

    def summary(self, scale: float = 1.0, unit: str = "") -> str:
        """The group in one line: `line` when its factor re-weights it, else `words`."""
        return self.line(scale, unit) if self.reweights else self.words()


def _num(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def _component(name: str, sel: np.ndarray, r: np.ndarray, v: np.ndarray, s: np.ndarray,
               alpha: float, members: tuple[str, ...] = ()) -> VarianceComponent:
    rk = float(np.sum(r[sel]))
    vtpv = float(np.sum((v[sel] / s[sel]) ** 2))
    n, s_med = int(sel.sum()), float(np.median(s[sel]))
    if rk < MIN_REDUNDANCY:
        nan = float("nan")
        return VarianceComponent(name, n, s_med, rk, vtpv, nan, nan, nan, False,
                                 members=members)
    f = vtpv / rk
    lower = chi2_cdf(vtpv, rk)
    p = float(min(1.0, 2 * min(lower, 1 - lower)))
    return VarianceComponent(name, n, s_med, rk, vtpv, f, f * float(np.sqrt(2.0 / rk)), p,
                             p < alpha, members=members)


def pooling_plan(comps: list[VarianceComponent]) -> dict[str, tuple[str, ...]]:
    """Pooled groups for control (and GNSS) axes too weak alone (r_k < MIN_REDUNDANCY):
    planimetry X and Y together as '<kind> XY' when Z is strong enough by itself (or
    absent); when Z is weak too, every axis together ('<kind> XYZ').  A pooled group that
    is still too weak is reported, not estimated (a strong Z is not borrowed for X, Y)."""
    by = {c.group: c for c in comps}
    plan: dict[str, tuple[str, ...]] = {}
    for fam in POOLED:
        axes = [a for a in AXES if f"{fam} {a}" in by]
        r = {a: by[f"{fam} {a}"].redundancy for a in axes}
        weak = [a for a in axes if r[a] < MIN_REDUNDANCY]
        if len(axes) < 2 or not weak:
            continue
        xy = [a for a in axes if a in ("X", "Y")]
        if len(xy) == 2 and "Z" not in weak:
            axes = xy
        plan[f"{fam} {''.join(axes)}"] = tuple(f"{fam} {a}" for a in axes)
    return plan


def estimate(model, alpha: float = ALPHA, *, pool: bool = False,
             plan: dict[str, tuple[str, ...]] | None = None,
             redundancy_numbers: np.ndarray | None = None) -> list[VarianceComponent]:
    """The variance components of the groups of an adjusted model (module docstring); with
    `pool` or a `plan`, the pooled groups after them (their members marked pooled_into).
    `redundancy_numbers`: the model's, when they are at hand (analyse's)."""
    r = cofactors(model)[1] if redundancy_numbers is None else redundancy_numbers
    act = np.asarray(model.active, bool)
    v = model.residuals
    s = model.sigma
    g = model.variance_groups()
    out = [_component(str(name), act & (g == name), r, v, s, alpha)
           for name in dict.fromkeys(g[act].tolist())]
    if plan is None and pool:
        plan = pooling_plan(out)
    if not plan:
        return out
    into = {m: name for name, ms in plan.items() for m in ms}
    out = [replace(c, pooled_into=into[c.group]) if c.group in into else c for c in out]
    return out + [_component(name, act & np.isin(g, ms), r, v, s, alpha, members=tuple(ms))
                  for name, ms in plan.items() if np.any(act & np.isin(g, ms))]


@dataclass(frozen=True)
class VarianceEstimation:
    """The model adjusted with the estimated group sigmas, the weight factors that give
    them (one per component), the components of the last iteration (factors about one) and
    those of the first (relative to the starting weights), the cumulative factor per
    estimated group, the log of the iterations and the (q_vv, r) of the model
    (quality.statistics.cofactors, from the last estimate)."""

    model: AdjustedModel
    factors: np.ndarray
    first: list[VarianceComponent]
    last: list[VarianceComponent]
    group_factor: dict[str, float]
    log: list[str]
    converged: bool
    cofactors: tuple[np.ndarray, np.ndarray] | None = None  # (q_vv, r) of `model`
    frozen: dict[str, tuple[int, float]] = field(default_factory=dict)  # (iteration, r_k)

    @property
    def plan(self) -> dict[str, tuple[str, ...]]:
        """Pooled group -> its member groups (pooling_plan), fixed by the first estimate."""
        return {c.group: c.members for c in self.first if c.members}

    def components(self) -> tuple[VarianceComponent, ...]:
        """The first estimates with the iterated factor of each group (a pooled group's
        members: the pooled factor)."""
        nan = float("nan")

        def est(c):
            name = c.pooled_into or c.group
            return self.group_factor.get(name, nan)

        def frozen(c):
            at, r = self.frozen.get(c.group, (0, nan))
            return {"frozen_at": at, "frozen_redundancy": r}

        return tuple(replace(c, estimated=est(c), **frozen(c)) for c in self.first)


def iterate(model, alpha: float = ALPHA, tolerance: float = TOLERANCE,
            max_iterations: int = MAX_ITERATIONS,
            progress: Callable[[str], None] | None = None, *, pool: bool = True,
            plan: dict[str, tuple[str, ...]] | None = None) -> VarianceEstimation:
    """Re-weight every group by its estimated factor and adjust again until the factors are
    within `tolerance` of one (module docstring).  Starts from the model's own weight
    factors (a-priori weights: ones); weak control axes pooled (`pool`) or as `plan` says."""
    groups = model.variance_groups()
    factors = np.array(model.factors, float)  # rejected components included
    cof = cofactors(model)
    first = estimate(model, alpha, pool=pool, plan=plan, redundancy_numbers=cof[1])
    plan = {c.group: c.members for c in first if c.members}
    estimated = {c.group for c in first if c.reweights}  # fixed by the first estimate
    frozen: dict[str, tuple[int, float]] = {}  # group -> (iteration, its r_k then)
    cumulative: dict[str, float] = {g: 1.0 for g in estimated}
    log = []
    comps = first
    converged = False
    last_step: dict[str, float] = {}
    for it in range(1, max_iterations + 1):
        for c in comps:
            if c.group in estimated and c.group not in frozen and not c.reweights:
                frozen[c.group] = (it, c.redundancy)
        live = [c for c in comps if c.group in estimated and c.group not in frozen]
        worst = max((_still_to_come(c, last_step, tolerance) for c in live), default=0.0)
        last_step = {c.group: abs(c.factor - 1) for c in live}
        log.append(f"iteration {it}: " + ", ".join(
            f"{c.group} {c.factor:.4f}" + (" (held)" if c not in live else "")
            for c in comps if not c.pooled_into))
        if progress:
            progress("variance components " + log[-1])
        if worst < tolerance:
            converged = True
            break
        for c in live:
            if c.factor > 0:
                factors[np.isin(groups, c.groups)] /= c.factor
                cumulative[c.group] *= c.factor
        model = model.refit(np.asarray(model.active, bool), factors)
        cof = cofactors(model)
        comps = estimate(model, alpha, plan=plan, redundancy_numbers=cof[1])
    return VarianceEstimation(model, factors, first, comps, cumulative, log, converged, cof,
                              frozen)


def _still_to_come(c: VarianceComponent, last_step: dict[str, float],
                   tolerance: float) -> float:
    """The change of a group's estimate still to come, |f - 1| / (1 - rho), rho = |f - 1|
    over the iteration before's (the iteration's contraction, at most 0.999); |f - 1| where
    there is no iteration before.  Only used against tolerances below 0.001: a looser
    tolerance keeps the former rule, |f - 1|."""
    step = abs(c.factor - 1)
    before = last_step.get(c.group)
    if tolerance >= 1e-3 or not before or not np.isfinite(step):
        return step
    return step / (1.0 - min(step / before, 0.999))


def challenge(model, plan: dict | None = None, tests: TestOptions = DEFAULT_TESTS,
              statistic: str = "w", alpha: float = ALPHA,
              progress: Callable[[str], None] | None = None, *,
              known: tuple[np.ndarray, np.ndarray] | None = None) -> int | None:
    """An active component that is significant when its group's variance is estimated
    without it, or None.  `model`: adjusted with the estimated sigmas (snooping's last);
    `known`: its (q_vv, r) when they are at hand (quality.statistics.cofactors).

    In each estimated group the component with the largest |w| is a candidate when the
    leave-one-out factor, approximated by (v'Pv_k - w^2) / (r_k - r_i), could make it
    significant (|w| / sqrt(factor) > 0.9 k, or the approximation is not positive); the
    candidate is switched off, the factors estimated again (iterate, from the current
    weights) and its statistic (predicted residual) tested with them."""
    q = analyse(model, tests, known=known, separability=False)
    g = model.variance_groups()
    act = np.asarray(model.active, bool)
    cands = []
    for c in estimate(model, alpha, plan=plan or {}, redundancy_numbers=q.redundancy_number):
        if not c.reweights:
            continue
        sel = np.flatnonzero(act & q.controlled & np.isin(g, c.groups))
        if not len(sel):
            continue
        i = int(sel[np.argmax(np.abs(np.nan_to_num(q.w[sel])))])
        rest = (c.vtpv - q.w[i] ** 2) / max(c.redundancy - q.redundancy_number[i], 1e-12)
        loo = np.inf if rest <= 0 else abs(q.w[i]) / np.sqrt(rest)
        if loo > 0.9 * q.k_w:
            cands.append((loo, i, c.group))
    for _, i, name in sorted(cands, reverse=True):
        trial = act.copy()
        trial[i] = False
        try:
            est = iterate(model.refit(trial, model.factors), alpha, plan=plan or {})
        except GeometryError:
            continue
        q2 = analyse(est.model, tests, known=est.cofactors, separability=False)
        s2, k2 = (q2.w, q2.k_w) if statistic == "w" else (q2.tau, q2.k_tau)
        if progress:
            progress(f"variance components: component {i} of {name} tested against the "
                     f"group estimated without it: |{statistic}| {abs(s2[i]):.3f} "
                     f"(critical {k2:.3f})")
        if abs(s2[i]) > k2:
            return i
    return None


def alternate(model, snoop: Callable[[np.ndarray], Assessment], *, alpha: float = ALPHA,
              tests: TestOptions = DEFAULT_TESTS, statistic: str = "w",
              max_rounds: int = 10,
              progress: Callable[[str], None] | None = None):
    """Variance components and data snooping in turn (module docstring).

    `model`: adjusted with the a-priori weights; its active components are the start of
    every snooping.  `snoop(factors)`: data snooping of the method with those weight
    factors, from the start, returning an Assessment (its .model, .quality).  The factors
    are estimated from every component first, then from what snooping left, until the
    rejections no longer change; then `challenge` may reject one more component (the
    snooping again from the start with the factors estimated without it, so that it is
    tested like every other).  Returns (the last Assessment, its VarianceEstimation)."""
    start = np.asarray(model.active, bool)
    active = None
    est = qc = None
    for _ in range(max_rounds):
        base = model if active is None else model.refit(active, model.factors)
        est = iterate(base, alpha, progress=progress, plan=None if est is None else est.plan)
        qc = snoop(est.factors)
        now = np.asarray(qc.quality.active, bool)
        if np.array_equal(now, start if active is None else active):
            i = challenge(qc.model, est.plan, tests, statistic, alpha, progress,
                          known=(qc.quality.qvv, qc.quality.redundancy_number))
            if i is None:
                break
            now = now.copy()
            now[i] = False
        active = now
    else:
        assert qc is not None  # max_rounds >= 1
        qc.quality.notes.append(
            f"variance components and data snooping did not settle in {max_rounds} rounds: "
            "the last snooping and its estimate are reported")
    return qc, est
