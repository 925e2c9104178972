"""Test distributions of Baarda's B-method of testing.

All functions are pure and work on floats (or NumPy arrays where stated). Test statistics are
dimensionless: quadratic forms are assumed to be scaled by the *a priori* variance factor
sigma0^2, i.e. ``omega = v^T P v / sigma0^2`` with ``P`` the weight matrix of the observations.

References
----------
* Baarda, W. (1968). *A testing procedure for use in geodetic networks*. Netherlands Geodetic
  Commission, Publications on Geodesy 2(5).
* Teunissen, P.J.G. (2000). *Testing theory: an introduction*. Delft University Press.
* Pope, A.J. (1976). *The statistics of residuals and the detection of outliers*. NOAA Technical
  Report NOS 65 NGS 1.
* Koch, K.R. (1999). *Parameter estimation and hypothesis testing in linear models*, 2nd ed.,
  Springer (F-test of linear hypotheses, outlier tests).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import special

from baarda.options import DEFAULT_TESTS
from baarda.quality.special_distributions import (
    chi2_cdf,
    chi2_isf,
    chi2_ppf,
    chi2_sf,
    f_isf,
    f_sf,
    ncx2_isf,
    ncx2_sf,
    t_isf,
)

__all__ = [
    "BMethod",
    "GlobalTest",
    "MultidimTest",
    "b_method",
    "global_test",
    "multidim_test",
    "noncentrality",
    "pope_alpha",
    "power",
    "tau_critical",
    "tau_pvalue",
    "w_test_logpvalue",
    "w_test_pvalue",
]

#: Above this number of degrees of freedom :meth:`BMethod.alpha_for` switches from the exact
#: inversion (SciPy's non-central chi-square, which stops converging around 1e11) to the
#: asymptotic normal formula with a calibrated O(1/dof) term (absolute error < 1e-11).
MAX_EXACT_DOF: int = 1_000_000_000


def _check_prob(name: str, p: float) -> float:
    p = float(p)
    if not 0.0 < p < 1.0:
        raise ValueError(f"{name} must lie in the open interval (0, 1), got {p!r}")
    return p


def _check_dof(name: str, dof: int, minimum: int = 1) -> int:
    if isinstance(dof, bool) or int(dof) != dof:
        raise ValueError(f"{name} must be an integer, got {dof!r}")
    dof = int(dof)
    if dof < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {dof}")
    return dof


def _scalar_or_array(x: NDArray[np.float64]) -> float | NDArray[np.float64]:
    return float(x) if x.ndim == 0 else x


# --------------------------------------------------------------------------------------------
# Power and non-centrality
# --------------------------------------------------------------------------------------------


def power(alpha: float, lam: float, dof: int = 1) -> float:
    """Power of a chi-square test: ``gamma = P(chi2'(dof, lam) > chi2_{1-alpha}(dof))``.

    ``chi2'(dof, lam)`` is the non-central chi-square distribution with non-centrality ``lam``
    (Baarda 1968; Teunissen 2000).
    """
    alpha = _check_prob("alpha", alpha)
    dof = _check_dof("dof", dof)
    if lam < 0:
        raise ValueError(f"lam must be non-negative, got {lam!r}")
    crit = chi2_isf(alpha, dof)
    if lam == 0:
        return alpha
    return float(ncx2_sf(crit, dof, lam))


def noncentrality(alpha: float, beta: float, dof: int = 1) -> float:
    """Non-centrality ``lambda = lambda(alpha, beta, dof)`` of Baarda's B-method.

    Solves ``P(chi2'(dof, lambda) > chi2_{1-alpha}(dof)) = beta`` exactly (Brent's method on the
    SciPy non-central chi-square survival function; relative accuracy ~1e-14). Baarda's standard
    ``alpha0 = 0.001, beta0 = 0.80, dof = 1`` gives ``lambda0 = 17.075`` and
    ``delta0 = sqrt(lambda0) = 4.132`` (Baarda 1968).
    """
    alpha = _check_prob("alpha", alpha)
    beta = _check_prob("beta", beta)
    dof = _check_dof("dof", dof)
    if beta < alpha:
        raise ValueError(f"power beta={beta} cannot be below the significance level {alpha}")
    if beta == alpha:
        return 0.0
    crit = chi2_isf(alpha, dof)

    def residual(lam: float) -> float:
        return float(ncx2_sf(crit, dof, lam)) - beta

    # the power grows monotonically with lambda; lambda ~ (z_{1-a} + z_b)^2 * O(sqrt(dof))
    hi = max(1.0, (special.ndtri(1 - alpha) + special.ndtri(beta)) ** 2)
    while residual(hi) < 0:
        hi *= 2.0
    lo = 0.0
    from scipy import optimize  # here: 0.1 s of import that most commands never need

    return float(optimize.brentq(residual, lo, hi, xtol=1e-13, rtol=4 * np.finfo(float).eps))


# --------------------------------------------------------------------------------------------
# The B-method
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BMethod:
    """Baarda's B-method: all tests share the non-centrality ``lambda0`` and power ``beta0``.

    The one-dimensional w-test has level ``alpha0``; a ``b``-dimensional test gets the level
    ``alpha_b`` that makes it equally sensitive (same ``lambda0`` detected with the same
    ``beta0``): ``lambda(alpha_b, beta0, b) = lambda(alpha0, beta0, 1) = lambda0``.
    """

    alpha0: float
    beta0: float
    lambda0: float
    delta0: float
    k_w: float

    def alpha_for(self, dof: int) -> float:
        """Significance level ``alpha_b`` of a ``dof``-dimensional test coupled by the B-method.

        Exact for ``dof <= MAX_EXACT_DOF`` (1e9): the critical value ``c`` is the ``1 - beta0``
        quantile of ``chi2'(dof, lambda0)`` and ``alpha_b = P(chi2(dof) > c)``; the round trip
        ``power(alpha_b, lambda0, dof) == beta0`` holds to ~1e-12 (checked up to 1e9). Beyond
        that (where SciPy's non-central chi-square no longer converges, ~1e11) the normal limit
        ``alpha_b = Phi(z_{beta0} - lambda0 / sqrt(2 dof)) + C / dof`` is used, the O(1/dof)
        coefficient ``C`` being calibrated on the exact value at ``MAX_EXACT_DOF``, which keeps
        ``alpha_b`` continuous and monotonic; absolute error < 1e-11 (checked against the exact
        route up to 1e10, where it still converges). ``alpha_b`` increases monotonically with
        ``dof`` towards ``beta0``; ``alpha_for(1) == alpha0``.
        """
        dof = _check_dof("dof", dof)
        if dof > MAX_EXACT_DOF:
            c1 = _asymptotic_coefficient(self.beta0, self.lambda0)
            return _alpha_for_normal(self.beta0, self.lambda0, dof) + c1 / dof
        return _alpha_for_exact(self.beta0, self.lambda0, dof)

    def critical_chi2(self, dof: int) -> float:
        """Critical value ``chi2_{1-alpha_b}(dof)`` of the B-method test of dimension ``dof``."""
        dof = _check_dof("dof", dof)
        return float(chi2_isf(self.alpha_for(dof), dof))

    def critical_F(self, dof: int, dof2: float = math.inf) -> float:  # noqa: N802
        """Critical value ``F_{1-alpha_b}(dof, dof2)``; ``dof2 = inf`` gives ``chi2/dof``.

        ``alpha_b`` is always the B-method level of the ``dof``-dimensional test with known
        variance factor; for finite ``dof2`` it is simply used as level of the F-test.
        """
        dof = _check_dof("dof", dof)
        alpha = self.alpha_for(dof)
        if math.isinf(dof2):
            return float(chi2_isf(alpha, dof)) / dof
        if dof2 <= 0:
            raise ValueError(f"dof2 must be positive, got {dof2!r}")
        return float(f_isf(alpha, dof, dof2))


def _alpha_for_exact(beta0: float, lambda0: float, dof: int) -> float:
    """``P(chi2(dof) > c)`` with ``c`` the ``1 - beta0`` quantile of ``chi2'(dof, lambda0)``."""
    crit = ncx2_isf(beta0, dof, lambda0)
    return float(chi2_sf(crit, dof))


def _alpha_for_normal(beta0: float, lambda0: float, dof: int) -> float:
    """Large-``dof`` limit of the B-method level: ``Phi(z_{beta0} - lambda0 / sqrt(2 dof))``.

    From the normal limits ``chi2(q) ~ N(q, 2q)`` and ``chi2'(q, l) ~ N(q + l, 2(q + 2l))``;
    the absolute error is O(1/dof) (about 1.34/dof for alpha0 = 0.001, beta0 = 0.80).
    """
    return float(special.ndtr(special.ndtri(beta0) - lambda0 / math.sqrt(2.0 * dof)))


@functools.lru_cache(maxsize=64)
def _asymptotic_coefficient(beta0: float, lambda0: float) -> float:
    """Coefficient ``C`` of the O(1/dof) term, matched to the exact value at MAX_EXACT_DOF."""
    q = MAX_EXACT_DOF
    return q * (_alpha_for_exact(beta0, lambda0, q) - _alpha_for_normal(beta0, lambda0, q))


@functools.lru_cache(maxsize=64)  # a pure function of two numbers (2,000 calls at BAL scale)
def b_method(alpha0: float = DEFAULT_TESTS.alpha0,
             beta0: float = DEFAULT_TESTS.beta0) -> BMethod:
    """Set up Baarda's B-method for w-test level ``alpha0`` and power ``beta0``.

    ``lambda0 = noncentrality(alpha0, beta0, 1)``, ``delta0 = sqrt(lambda0)`` and the critical
    value of ``|w|`` is ``k_w = Phi^{-1}(1 - alpha0/2)`` (3.29 for alpha0 = 0.001).
    """
    alpha0 = _check_prob("alpha0", alpha0)
    beta0 = _check_prob("beta0", beta0)
    lam0 = noncentrality(alpha0, beta0, 1)
    return BMethod(
        alpha0=alpha0,
        beta0=beta0,
        lambda0=lam0,
        delta0=math.sqrt(lam0),
        k_w=float(-special.ndtri(alpha0 / 2.0)),
    )


# --------------------------------------------------------------------------------------------
# w-test and Pope's tau-test
# --------------------------------------------------------------------------------------------


def w_test_pvalue(w: ArrayLike) -> float | NDArray[np.float64]:
    """Two-sided p-value of Baarda's w-test statistic, ``p = 2 Phi(-|w|)``.

    Computed with ``scipy.special.ndtr`` of the negative tail (no ``1 - cdf`` cancellation), so
    the relative accuracy is ~1e-15 while ``p`` is representable (``|w| <~ 37.5``); for larger
    ``|w|`` the p-value underflows to 0: use :func:`w_test_logpvalue` there.
    """
    w = np.asarray(w, dtype=float)
    return _scalar_or_array(2.0 * special.ndtr(-np.abs(w)))


def w_test_logpvalue(w: ArrayLike) -> float | NDArray[np.float64]:
    """Natural log of the two-sided w-test p-value, ``log 2 + log Phi(-|w|)``, for any ``|w|``."""
    w = np.asarray(w, dtype=float)
    return _scalar_or_array(math.log(2.0) + special.log_ndtr(-np.abs(w)))


def tau_critical(alpha: float, redundancy: int) -> float:
    """Two-sided critical value of Pope's tau distribution with redundancy ``r >= 2``.

    ``tau = sqrt(r) t / sqrt(r - 1 + t^2)`` with ``t ~ t(r - 1)`` (Pope 1976), hence
    ``tau_c = sqrt(r) t_c / sqrt(r - 1 + t_c^2)`` with ``t_c = t_{1-alpha/2}(r - 1)``.
    """
    alpha = _check_prob("alpha", alpha)
    r = _check_dof("redundancy", redundancy, minimum=2)
    t_c = float(t_isf(alpha / 2.0, r - 1))
    # sqrt(r) / sqrt((r - 1)/t^2 + 1) avoids overflow of t^2 for tiny alpha
    return math.sqrt(r) / math.sqrt((r - 1) / t_c**2 + 1.0)


def tau_pvalue(tau: ArrayLike, redundancy: int) -> float | NDArray[np.float64]:
    """Two-sided p-value of Pope's tau statistic (vectorised in ``tau``).

    ``t = |tau| sqrt(r - 1) / sqrt(r - tau^2)`` and ``p = 2 P(t(r - 1) > t)`` (Pope 1976);
    ``|tau| >= sqrt(r)`` is impossible under the model and gets ``p = 0``. Equivalently
    ``tau^2 / r ~ Beta(1/2, (r - 1)/2)``.
    """
    r = _check_dof("redundancy", redundancy, minimum=2)
    a = np.abs(np.asarray(tau, dtype=float))
    sr = math.sqrt(r)
    inside = a < sr
    # (sqrt(r) - a)(sqrt(r) + a) = r - tau^2 without cancellation near the bound
    gap = np.where(inside, (sr - a) * (sr + a), 1.0)
    t = a * math.sqrt(r - 1) / np.sqrt(gap)
    p = np.where(inside, 2.0 * special.stdtr(r - 1, -t), 0.0)
    p = np.where(np.isnan(a), np.nan, p)
    return _scalar_or_array(np.asarray(p, dtype=float))


def pope_alpha(alpha_total: float, n: int) -> float:
    """Per-observation level for a family-wise level over ``n`` tests (Sidak correction).

    ``alpha = 1 - (1 - alpha_total)^(1/n)``, evaluated as ``-expm1(log1p(-alpha_total)/n)``.
    """
    alpha_total = _check_prob("alpha_total", alpha_total)
    n = _check_dof("n", n)
    return -math.expm1(math.log1p(-alpha_total) / n)


# --------------------------------------------------------------------------------------------
# Global (overall model) test and Baarda's generalized (multidimensional) test
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class GlobalTest:
    """Result of the global test ``omega / r ~ chi2(r) / r`` (= ``sigma0_hat^2 / sigma0^2``).

    ``passed`` is the usual one-sided test ``statistic <= critical`` (level ``alpha``);
    ``passed_two_sided`` uses the interval ``[lower, upper]`` with ``alpha/2`` in each tail.
    """

    omega: float
    redundancy: int
    alpha: float
    statistic: float
    critical: float
    lower: float
    upper: float
    p_value: float
    p_value_two_sided: float
    passed: bool
    passed_two_sided: bool

    @property
    def sigma0_hat(self) -> float:
        """A posteriori sigma0 in units of the a priori sigma0: ``sqrt(omega / r)``."""
        return math.sqrt(self.statistic)


def global_test(omega: float, redundancy: int, alpha: float) -> GlobalTest:
    """Global test of the adjustment (Baarda 1968; Teunissen 2000).

    ``omega = v^T P v / sigma0^2 ~ chi2(r)`` under H0; statistic ``omega / r``, critical value
    ``chi2_{1-alpha}(r) / r``, two-sided bounds ``chi2_{alpha/2}(r)/r`` and
    ``chi2_{1-alpha/2}(r)/r``, upper-tail p-value ``P(chi2(r) > omega)``. All values come from
    the regularized incomplete gamma function (no cancellation), fine for ``r`` up to 1e7+.
    """
    r = _check_dof("redundancy", redundancy)
    alpha = _check_prob("alpha", alpha)
    omega = float(omega)
    if not omega >= 0.0:
        raise ValueError(f"omega must be non-negative, got {omega!r}")
    statistic = omega / r
    critical = float(chi2_isf(alpha, r)) / r
    lower = float(chi2_ppf(alpha / 2.0, r)) / r
    upper = float(chi2_isf(alpha / 2.0, r)) / r
    sf = float(chi2_sf(omega, r))
    cdf = float(chi2_cdf(omega, r))
    return GlobalTest(
        omega=omega,
        redundancy=r,
        alpha=alpha,
        statistic=statistic,
        critical=critical,
        lower=lower,
        upper=upper,
        p_value=sf,
        p_value_two_sided=min(1.0, 2.0 * min(sf, cdf)),
        passed=statistic <= critical,
        passed_two_sided=lower <= statistic <= upper,
    )


@dataclass(frozen=True)
class MultidimTest:
    """Result of Baarda's generalized test of a ``q``-dimensional alternative hypothesis."""

    T: float
    q: int
    alpha: float
    dof2: float  # math.inf for a priori variance, r - q otherwise
    statistic: float
    critical: float
    p_value: float
    rejected: bool


def multidim_test(
    T: float,  # noqa: N803
    q: int,
    alpha: float,
    redundancy: int | None = None,
    sigma0_hat2: float | None = None,
) -> MultidimTest:
    """Baarda's generalized test ``T_q`` of a ``q``-dimensional model error ``C nabla``.

    ``T = nabla_hat^T Q_nabla_hat^{-1} nabla_hat / sigma0^2`` (the decrease of ``omega`` when
    the model is extended by ``C``), ``0 <= T <= omega``.

    * A priori variance (``redundancy`` None): ``T / q ~ F(q, inf) = chi2(q) / q``
      (Baarda 1968; Teunissen 2000).
    * A posteriori variance (``redundancy = r`` and ``sigma0_hat2 = omega / r`` given):
      ``F = (T / q) / ((omega - T) / (r - q)) ~ F(q, r - q)``. The estimate of the variance
      factor is taken from the *extended* model (T excluded): ``omega - T`` and ``T`` are
      independent chi-squares with ``r - q`` and ``q`` degrees of freedom, so the ratio is an
      exact (non-central under Ha) F-distribution, and an error in ``C`` cannot inflate the
      denominator and mask itself (Koch 1999). Using ``omega / r`` instead would give
      a beta-type statistic (Pope's tau for q = 1), not an F-statistic. For ``q = 1`` this is
      the externally studentized residual, ``F = t^2`` with ``t ~ t(r - 1)``.

    Returns statistic, critical value ``F_{1-alpha}``, upper-tail p-value and ``rejected``.
    """
    q = _check_dof("q", q)
    alpha = _check_prob("alpha", alpha)
    T = float(T)  # noqa: N806
    if not T >= 0.0:
        raise ValueError(f"T must be non-negative, got {T!r}")
    if redundancy is None:
        if sigma0_hat2 is not None:
            raise ValueError("sigma0_hat2 needs the redundancy it was estimated with")
        statistic = T / q
        critical = float(chi2_isf(alpha, q)) / q
        p_value = float(chi2_sf(T, q))
        dof2 = math.inf
    else:
        if sigma0_hat2 is None:
            raise ValueError("the a posteriori test needs sigma0_hat2 = omega / redundancy")
        r = _check_dof("redundancy", redundancy)
        if r <= q:
            raise ValueError(f"need redundancy > q for the F(q, r - q) test, got r={r}, q={q}")
        omega = r * float(sigma0_hat2)
        rest = omega - T
        if rest < -1e-12 * max(omega, 1.0):
            raise ValueError(f"T={T} exceeds omega = r * sigma0_hat2 = {omega}")
        dof2 = float(r - q)
        statistic = (T / q) / (rest / dof2) if rest > 0 else math.inf
        critical = float(f_isf(alpha, q, dof2))
        p_value = float(f_sf(statistic, q, dof2)) if rest > 0 else 0.0
    return MultidimTest(
        T=T,
        q=q,
        alpha=alpha,
        dof2=dof2,
        statistic=statistic,
        critical=critical,
        p_value=p_value,
        rejected=statistic > critical,
    )
