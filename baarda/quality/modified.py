"""Gruen's (1980) modified data snooping: approximate sqrt(qvv), exact values only in a band.

With approximate values sqrt(qvv0) (unit weight: sqrt(r0), r0 the redundancy number) that are
trusted to +-k_q (Gruen eq. 7, k_q = 25 % by default), one adjustment decides every
observation component i:

    reject   |v_i| > c (1 + k_q) sigma0 sigma_i sqrt(r0_i)                       (eq. 9)
    accept   |v_i| < c (1 - k_q) sigma0 sigma_i sqrt(r0_i)                       (eq. 10)
    else     compute the exact r_i and test w_i = -v_i / (sigma0 sigma_i sqrt(r_i))  (eq. 11)

The exact values come from Gruen's identity-matrix observation (eq. 12-17): with f = e_i as
observation vector, A N^-1 A^T P e_i = AdjustedModel.solve_columns(e_i) and
r_i = 1 - (A N^-1 A^T P e_i)_i (quality.statistics.qvv_columns); the columns of the band are
solved in batches.

statistic 'w': sigma0 = 1 (a priori) and c = k_w of the B-method (Baarda's w-test);
statistic 'tau': sigma0 = sigma0_hat and c = Pope's tau critical value (Gruen's eq. 8).
Whenever the exact sqrt(r_i) lies within +-k_q of sqrt(r0_i) the decision equals the rigorous
one; only components whose approximation is outside the band can be decided otherwise.
Rejected (inactive) components are not tested here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.quality.adjusted_model import AdjustedModel
from baarda.quality.distributions import b_method, tau_critical
from baarda.quality.statistics import R_MIN, qvv_columns


@dataclass
class ModifiedSnooping:
    """Decisions of the modified data snooping for every component of a model."""

    approx: np.ndarray  # (n,) approximate sqrt(r) (Gruen's sqrt(qvv0) at unit weight)
    approximated: np.ndarray  # (n,) bool: active with a usable approximation
    w0: np.ndarray  # (n,) test statistic with the approximate value
    exact: np.ndarray  # (n,) bool: exact redundancy number computed (inside the band)
    redundancy_number: np.ndarray  # (n,) exact r where computed, NaN elsewhere
    statistic_value: np.ndarray  # (n,) exact statistic where computed, else w0
    rejected: np.ndarray  # (n,) bool: decision
    tested: np.ndarray  # (n,) bool: active and decided (not uncontrolled)
    statistic: str
    critical: float
    k_q: float
    sigma0: float

    @property
    def n_exact(self) -> int:
        """How many exact qvv values were needed."""
        return int(np.count_nonzero(self.exact))

    @property
    def n_tested(self) -> int:
        return int(np.count_nonzero(self.tested))

    def summary(self) -> str:
        n_act = int(np.count_nonzero(self.tested | self.exact))
        n_band = int(np.count_nonzero(self.exact & self.approximated))
        return (f"modified data snooping ({self.statistic}, k_q = {self.k_q:.0%}, critical "
                f"{self.critical:.3f}): {int(np.sum(self.rejected))} rejected, "
                f"{self.n_exact} exact qvv of {n_act} components "
                f"({self.n_exact / max(n_act, 1):.1%}): {n_band} inside the band, "
                f"{self.n_exact - n_band} without an approximation")


def exact_redundancy_numbers(model: AdjustedModel, rows: np.ndarray,
                             batch: int = 256) -> np.ndarray:
    """r_i = (Qvv)_ii / sigma_i^2 for the active components `rows`, by Gruen's
    identity-matrix observation (quality.statistics.qvv_columns, eq. 12-17) in batches."""
    rows = np.asarray(rows, dtype=np.int64)
    if np.any(~model.active[rows]):
        raise ValueError("exact redundancy numbers by eq. 17 need active components")
    out = np.empty(len(rows))
    for s in range(0, len(rows), batch):
        part = rows[s:s + batch]
        col = qvv_columns(model, part)
        out[s:s + batch] = col[part, np.arange(len(part))] / model.sigma[part] ** 2
    return out


def modified_snooping(model: AdjustedModel, approx_sqrt_r: np.ndarray, *, k_q: float = 0.25,
                      tests: TestOptions = DEFAULT_TESTS, statistic: str = "w",
                      r_min: float = R_MIN, batch: int = 256) -> ModifiedSnooping:
    """Gruen's modified data snooping of `model` with approximate sqrt(r) values.

    approx_sqrt_r: (n,) approximate sqrt(qvv / sigma^2); NaN (no approximation) or values
    below sqrt(r_min) send the component to the exact computation.  k_q: relative tolerance
    of the approximations (0.25 = Gruen's 25 %).
    """
    if not 0.0 <= k_q < 1.0:
        raise ValueError(f"k_q must lie in [0, 1), got {k_q}")
    approx = np.asarray(approx_sqrt_r, float)
    if approx.shape != (model.n,):
        raise ValueError(f"approx_sqrt_r has shape {approx.shape}, the model has {model.n} "
                         "components")
    v, s, act = model.residuals, model.sigma, model.active
    red = model.redundancy
    if statistic == "w":
        s0, crit = 1.0, b_method(tests.alpha0, tests.beta0).k_w
    elif statistic == "tau":
        if red < 2:
            raise ValueError("Pope's tau needs a redundancy of at least 2")
        s0 = float(np.sqrt(np.sum((v[act] / s[act]) ** 2) / red))
        crit = tau_critical(tests.alpha0, red)
    else:
        raise ValueError(f"statistic must be 'w' or 'tau', got {statistic!r}")
    usable = act & np.isfinite(approx) & (approx >= np.sqrt(r_min))
    with np.errstate(divide="ignore", invalid="ignore"):
        sv0 = s0 * s * np.where(usable, approx, np.nan)
        w0 = np.where(usable, -v / sv0, np.nan)
    mag = np.abs(v)
    reject0 = usable & (mag > crit * (1 + k_q) * sv0)
    accept0 = usable & (mag < crit * (1 - k_q) * sv0)
    band = act & ~reject0 & ~accept0
    rows = np.flatnonzero(band)
    r = np.full(model.n, np.nan)
    r[rows] = np.clip(exact_redundancy_numbers(model, rows, batch), 0.0, None)
    controlled = r[rows] >= r_min
    stat = w0.copy()
    with np.errstate(divide="ignore", invalid="ignore"):
        stat[rows] = np.where(controlled, -v[rows] / (s0 * s[rows] * np.sqrt(r[rows])), np.nan)
    rejected = reject0.copy()
    rejected[rows] = controlled & (np.abs(np.nan_to_num(stat[rows])) > crit)
    tested = reject0 | accept0
    tested[rows] = controlled
    return ModifiedSnooping(approx=approx, approximated=usable, w0=w0, exact=band,
                            redundancy_number=r, statistic_value=stat, rejected=rejected,
                            tested=tested,
                            statistic=statistic, critical=float(crit), k_q=k_q, sigma0=s0)
