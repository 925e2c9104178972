"""Correlations of the w-tests and the minimal separable bias (quality/separability.py)
against dense brute force."""

from dataclasses import replace

import numpy as np
import pytest
from docs_text import doc_says
from gnss_blocks import with_gnss
from scipy import integrate, stats
from separability_dense import check

from baarda.block.photo_block import Distances
from baarda.bundle.bundle_model import BundleModel
from baarda.pipeline import adjust
from baarda.quality.distributions import b_method
from baarda.quality.separability import (
    identification_probability,
    separable_delta,
)
from baarda.quality.statistics import analyse
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def plain():
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=5, pattern=5, seed=7))
    return BundleModel(adjust(block))


def test_correlations_equal_the_dense_ones(plain):
    q, rho, near = check(plain)
    # the bound leaves frames out here; and the farther pairs are not asked for
    assert np.nanmax(q.rho_max) > 0.9999


def test_with_a_rejected_component(plain):
    r = analyse(plain, separability=False).redundancy_number
    act = plain.active.copy()
    act[np.argsort(-r)[[0, 1, 5]]] = False  # three well-controlled components rejected
    check(plain.refit(act))


def test_with_gnss_imu_and_their_global_unknowns():
    block, truth = simulate_block(FlightPlan(strips=3, photos_per_strip=6, pattern=3,
                                             seed=11))
    res = adjust(with_gnss(block, truth, offsets="strip", drift=True, boresight="estimated"))
    model = BundleModel(res)
    assert res.problem.system.ng and res.problem.system.mx
    check(model)


def test_with_self_calibration_fixed_control_and_a_distance():
    block, truth = simulate_block(FlightPlan(strips=4, photos_per_strip=5, relief_m=150.0,
                                             side_overlap=0.6, seed=21))
    cams = replace(block.cameras, model=np.array(["brown"], dtype=object),
                   coefficients=np.array([[1e-6, 0, 0, 2e-6, -1e-6, 0, 0]]))
    pts = block.points
    sigma = pts.sigma.copy()
    sigma[np.flatnonzero(pts.role == "control")[0]] = 0.0
    tie = np.flatnonzero(pts.role == "tie")
    a, b = tie[2], tie[-3]
    xa, xb = (np.array(truth["points"][pts.ids[j]]) for j in (a, b))
    dist = Distances(["bar"], np.array([a]), np.array([b]),
                     np.array([float(np.linalg.norm(xa - xb)) + 0.01]), np.array([0.02]))
    block = replace(block, cameras=cams,
                    settings=replace(block.settings,
                                     calibration_free=(("c", "k1", "p1", "p2", "b1"),)),
                    points=replace(pts, sigma=sigma), distances=dist)
    model = BundleModel(adjust(block))
    assert len(block.photos) == 20 and model.factor.system.ng > 5
    check(model)


# ------------------------------------------------------------------ MSB
def test_identification_probability_equals_numerical_integration():
    k = 3.29
    for delta, rho in ((4.0, 0.0), (5.0, 0.6), (7.5, 0.95), (12.0, 0.999), (4.2, -0.7)):
        r = abs(rho)
        s = np.sqrt(1 - r * r)

        def f(x, delta=delta, r=r, s=s):
            return stats.norm.pdf(x - delta) * (stats.norm.cdf((abs(x) - r * x) / s)
                                                - stats.norm.cdf((-abs(x) - r * x) / s))
        want = (integrate.quad(f, k, np.inf, epsabs=1e-12)[0]
                + integrate.quad(f, -np.inf, -k, epsabs=1e-12)[0])
        assert identification_probability(delta, rho, k) == pytest.approx(want, abs=1e-9)


