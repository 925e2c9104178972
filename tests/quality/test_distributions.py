"""Tests of baarda.quality.distributions against independent computations.

Every number is checked by a route that does not go through the function under test: closed
forms (normal for dof 1), the Poisson mixture of the non-central chi-square, direct numerical
integration (dof 2), Monte-Carlo simulation, or asymptotic expansions.
"""

import math

import numpy as np
import pytest
from scipy import integrate, special, stats

from baarda.quality.distributions import (
    MAX_EXACT_DOF,
    b_method,
    global_test,
    multidim_test,
    noncentrality,
    pope_alpha,
    power,
    tau_critical,
    tau_pvalue,
    w_test_logpvalue,
    w_test_pvalue,
)


def ncx2_sf_poisson(x: float, dof: int, lam: float) -> float:
    """P(chi2'(dof, lam) > x) as Poisson(lam/2) mixture of central chi-squares."""
    j = np.arange(0, int(lam / 2 + 40 * math.sqrt(lam / 2 + 1) + 40))
    return float(np.sum(stats.poisson.pmf(j, lam / 2) * stats.chi2.sf(x, dof + 2 * j)))


def power_dof1_closed(alpha: float, lam: float) -> float:
    """P(|Z + delta| > k) with k = z_{1-alpha/2}."""
    k = -special.ndtri(alpha / 2)
    d = math.sqrt(lam)
    return float(special.ndtr(d - k) + special.ndtr(-k - d))


# --------------------------------------------------------------------------------------------
# noncentrality and the B-method
# --------------------------------------------------------------------------------------------


def test_lambda0_delta0_standard():
    lam0 = noncentrality(0.001, 0.80, 1)
    assert round(lam0, 2) == 17.07
    assert round(math.sqrt(lam0), 2) == 4.13
    # exact closed form for dof 1
    assert power_dof1_closed(0.001, lam0) == pytest.approx(0.80, abs=1e-13)
    bm = b_method()
    assert bm.lambda0 == pytest.approx(lam0, rel=1e-14)
    assert round(bm.delta0, 2) == 4.13
    assert round(bm.k_w, 2) == 3.29
    assert 2 * special.ndtr(-bm.k_w) == pytest.approx(0.001, rel=1e-12)


def test_delta0_005_080():
    bm = b_method(0.05, 0.80)
    assert round(bm.delta0, 2) == 2.80
    assert round(bm.k_w, 2) == 1.96
    assert power_dof1_closed(0.05, bm.lambda0) == pytest.approx(0.80, abs=1e-13)


@pytest.mark.parametrize("dof", [1, 2, 3, 10, 100, 10_000, 1_000_000])
def test_noncentrality_poisson_mixture(dof):
    lam = noncentrality(0.001, 0.80, dof)
    crit = stats.chi2.isf(0.001, dof)
    assert ncx2_sf_poisson(crit, dof, lam) == pytest.approx(0.80, abs=1e-10)
    assert power(0.001, lam, dof) == pytest.approx(0.80, abs=1e-12)


def test_noncentrality_edge_cases():
    assert noncentrality(0.05, 0.05) == 0.0
    with pytest.raises(ValueError):
        noncentrality(0.05, 0.01)
    with pytest.raises(ValueError):
        noncentrality(0.0, 0.8)
    with pytest.raises(ValueError):
        noncentrality(0.001, 0.8, 0)


def test_alpha_for_one_is_alpha0():
    for a0, b0 in [(0.001, 0.80), (0.05, 0.80), (0.01, 0.90), (1e-6, 0.99)]:
        assert b_method(a0, b0).alpha_for(1) == pytest.approx(a0, abs=1e-10, rel=1e-10)


@pytest.mark.parametrize("dof", [1, 2, 3, 10, 100, 1000, 10_000, 1_000_000, 100_000_000])
def test_alpha_for_roundtrip(dof):
    """power(alpha_b) == beta0, checked by scipy's ncx2 and by the Poisson mixture."""
    bm = b_method()
    alpha = bm.alpha_for(dof)
    crit = stats.chi2.isf(alpha, dof)
    assert crit == pytest.approx(bm.critical_chi2(dof), rel=1e-14)
    assert stats.ncx2.sf(crit, dof, bm.lambda0) == pytest.approx(0.80, abs=1e-10)
    assert ncx2_sf_poisson(crit, dof, bm.lambda0) == pytest.approx(0.80, abs=1e-10)
    # the B-method couples the tests: the same lambda0 for dimension dof
    if dof <= 10_000:
        assert noncentrality(alpha, 0.80, dof) == pytest.approx(bm.lambda0, rel=1e-9)


