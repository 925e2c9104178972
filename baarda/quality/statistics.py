"""Data snooping and reliability of every observation (Baarda 1968; Gruen 1980; Kratky 1983).

Conventions: residual v = adjusted - observed; weight p = 1/sigma^2 with sigma0 = 1 a
priori; cofactors in observation units squared.

    q_vv  = sigma^2 - q_ll^   (active)        q_vv = sigma^2 + q_ll^   (rejected: predicted)
    r     = q_vv / sigma^2                    (redundancy number, (Qvv P)_ii)
    sigma_v = sqrt(q_vv)                      (= sigma * sqrt(r) for active components)
    w     = -v / sigma_v                      (sign of the error in the observation)
    tau   = w / sigma0_hat                    (Pope)
    MDB   = delta0 * sigma / sqrt(r)          (boundary value, internal reliability)
    lambda_bar = delta0 * sqrt((1 - r) / r)   (external reliability, normalised)
    effect = MDB * dX/dl                      (on the adjusted coordinates of a point)
    rho_max = max_j |q_vv,ij| / sqrt(q_vv,ii q_vv,jj)   (j sharing a point or a frame)
    MSB   = MDB * delta_s(rho_max) / delta0   (minimal separable bias, quality/separability.py)
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.quality.adjusted_model import AdjustedModel
from baarda.quality.distributions import (
    GlobalTest,
    b_method,
    global_test,
    tau_critical,
    w_test_pvalue,
)
from baarda.quality.separability import separable_delta, w_correlations

R_MIN = 1e-3  # redundancy numbers below this: uncontrolled, not tested


@dataclass(frozen=True)
class QualityResult:
    """Per-component statistics, as arrays aligned with the model's observation vector."""

    residual: np.ndarray
    sigma: np.ndarray
    active: np.ndarray
    qvv: np.ndarray
    redundancy_number: np.ndarray
    sigma_residual: np.ndarray
    w: np.ndarray
    tau: np.ndarray
    p_value: np.ndarray
    mdb: np.ndarray
    lambda_bar: np.ndarray
    external: np.ndarray  # (n, 3) effect of the MDB on a point's coordinates
    external_max: np.ndarray  # (n,) largest coordinate effect
    external_point: np.ndarray  # (n,) label of that point
    controlled: np.ndarray  # r >= R_MIN
    flagged: np.ndarray  # active, controlled and |w| > k
    redundancy: int
    vtpv: float
    sigma0_hat: float
    k_w: float
    k_tau: float
    alpha0: float
    beta0: float
    delta0: float
    b_method_alpha: float
    global_test: GlobalTest | None = None  # the B-method's (alpha coupled to the w-test's power)
    notes: list[str] = field(default_factory=list)
    alpha_global: float = TestOptions.alpha_global
    headline_test: GlobalTest | None = None  # the global test at the conventional alpha_global
    # separability (quality/separability.py); None when not computed (inside snooping)
    rho_max: np.ndarray | None = None  # (n,) largest |rho| with a tested neighbour, NaN
    rho_partner: np.ndarray | None = None  # (n,) that neighbour's index, -1: none
    msb: np.ndarray | None = None  # (n,) minimal separable bias (model units), inf: none

    @property
    def tests(self) -> TestOptions:
        return TestOptions(self.alpha0, self.beta0, self.alpha_global)

    @property
    def sum_redundancy_numbers(self) -> float:
        return float(np.sum(self.redundancy_number[self.active]))


def cofactors(model: AdjustedModel) -> tuple[np.ndarray, np.ndarray]:
    """q_vv and redundancy numbers r, with cancellation guarded.

    For a rejected (inactive) component q_vv is the cofactor of its predicted residual,
    sigma^2 + q_ll^, and r the redundancy number it would have if it were put back,
    sigma^2 / (sigma^2 + q_ll^) (a rank-one update of N).
    """
    return residual_cofactors(model.adjusted_cofactor_diag(), model.sigma, model.active)


def residual_cofactors(qhat: np.ndarray, sigma: np.ndarray, active: np.ndarray | bool = True
                       ) -> tuple[np.ndarray, np.ndarray]:
    """(q_vv, r) of components from q_ll^ = diag(A N^-1 A^T) and their sigmas (`cofactors`;
    the on-line bundle's from its factorisation)."""
    qhat = np.maximum(qhat, 0.0)
    s2 = sigma**2
    qvv = np.where(active, s2 - qhat, s2 + qhat)
    # cancellation: q_ll^ cannot exceed sigma^2 for an active component
    qvv = np.where(active & (qvv < 1e-12 * s2), 0.0, qvv)
    r = np.where(active, qvv / s2, s2 / (s2 + qhat))
    return qvv, r