def test_separable_delta_reaches_beta0_and_exceeds_delta0():
    bm = b_method(0.001, 0.8)
    rho = np.array([0.0, 0.3, 0.7, 0.9, 0.99, 0.9999])
    d = separable_delta(rho, bm.k_w, 0.8)
    assert np.all(d >= bm.delta0) and np.all(np.diff(d) > 0)
    assert identification_probability(d, rho, bm.k_w) == pytest.approx(0.8, abs=1e-4)
    # inseparable: grows as sqrt(2) Phi^-1(beta0) / sqrt(1 - rho)
    assert d[-1] * np.sqrt(1e-4) == pytest.approx(np.sqrt(2) * stats.norm.ppf(0.8), rel=1e-2)
    assert separable_delta(1.0, bm.k_w, 0.8) == np.inf


def test_rho_one_within_rounding_is_one_test():
    """Issue 44: |rho| within 1e-9 of 1 (rounding makes a pair that is one test 1 +- 1e-14)
    has no MSB (inf), whichever side of 1 it falls; from 1 - 1e-8 on it is finite and
    follows sqrt(2) Phi^-1(beta0) / sqrt(1 - rho)."""
    bm = b_method(0.001, 0.8)
    d = separable_delta(np.array([1 - 1e-14, 1.0, 1 + 1e-14, -1 + 1e-14, 1 - 1e-10]),
                        bm.k_w, 0.8)
    assert np.all(d == np.inf)
    d8 = float(separable_delta(1 - 1e-8, bm.k_w, 0.8))
    assert d8 * 1e-4 == pytest.approx(np.sqrt(2) * stats.norm.ppf(0.8), rel=1e-2)


@pytest.mark.slow
def test_farther_pairs_rarely_change_rho_max():
    """docs/quality.md, "Farther pairs are left out": the share of tested components whose
    largest correlation with any tested component exceeds the one with its neighbours."""
    words = []
    for plan in (FlightPlan(strips=3, photos_per_strip=8, pattern=5, seed=1),
                 FlightPlan(strips=4, photos_per_strip=8, pattern=3, seed=1),
                 FlightPlan(strips=3, photos_per_strip=8, pattern=5, side_overlap=0.6,
                            seed=1)):
        model = BundleModel(adjust(simulate_block(plan)[0]))
        q, rho, _ = check(model)
        t = q.controlled
        every = np.where(t[None, :], rho, 0.0).max(axis=1)[t]
        more = every - q.rho_max[t]
        assert np.all(more > -1e-6)
        assert not np.any((every >= 0.99) != (q.rho_max[t] >= 0.99))
        words.append((f"{100 * np.mean(more > 0.01):.1f} %", f"{more.max():.2f}"))
    (a, am), (b, bm), (c, cm) = words
    assert doc_says("docs/quality.md", f"on the 3 x 8 block (5 x 5 points, 60/30 %) {a} of "
                    f"the tested components get a larger rho_max from a farther pair by more "
                    f"than 0.01 (at most {am}); on a 4 x 8 block with 3 x 3 points {b} (at "
                    f"most {bm}); with 60 % side overlap {c} (at most {cm}); none of them "
                    "crosses |rho| = 0.99")


def test_partners_within_rounding_of_each_other_are_a_tie_the_first_is_taken():
    """Two partners of one test (rho = 1 +- rounding): the lower index, whichever the
    rounding favours and in whatever order the pairs come; rho_max the larger value."""
    from baarda.quality.separability import _update

    d = np.ones(4)
    act, tested = np.ones(4, np.bool_), np.ones(4, np.bool_)
    for order in ([0, 1, 2], [2, 1, 0]):
        i = np.array([0, 0, 0])[order]
        j = np.array([3, 1, 2])[order]
        q = np.array([0.5, 1.0 - 2e-16, 1.0 + 2e-16])[order]
        best, partner = np.zeros(4), np.full(4, -1, np.int64)
        _update(i, j, q, d, act, tested, best, partner)
        assert partner[0] == 1 and best[0] == 1.0 + 2e-16
        assert partner[1] == 0 and partner[2] == 0 and partner[3] == 0
    best, partner = np.zeros(4), np.full(4, -1, np.int64)
    _update(np.array([0, 0]), np.array([1, 2]), np.array([0.9, 0.9 + 1e-9]), d, act, tested,
            best, partner)
    assert partner[0] == 2  # 1e-9 apart: not a tie