def test_alpha_for_2_numerical_integration():
    """dof 2: power = 1 - int_0^sqrt(c) rho exp(-(rho^2 + lam)/2) I0(rho sqrt(lam)) drho."""
    bm = b_method()
    alpha2 = bm.alpha_for(2)
    c = bm.critical_chi2(2)
    assert math.exp(-c / 2) == pytest.approx(alpha2, rel=1e-12)  # chi2(2) is exponential
    d = bm.delta0

    def dens(rho):
        return rho * math.exp(-((rho - d) ** 2) / 2) * special.i0e(rho * d)

    inside, _ = integrate.quad(dens, 0.0, math.sqrt(c), epsabs=1e-14, epsrel=1e-13)
    assert 1 - inside == pytest.approx(0.80, abs=1e-10)
    assert round(alpha2, 4) == 0.0028
    assert round(bm.alpha_for(3), 4) == 0.0055


def test_alpha_for_monte_carlo():
    """Simulated q-dim normal vectors with |mu|^2 = lambda0: power 0.80, size alpha_b."""
    bm = b_method()
    rng = np.random.default_rng(20240601)
    n = 400_000
    for q in (2, 3):
        crit = bm.critical_chi2(q)
        alpha = bm.alpha_for(q)
        z = rng.standard_normal((n, q))
        t0 = np.sum(z**2, axis=1)
        z[:, 0] += bm.delta0
        t1 = np.sum(z**2, axis=1)
        size, pw = np.mean(t0 > crit), np.mean(t1 > crit)
        assert abs(size - alpha) < 3 * math.sqrt(alpha * (1 - alpha) / n)
        assert abs(pw - 0.80) < 3 * math.sqrt(0.16 / n)


def test_alpha_for_monotonic_and_limit():
    bm = b_method()
    dofs = [1, 2, 3, 5, 10, 30, 100, 1000, 10**4, 10**5, 10**6, 10**7, 10**8]
    dofs += [MAX_EXACT_DOF, MAX_EXACT_DOF + 1, 10**10, 10**12]
    alphas = [bm.alpha_for(q) for q in dofs]
    assert all(a < b for a, b in zip(alphas, alphas[1:], strict=False))
    assert alphas[-1] < bm.beta0
    assert alphas[-1] == pytest.approx(bm.beta0, abs=1e-5)


def test_alpha_for_asymptotic_accuracy():
    """Documented: plain normal limit has error < 2/q; calibrated form < 1e-11 beyond 1e9."""
    from baarda.quality.distributions import _alpha_for_exact, _alpha_for_normal

    bm = b_method()
    for q in (10**6, 10**8, MAX_EXACT_DOF):
        err = abs(bm.alpha_for(q) - _alpha_for_normal(bm.beta0, bm.lambda0, q))
        assert err < 2.0 / q
    # beyond the switch, against the exact route where SciPy still converges
    for q in (2 * MAX_EXACT_DOF, 10 * MAX_EXACT_DOF):
        exact = _alpha_for_exact(bm.beta0, bm.lambda0, q)
        assert bm.alpha_for(q) == pytest.approx(exact, abs=1e-11)
    # continuity across the switch
    step = bm.alpha_for(MAX_EXACT_DOF + 1) - bm.alpha_for(MAX_EXACT_DOF)
    assert 0 < step < 1e-12


def test_critical_F():
    bm = b_method()
    assert bm.critical_F(3) == pytest.approx(bm.critical_chi2(3) / 3, rel=1e-14)
    assert bm.critical_F(1) == pytest.approx(bm.k_w**2, rel=1e-10)
    f = bm.critical_F(2, 50)
    assert stats.f.sf(f, 2, 50) == pytest.approx(bm.alpha_for(2), rel=1e-9)
    assert bm.critical_F(2, 1e9) == pytest.approx(bm.critical_F(2), rel=1e-6)


# --------------------------------------------------------------------------------------------
# w-test
# --------------------------------------------------------------------------------------------


def _mills_log_sf(x: float) -> float:
    """log of the upper normal tail by the asymptotic Mills-ratio series (for x >= 10)."""
    s, term = 1.0, 1.0
    for k in range(1, 12):
        term *= -(2 * k - 1) / x**2
        s += term
    return -x * x / 2 - math.log(x * math.sqrt(2 * math.pi)) + math.log(s)


def test_w_test_pvalue():
    p = w_test_pvalue(10.0)
    assert p > 0
    assert p == pytest.approx(2 * stats.norm.sf(10), rel=1e-12)
    assert isinstance(p, float)
    for w in (10.0, 20.0, 30.0, 37.0):
        assert w_test_pvalue(-w) == pytest.approx(2 * math.exp(_mills_log_sf(w)), rel=1e-12)
    # log form for |w| up to 40 and beyond, where p itself underflows
    assert w_test_pvalue(40.0) == 0.0
    for w in (10.0, 20.0, 38.5, 40.0, 100.0):
        assert w_test_logpvalue(w) == pytest.approx(math.log(2) + _mills_log_sf(w), rel=1e-14)
    arr = w_test_pvalue(np.array([0.0, 1.959963984540054, -3.2905267314919255]))
    np.testing.assert_allclose(arr, [1.0, 0.05, 0.001], rtol=1e-12)


