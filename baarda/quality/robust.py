"""Robust pre-screening by re-weighting (the Danish method, Krarup and Kubik).

Before data snooping, large errors are down-weighted iteratively: with the standardised
residual w_i = v_i / (sigma_i sqrt(r_i)) (a-priori sigma, redundancy number of the current
weights) the weight factor is

    f_i = 1                              |w_i| <= c
    f_i = exp(1 - (|w_i| / c)^2)         |w_i| >  c      (continuous at c)

until the factors settle.  Components whose factor falls below `reject_below` are handed
to data snooping as rejected; snooping tests them again and restores those that fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.quality.adjusted_model import AdjustedModel
from baarda.quality.statistics import cofactors


@dataclass
class RobustResult:
    factors: np.ndarray  # (n,) final weight factors
    rejected: np.ndarray  # (n,) bool: factor below the threshold
    iterations: int
    converged: bool


def danish_method(model: AdjustedModel, c: float = 3.0, max_iterations: int = 20,
                  tol: float = 1e-3, reject_below: float = 0.01) -> RobustResult:
    """Iterate weight factors from `model` (a-priori weights); each step adjusts again by
    `model.refit(model.active, factors)`: weights p_i * factors_i."""
    sigma_apriori = model.sigma_apriori
    f = np.ones(model.n)
    current = model if np.all(model.factors == 1.0) else model.refit(model.active, f)
    for it in range(1, max_iterations + 1):
        _, r = cofactors(current)
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.abs(current.residuals) / (sigma_apriori * np.sqrt(r))
        w = np.where(np.isfinite(w) & (r > 1e-3), w, 0.0)
        new = np.where(w > c, np.exp(1.0 - (w / c) ** 2), 1.0)
        new = np.maximum(new, 1e-12)
        done = np.max(np.abs(new - f)) < tol
        f = new
        if done:
            return RobustResult(f, f < reject_below, it, True)
        current = current.refit(current.active, f)
    return RobustResult(f, f < reject_below, max_iterations, False)
