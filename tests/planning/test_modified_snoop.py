"""Gruen's modified data snooping against the rigorous w-test (and Pope's tau)."""

import numpy as np
import pytest

from baarda.pipeline import adjust, assess
from baarda.planning.modified_snoop import modified_snoop
from baarda.planning.reliability_tables import baarda_table, gruen_table
from baarda.quality.dense_model import DenseModel
from baarda.quality.modified import exact_redundancy_numbers, modified_snooping
from baarda.quality.statistics import analyse
from baarda.simulate.aerial import FlightPlan, simulate_block


def _dense(seed=0, n=40, u=6, blunders=3):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, u))
    sigma = rng.uniform(0.5, 2.0, n)
    x = rng.normal(size=u)
    y = a @ x + rng.normal(size=n) * sigma
    y[rng.choice(n, blunders, replace=False)] += rng.choice([-1, 1], blunders) * 8 * sigma[0]
    p = 1 / sigma**2
    xh = np.linalg.solve(a.T @ (p[:, None] * a), a.T @ (p * y))
    return DenseModel(a, sigma, a @ xh - y)


def test_exact_redundancy_numbers_equal_brute_force():
    m = _dense()
    qvv_p = np.eye(m.n) - m.a @ np.linalg.solve(m.nmat, m.a.T * m.p[None, :])
    rows = np.array([0, 3, 17, 39])
    assert np.allclose(exact_redundancy_numbers(m, rows, batch=3), np.diag(qvv_p)[rows],
                       atol=1e-12)


@pytest.mark.parametrize("statistic", ["w", "tau"])
def test_exact_approximations_give_rigorous_decisions(statistic):
    m = _dense(1)
    q = analyse(m)
    ref = q.flagged if statistic == "w" else q.active & (np.abs(q.tau) > q.k_tau)
    res = modified_snooping(m, np.sqrt(q.redundancy_number), statistic=statistic)
    assert (res.rejected == ref).all()
    # only observations near the critical value needed the exact computation
    c, v, s = res.critical, np.abs(m.residuals), res.sigma0 * m.sigma * res.approx
    band = (v >= 0.75 * c * s) & (v <= 1.25 * c * s)
    assert (res.exact == band).all() and res.n_exact == int(band.sum())


def test_no_band_needs_all_values_and_wrong_input():
    m = _dense(2)
    res = modified_snooping(m, np.full(m.n, np.nan))
    assert res.n_exact == m.n
    assert (res.rejected == analyse(m).flagged).all()
    with pytest.raises(ValueError):
        modified_snooping(m, np.ones(3))
    with pytest.raises(ValueError):
        modified_snooping(m, np.ones(m.n), k_q=1.5)


@pytest.fixture(scope="module")
def blundered():
    plan = FlightPlan(strips=5, photos_per_strip=6, side_overlap=0.6, stereo=True, pattern=3,
                      blunders=10, blunder_sigma=(3.0, 12.0), seed=3)
    block, truth = simulate_block(plan)
    res = adjust(block)
    return res, assess(res).quality, truth


@pytest.mark.parametrize("table", ["gruen", "baarda"])
@pytest.mark.parametrize("k_q", [0.25, 0.05])
def test_block_decisions_equal_rigorous_except_outside_band(blundered, table, k_q):
    res, q, truth = blundered
    tab = gruen_table() if table == "gruen" else baarda_table()
    ms = modified_snoop(res, table=tab, k_q=k_q)
    r = ms.result
    assert r.n_exact > 0 and r.n_exact < ms.model.n  # counted and reported
    assert f"{r.n_exact} exact qvv" in ms.summary()
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.sqrt(np.clip(q.redundancy_number, 0, None)) / r.approx
    outside = ~(np.abs(ratio - 1) <= k_q)
    differ = r.rejected != q.flagged
    assert not np.any(differ & ~outside)
    # every exact value equals the rigorous one
    assert np.allclose(r.redundancy_number[r.exact], q.redundancy_number[r.exact], atol=1e-10)
    assert not np.any(differ & r.exact)
    # the large blunders are found
    big = [b for b in truth["blunders"] if b["sigmas"] > 8]
    rej = ms.table()[lambda d: d["rejected"]]
    for b in big:
        assert ((rej["photo"] == b["photo"]) & (rej["point"] == b["point"])
                & (rej["component"] == b["component"])).any()


def test_block_tau_decisions(blundered):
    res, q, _ = blundered
    ms = modified_snoop(res, table=gruen_table(), statistic="tau")
    r = ms.result
    ref = q.active & q.controlled & (np.abs(np.nan_to_num(q.tau)) > q.k_tau)
    with np.errstate(divide="ignore", invalid="ignore"):
        outside = ~(np.abs(np.sqrt(np.clip(q.redundancy_number, 0, None)) / r.approx - 1)
                    <= 0.25)
    assert not np.any((r.rejected != ref) & ~outside)
    assert r.sigma0 == pytest.approx(q.sigma0_hat)