# --------------------------------------------------------------------------------------------
# Pope's tau
# --------------------------------------------------------------------------------------------


def test_tau_critical_and_pvalue_consistent():
    for r in (2, 3, 5, 20, 1000, 10**7):
        # for r = 2 and tiny alpha, tau_c = sqrt(2)(1 - O(alpha^2)) rounds to sqrt(2)
        for alpha in (0.05, 0.001, 1e-9) if r > 2 else (0.05, 0.001):
            c = tau_critical(alpha, r)
            assert c < math.sqrt(r)
            assert tau_pvalue(c, r) == pytest.approx(alpha, rel=1e-9)
            # independent: tau^2/r ~ Beta(1/2, (r-1)/2)
            assert special.betaincc(0.5, (r - 1) / 2, c * c / r) == pytest.approx(alpha, rel=1e-8)
    # large r: tau -> standard normal
    assert tau_critical(0.05, 10**7) == pytest.approx(1.959963984540054, rel=1e-6)


def test_tau_pvalue_edges():
    r = 6
    p = tau_pvalue(np.array([0.0, math.sqrt(r), -3.0, np.nan, 1.0]), r)
    assert p[0] == 1.0 and p[1] == 0.0 and p[2] == 0.0 and np.isnan(p[3])
    assert p[4] == pytest.approx(special.betaincc(0.5, (r - 1) / 2, 1.0 / r), rel=1e-12)
    with pytest.raises(ValueError):
        tau_pvalue(1.0, 1)


def test_pope_alpha():
    assert pope_alpha(0.05, 1) == pytest.approx(0.05, rel=1e-15)
    a = pope_alpha(0.05, 1000)
    assert 1 - (1 - a) ** 1000 == pytest.approx(0.05, rel=1e-10)
    assert pope_alpha(1e-12, 10**6) == pytest.approx(1e-18, rel=1e-6)


def _simulate_tau(n_rep: int, seed: int):
    """tau_i = v_i / (sigma0_hat sqrt(qvv_i)) of a random small weighted linear model."""
    rng = np.random.default_rng(seed)
    n, u = 11, 4
    a = rng.standard_normal((n, u))
    p = rng.uniform(0.5, 4.0, n)  # diagonal weights, sigma0 = 1
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    qvv = np.diag(1 / p) - a @ qxx @ a.T
    red = np.eye(n) - a @ qxx @ a.T @ np.diag(p)  # v = -R e
    e = rng.standard_normal((n_rep, n)) / np.sqrt(p)
    v = e @ red.T
    r = n - u
    s2 = np.sum(p * v**2, axis=1) / r
    tau = v / np.sqrt(s2[:, None] * np.diag(qvv)[None, :])
    return tau, r


def test_tau_monte_carlo_rejection_rate_and_uniformity():
    tau, r = _simulate_tau(40_000, seed=7)
    alpha = 0.05
    crit = tau_critical(alpha, r)
    rejected = np.abs(tau) > crit
    # pooled over observations; SE from the replication means (observations correlate)
    k = rejected.mean(axis=1)
    se = k.std(ddof=1) / math.sqrt(k.size)
    assert abs(k.mean() - alpha) < 3 * se
    # every single observation (independent replications, binomial SE)
    se1 = math.sqrt(alpha * (1 - alpha) / tau.shape[0])
    assert np.all(np.abs(rejected.mean(axis=0) - alpha) < 3.5 * se1)
    # p-values uniform for one observation, and consistent with the critical value
    pv = tau_pvalue(tau, r)
    assert np.array_equal(pv < alpha, rejected)
    ks = stats.kstest(pv[:, 0], "uniform")
    assert ks.pvalue > 1e-3
    hist = np.histogram(pv, bins=10, range=(0, 1))[0] / pv.size
    np.testing.assert_allclose(hist, 0.1, atol=0.01)


# --------------------------------------------------------------------------------------------
# global test and multidimensional test
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("r", [1, 2, 5, 30])
def test_global_test_small_r(r):
    omega = 1.7 * r
    g = global_test(omega, r, 0.05)
    assert g.statistic == pytest.approx(1.7)
    assert g.p_value == pytest.approx(stats.chi2.sf(omega, r), rel=1e-13)
    # independent: regularized upper incomplete gamma
    assert g.p_value == pytest.approx(special.gammaincc(r / 2, omega / 2), rel=1e-12)
    assert g.critical == pytest.approx(stats.chi2.ppf(0.95, r) / r, rel=1e-12)
    assert g.passed == (g.p_value >= 0.05)
    assert g.lower < 1 < g.upper and g.critical < g.upper
    assert g.sigma0_hat == pytest.approx(math.sqrt(1.7))
    assert 0 < g.p_value_two_sided <= 1