def w_tests(v: np.ndarray, sigma: np.ndarray, qvv: np.ndarray, r: np.ndarray, delta0: float,
            controlled: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(sigma_v, w, MDB, controlled) of components from their residuals v, sigmas, residual
    cofactors q_vv and redundancy numbers r (module docstring): every consumer's w-test
    and internal reliability (`analyse`; the on-line bundle, online/addition_tests.py).
    `controlled`: the components tested (default r >= R_MIN); the others have w NaN and an
    infinite MDB."""
    if controlled is None:
        controlled = r >= R_MIN
    with np.errstate(divide="ignore", invalid="ignore"):
        sv = np.sqrt(qvv)
        w = np.where(controlled, -v / sv, np.nan)
        mdb = np.where(controlled, delta0 * sigma / np.sqrt(r), np.inf)
    return sv, w, mdb, controlled


def analyse(model: AdjustedModel, tests: TestOptions = DEFAULT_TESTS,
            r_min: float = R_MIN, *,
            known: tuple[np.ndarray, np.ndarray] | None = None,
            separability: bool = True) -> QualityResult:
    """Every statistic of data snooping and reliability for every component of `model`.
    `known`: its (q_vv, r) from `cofactors(model)` when they are at hand (not computed
    again); `separability`: the w-test correlations and the MSB as well (snooping's
    intermediate adjustments leave them out)."""
    alpha0, beta0 = tests.alpha0, tests.beta0
    bm = b_method(alpha0, beta0)
    v, s, act = model.residuals, model.sigma, model.active
    qvv, r = cofactors(model) if known is None else known
    red = model.redundancy
    vtpv = float(np.sum((v[act] / s[act]) ** 2))
    s0 = float(np.sqrt(vtpv / red)) if red > 0 else np.nan
    # a rejected component is testable whenever it can be predicted: its predicted residual
    # has cofactor sigma^2 + q_ll^ (restored when it fits, even if nothing else would control
    # it); one whose unknowns are undetermined without it (infinite q_ll^) is not
    sv, w, mdb, controlled = w_tests(v, s, qvv, r, bm.delta0,
                                     (r >= r_min) | (~act & np.isfinite(qvv)))
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = w / s0
        lam = np.where(controlled & act, bm.delta0 * np.sqrt(np.clip(1 - r, 0, None) / r),
                       np.inf)
    effect_unit, labels = model.point_effect()
    external = effect_unit * np.where(np.isfinite(mdb), mdb, np.nan)[:, None]
    ext_abs = np.abs(external)
    ext_max = np.max(np.where(np.isnan(ext_abs), -np.inf, ext_abs), axis=1, initial=-np.inf)
    ext_max = np.where(controlled & act, ext_max, np.where(controlled, np.nan, np.inf))
    k_tau = tau_critical(alpha0, red) if red >= 2 else np.nan
    ga = bm.alpha_for(red) if red > 0 else np.nan
    gt = global_test(vtpv, red, ga) if red > 0 else None
    headline = global_test(vtpv, red, tests.alpha_global) if red > 0 else None
    notes = []
    total = float(np.sum(r[act]))
    if red > 0 and abs(total - red) > 1e-6 * red:
        notes.append(f"the redundancy numbers add up to {total:.6f}, not to the redundancy "
                     f"{red}: the normal equations are ill-conditioned")
    unc = int(np.sum(act & ~controlled))
    if unc:
        notes.append(f"{unc} observation component(s) with redundancy number below {r_min} are "
                     "not controlled by other observations: an error in them cannot be "
                     "detected (not tested)")
    out = QualityResult(
        residual=v, sigma=s, active=act, qvv=qvv, redundancy_number=r, sigma_residual=sv,
        w=w, tau=tau, p_value=w_test_pvalue(np.nan_to_num(w)) * np.where(controlled, 1, np.nan),
        mdb=mdb, lambda_bar=lam, external=external, external_max=ext_max,
        external_point=labels, controlled=controlled,
        flagged=act & controlled & (np.abs(np.nan_to_num(w)) > bm.k_w), redundancy=red,
        vtpv=vtpv, sigma0_hat=s0, k_w=bm.k_w, k_tau=k_tau, alpha0=alpha0, beta0=beta0,
        delta0=bm.delta0, b_method_alpha=ga, global_test=gt, notes=notes,
        alpha_global=tests.alpha_global, headline_test=headline)
    return with_separability(model, out) if separability else out


def with_separability(model: AdjustedModel, q: QualityResult) -> QualityResult:
    """`q` with rho_max, rho_partner and the MSB (quality/separability.py); `q` itself when
    it has them."""
    if q.rho_max is not None:
        return q
    rho, partner = w_correlations(model, q.qvv, q.controlled)
    others = int(np.sum(np.isfinite(rho))) - 2  # the tests besides i and its partner
    factor = separable_delta(np.nan_to_num(rho), q.k_w, q.beta0, others) / q.delta0
    return replace(q, rho_max=rho, rho_partner=partner,
                   msb=np.where(q.controlled, q.mdb * factor, np.inf))


def qvv_columns(model: AdjustedModel, rows: np.ndarray) -> np.ndarray:
    """Columns `rows` of Qvv (n, len(rows)) by Gruen's identity-matrix observation.

    With f_i the i-th unit vector as observation vector, x_i = N^-1 A^T P f_i and
    Qvv P f_i = f_i - A x_i (Gruen 1980, eq. 12-17), so column i of Qvv is
    (f_i - A x_i) / p_i: one reduction of the right-hand side and one back substitution per
    column.  Right for a few columns; the diagonal of all of them comes from
    adjusted_cofactor_diag (selected inversion).
    """
    rows = np.atleast_1d(np.asarray(rows))
    h = np.zeros((model.n, len(rows)))
    h[rows, np.arange(len(rows))] = 1.0
    ax = model.solve_columns(h)
    p = 1.0 / model.sigma[rows] ** 2
    return (h - ax) / p[None, :]


def w_correlation(model: AdjustedModel, i: int) -> np.ndarray:
    """Correlation of the w-test of active component i with the w-test of every component.

    rho_ij = q_vv,ij / sqrt(q_vv,ii q_vv,jj), column i of Q_vv from qvv_columns (Foerstner's
    separability: |rho| near 1 means an error in i cannot be told from an error in j).  A
    rejected (inactive) j is uncorrelated with v_i: 0.
    """
    if not model.active[i]:
        raise ValueError("w_correlation: component i must be active")
    col = qvv_columns(model, np.array([i]))[:, 0]
    qvv, _ = cofactors(model)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = col / np.sqrt(qvv * qvv[i])
    return np.where(model.active & (qvv > 0) & (qvv[i] > 0), rho, 0.0)
