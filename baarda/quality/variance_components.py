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
one (the estimated sigmas are then the a-priori sigma times the product of the factors'
square roots).  Groups: the model's `variance_groups()` (a bundle: image per camera, control
X, Y, Z, GNSS X, Y, Z, IMU, distances), else kind (and component for control).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from baarda.quality.statistics import cofactors

ALPHA = 0.05
TOLERANCE = 0.01  # in the factor: a quarter of the best precision seen (sqrt(2 / r), r 1400)
MIN_REDUNDANCY = 5.0  # a group with less is reported, not re-weighted (it could collapse)
MAX_ITERATIONS = 50


def groups_of(model) -> np.ndarray:
    """(n,) group name of every component (the model's variance_groups() when it has one)."""
    if hasattr(model, "variance_groups"):
        return np.asarray(model.variance_groups(), dtype=object)
    kind = np.asarray(model.kind, dtype=object)
    comp = np.asarray(model.component, dtype=object)
    return np.where(kind == "control", kind + " " + comp, kind).astype(object)


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
    estimated: float = float("nan")  # the iterated factor (--vce), relative to a priori

    @property
    def sigma_estimated(self) -> float:
        f = self.estimated if np.isfinite(self.estimated) else self.factor
        return self.sigma_apriori * float(np.sqrt(f))

    def to_dict(self) -> dict:
        return {"group": self.group, "n": self.n, "sigma_apriori": self.sigma_apriori,
                "redundancy": self.redundancy, "vtpv": self.vtpv, "factor": _num(self.factor),
                "factor_std": _num(self.factor_std), "p_value": _num(self.p_value),
                "rejected": bool(self.rejected), "estimated_factor": _num(self.estimated),
                "sigma_estimated": _num(self.sigma_estimated)}

    def line(self, scale: float = 1.0, unit: str = "") -> str:
        return (f"{self.group}: n {self.n}, r {self.redundancy:.2f}, sigma a priori "
                f"{self.sigma_apriori * scale:.4g} {unit}, factor sigma^2 {self.factor:.4f} "
                f"+- {self.factor_std:.4f} (sigma x {np.sqrt(self.factor):.4f} = "
                f"{self.sigma_estimated * scale:.4g} {unit}), p = {self.p_value:.3g} -> "
                + ("differs from 1" if self.rejected else "1 accepted")).replace("  ", " ")


def _num(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def estimate(model, alpha: float = ALPHA) -> list[VarianceComponent]:
    """The variance components of the groups of an adjusted model (module docstring)."""
    _, r = cofactors(model)
    act = np.asarray(model.active, bool)
    v = model.residuals
    s = model.sigma
    g = groups_of(model)
    out = []
    for name in dict.fromkeys(g[act].tolist()):
        sel = act & (g == name)
        rk = float(np.sum(r[sel]))
        vtpv = float(np.sum((v[sel] / s[sel]) ** 2))
        if rk < MIN_REDUNDANCY:
            out.append(VarianceComponent(str(name), int(sel.sum()), float(np.median(s[sel])),
                                         rk, vtpv, float("nan"), float("nan"), float("nan"),
                                         False))
            continue
        f = vtpv / rk
        lower = float(chi2.cdf(vtpv, rk))
        p = float(min(1.0, 2 * min(lower, 1 - lower)))
        out.append(VarianceComponent(str(name), int(sel.sum()), float(np.median(s[sel])),
                                     rk, vtpv, f, f * float(np.sqrt(2.0 / rk)), p, p < alpha))
    return out


@dataclass(frozen=True)
class VarianceEstimation:
    """The model adjusted with the estimated group sigmas, the weight factors that give
    them (one per component), the components of the last iteration (factors about one) and
    those of the first (relative to the a-priori sigmas), the cumulative factor per group,
    and the log of the iterations."""

    model: object
    factors: np.ndarray
    first: list[VarianceComponent]
    last: list[VarianceComponent]
    group_factor: dict[str, float]
    log: list[str]
    converged: bool

    def components(self) -> tuple[VarianceComponent, ...]:
        """The first estimates with the iterated factor of each group."""
        from dataclasses import replace

        return tuple(replace(c, estimated=self.group_factor.get(c.group, float("nan"))
                             if np.isfinite(c.factor) else float("nan")) for c in self.first)

    def lines(self, units: dict | None = None) -> list[str]:
        out = [f"variance components per group (Foerstner), estimated in {len(self.log)} "
               f"iteration(s){'' if self.converged else ' (NOT converged)'}:"]
        for c in self.first:
            f = self.group_factor.get(c.group, float("nan"))
            if not np.isfinite(c.factor):
                out.append(f"  {c.group}: n {c.n}, r {c.redundancy:.2f}: too little "
                           f"redundancy (< {MIN_REDUNDANCY:g}), not estimated")
                continue
            out.append(f"  {c.group}: n {c.n}, r {c.redundancy:.2f}, first estimate sigma^2 "
                       f"{c.factor:.4f} +- {c.factor_std:.4f}, p = {c.p_value:.3g} -> "
                       f"{'differs from 1' if c.rejected else '1 accepted'}; estimated "
                       f"sigma = a priori x {np.sqrt(f):.4f}")
        return out


def iterate(model, alpha: float = ALPHA, tolerance: float = TOLERANCE,
            max_iterations: int = MAX_ITERATIONS,
            progress: Callable[[str], None] | None = None) -> VarianceEstimation:
    """Re-weight every group by its estimated factor and adjust again until the factors are
    within `tolerance` of one (module docstring)."""
    groups = groups_of(model)
    factors = np.ones(model.n)  # relative to the a-priori sigmas (rejected ones included)
    first = estimate(model, alpha)
    cumulative = {c.group: 1.0 for c in first}
    log = []
    comps = first
    converged = False
    for it in range(1, max_iterations + 1):
        worst = max((abs(c.factor - 1) for c in comps if np.isfinite(c.factor)), default=0.0)
        log.append(f"iteration {it}: " + ", ".join(
            f"{c.group} {c.factor:.4f}" for c in comps))
        if progress:
            progress("variance components " + log[-1])
        if worst < tolerance:
            converged = True
            break
        for c in comps:
            if np.isfinite(c.factor) and c.factor > 0:
                factors[groups == c.group] /= c.factor
                cumulative[c.group] *= c.factor
        model = model.refit(np.asarray(model.active, bool), factors)
        comps = estimate(model, alpha)
    return VarianceEstimation(model, factors, first, comps, cumulative, log, converged)