def test_global_test_large_r():
    r = 10**7
    z = special.ndtri(0.95)
    g = global_test(1.0003 * r, r, 0.05)
    # Wilson-Hilferty: chi2_p(r)/r = (1 - 2/(9r) + z sqrt(2/(9r)))^3, error O(1/r)
    wh = (1 - 2 / (9 * r) + z * math.sqrt(2 / (9 * r))) ** 3
    assert g.critical == pytest.approx(wh, abs=1e-9)
    assert g.critical == pytest.approx(1 + z * math.sqrt(2 / r), abs=1e-6)
    zl, zu = special.ndtri(0.025), special.ndtri(0.975)
    assert g.lower == pytest.approx((1 - 2 / (9 * r) + zl * math.sqrt(2 / (9 * r))) ** 3, abs=1e-9)
    assert g.upper == pytest.approx((1 - 2 / (9 * r) + zu * math.sqrt(2 / (9 * r))) ** 3, abs=1e-9)
    x = ((1.0003) ** (1 / 3) - (1 - 2 / (9 * r))) / math.sqrt(2 / (9 * r))
    assert g.p_value == pytest.approx(special.ndtr(-x), abs=1e-7)
    assert g.passed and g.passed_two_sided
    # clear failure far out in the tail: tiny but positive p-value
    g2 = global_test(1.01 * r, r, 0.05)
    assert not g2.passed and 0 < g2.p_value < 1e-100
    assert math.isfinite(g2.sigma0_hat)


def test_multidim_apriori():
    t = multidim_test(9.0, 1, 0.001)
    assert t.p_value == pytest.approx(w_test_pvalue(3.0), rel=1e-12)
    assert not t.rejected
    bm = b_method()
    t3 = multidim_test(25.0, 3, bm.alpha_for(3))
    assert t3.critical == pytest.approx(bm.critical_F(3), rel=1e-12)
    assert t3.statistic == pytest.approx(25 / 3)
    assert t3.rejected == (t3.p_value < t3.alpha)
    assert math.isinf(t3.dof2)


def test_multidim_aposteriori_q1_matches_tau():
    """q = 1: F = t^2 (external studentization) and tau^2 = r w^2/omega: equal p-values."""
    r, omega, w = 12, 15.0, 3.1
    t = multidim_test(w * w, 1, 0.05, redundancy=r, sigma0_hat2=omega / r)
    tau = math.sqrt(r) * w / math.sqrt(omega)
    assert t.p_value == pytest.approx(tau_pvalue(tau, r), rel=1e-12)
    assert t.dof2 == r - 1
    assert t.rejected == (abs(tau) > tau_critical(0.05, r))


def test_multidim_aposteriori_monte_carlo():
    """T and omega - T from a simulated model: F(q, r-q) size at alpha = 0.05."""
    rng = np.random.default_rng(3)
    n, u, q, n_rep = 15, 3, 2, 40_000
    a = rng.standard_normal((n, u))
    c = rng.standard_normal((n, q))

    def omega_of(design, e):
        qmat, _ = np.linalg.qr(design)
        res = e - (e @ qmat) @ qmat.T
        return np.sum(res**2, axis=1)

    e = rng.standard_normal((n_rep, n))
    om = omega_of(a, e)
    om_ext = omega_of(np.hstack([a, c]), e)
    r = n - u
    t_q = om - om_ext
    f_stat = (t_q / q) / (om_ext / (r - q))
    crit = multidim_test(1.0, q, 0.05, redundancy=r, sigma0_hat2=2.0).critical
    rate = np.mean(f_stat > crit)
    for i in range(20):  # the function agrees with the vectorised statistic
        res = multidim_test(t_q[i], q, 0.05, redundancy=r, sigma0_hat2=om[i] / r)
        assert res.statistic == pytest.approx(f_stat[i], rel=1e-10)
        assert res.rejected == (f_stat[i] > crit)
    assert abs(rate - 0.05) < 3 * math.sqrt(0.05 * 0.95 / n_rep)


def test_multidim_errors():
    with pytest.raises(ValueError):
        multidim_test(1.0, 2, 0.05, sigma0_hat2=1.0)
    with pytest.raises(ValueError):
        multidim_test(1.0, 2, 0.05, redundancy=10)
    with pytest.raises(ValueError):
        multidim_test(1.0, 3, 0.05, redundancy=3, sigma0_hat2=1.0)
    with pytest.raises(ValueError):
        multidim_test(20.0, 1, 0.05, redundancy=5, sigma0_hat2=1.0)
