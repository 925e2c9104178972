"""quality/special_distributions.py takes the test distributions from scipy.special directly
(scipy.stats costs 0.4 s to import): they must give scipy.stats' numbers to the last bit."""

import subprocess
import sys

import pytest
from scipy import stats

from baarda.quality import distributions
from baarda.quality import special_distributions as d

PROBS = [1e-12, 1e-6, 0.001, 0.01, 0.025, 0.05, 0.2, 0.5, 0.8, 0.95, 0.999]
DOFS = [1, 2, 3, 5, 17, 100, 3141, 2_946_873]
XS = [0.0, 1e-8, 0.3, 1.0, 3.84, 10.83, 50.0, 1234.5, 3.0e6]


@pytest.mark.parametrize("dof", DOFS)
def test_chi2_equals_scipy_stats(dof):
    for p in PROBS:
        assert d.chi2_isf(p, dof) == float(stats.chi2.isf(p, dof))
        assert d.chi2_ppf(p, dof) == float(stats.chi2.ppf(p, dof))
    for x in XS:
        assert d.chi2_sf(x, dof) == float(stats.chi2.sf(x, dof))
        assert d.chi2_cdf(x, dof) == float(stats.chi2.cdf(x, dof))
    assert d.chi2_cdf(31334.25, 31460.0) == float(stats.chi2.cdf(31334.25, 31460.0))


@pytest.mark.parametrize("dof", [1, 2, 3, 6, 20])
def test_noncentral_chi2_equals_scipy_stats(dof):
    for lam in [0.0, 0.5, 4.13, 17.075, 40.0]:
        for x in [0.5, 3.84, 10.83, 30.0]:
            assert d.ncx2_sf(x, dof, lam) == float(stats.ncx2.sf(x, dof, lam))
        for p in [0.2, 0.5, 0.8, 0.99]:
            assert d.ncx2_isf(p, dof, lam) == float(stats.ncx2.isf(p, dof, lam))


def test_f_and_t_equal_scipy_stats():
    for q in [1, 2, 3, 7]:
        for dof2 in [1.0, 4.0, 30.0, 1e4]:
            for p in PROBS:
                assert d.f_isf(p, q, dof2) == float(stats.f.isf(p, q, dof2))
            for x in [0.0, 0.1, 1.0, 3.5, 100.0]:
                assert d.f_sf(x, q, dof2) == float(stats.f.sf(x, q, dof2))
    for dof in [1, 2, 9, 1000]:
        for p in PROBS:
            assert d.t_isf(p, dof) == float(stats.t.isf(p, dof))
    for p in PROBS + [0.975, 0.5, 0.995]:
        assert d.norm_ppf(p) == float(stats.norm.ppf(p))


def test_lambda0_unchanged():
    # Baarda's standard: alpha0 = 0.001, beta0 = 0.80 -> lambda0 = 17.075 (delta0 = 4.132)
    lam = distributions.noncentrality(0.001, 0.80, 1)
    assert lam == pytest.approx(17.0746, abs=5e-5)
    crit = float(stats.chi2.isf(0.001, 1))
    assert float(stats.ncx2.sf(crit, 1, lam)) == pytest.approx(0.80, abs=1e-13)


def test_statistics_do_not_import_scipy_stats():
    code = ("import sys, baarda.quality.distributions, baarda.quality.variance_components, "
            "baarda.quality.assessment; print('scipy.stats' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "False"
