"""Stage 1: 2D transformations of photo pairs, tested with planted errors."""

import numpy as np
import pytest

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.screening.log import ScreeningLog
from baarda.screening.pairs import (
    PAIR_TESTS,
    PairTest,
    blame,
    choose_kind,
    design,
    fit_pair,
    screen_pairs,
    transformation,
)
from baarda.simulate.aerial import FlightPlan, simulate_block


def pair_block(xy_a, xy_b, sigma_mm=0.005):
    """Two photos, k points: the smallest block fit_pair can work on."""
    k = len(xy_a)
    ids = [f"p{i}" for i in range(k)]
    return Block(Settings(), Cameras(["c"], np.array([153.0]), np.zeros((1, 2))),
                 Photos(["a", "b"], np.zeros(2, int), np.array(["1", "1"], dtype=object),
                        np.zeros((2, 6))),
                 ImagePoints(np.repeat([0, 1], k), np.tile(np.arange(k), 2),
                             np.vstack([xy_a, xy_b]), np.full(2 * k, sigma_mm)),
                 GroundPoints(ids, np.full((k, 3), np.nan), np.full((k, 3), np.nan),
                              np.full(k, "tie", dtype=object)))


@pytest.mark.parametrize("kind,params", [("similarity", [0.98, 0.05, -90.0, 2.0]),
                                         ("affine", [0.99, 0.02, -91.0, -0.03, 1.01, 1.5])])
def test_design_reproduces_the_transformation(kind, params):
    rng = np.random.default_rng(1)
    xy = rng.uniform(-100, 100, (7, 2))
    x, y = xy.T
    if kind == "similarity":
        a, b, c, d = params
        ref = np.column_stack([a * x - b * y + c, b * x + a * y + d])
    else:
        a1, a2, a3, b1, b2, b3 = params
        ref = np.column_stack([a1 * x + a2 * y + a3, b1 * x + b2 * y + b3])
    np.testing.assert_allclose(design(xy, kind) @ params, ref.ravel(), atol=1e-12)


def test_projective_jacobian_and_exact_fit():
    rng = np.random.default_rng(2)
    xy = rng.uniform(-100, 100, (9, 2))
    p = np.array([0.98, 0.03, -91.0, -0.02, 1.01, 1.2, 2e-4, -1e-4])
    f, _ = transformation(xy, "projective")
    val, jac = f(p)
    num = np.column_stack([(f(p + h)[0] - f(p - h)[0]) / (2 * h[k])
                           for k, h in enumerate(np.eye(8) * np.array([1e-6] * 6 + [1e-9] * 2))])
    np.testing.assert_allclose(jac, num, rtol=1e-5, atol=1e-6)
    # a plane seen from two tilted photos: the projective fit leaves nothing
    block = pair_block(xy, val.reshape(-1, 2))
    t = fit_pair(block, 0, 1, np.arange(9), 9 + np.arange(9), "projective", tests=PAIR_TESTS,
                 statistic="w")
    assert np.max(np.abs(t.run.model.residuals)) < 1e-9
    assert choose_kind(7, "auto", 4) == "projective"
    assert choose_kind(6, "auto", 4) == "affine"
    assert choose_kind(4, "auto", 4) == "similarity"
    assert choose_kind(3, "auto", 4) is None


def test_planted_error_is_found_and_tau_matches_brute_force():
    """Affine pair with 0.3 mm of 'relief' scatter and a 4 mm identification error."""
    rng = np.random.default_rng(3)
    xy_a = rng.uniform(-100, 100, (10, 2))
    truth = np.array([0.99, 0.02, -91.0, -0.03, 1.01, 1.5])
    xy_b = (design(xy_a, "affine") @ truth).reshape(-1, 2) + rng.normal(0, 0.3, (10, 2))
    xy_b[6] += (4.0, -1.0)
    block = pair_block(xy_a, xy_b)
    rows_a, rows_b = np.arange(10), 10 + np.arange(10)
    t = fit_pair(block, 0, 1, rows_a, rows_b, "affine", tests=PAIR_TESTS)
    assert t.rejected.tolist() == [i == 6 for i in range(10)]
    assert t.size[6] == pytest.approx(np.hypot(4.0, -1.0), rel=0.2)
    # independent: tau of the first adjustment from numpy least squares
    a = design(xy_a, "affine")
    sol, *_ = np.linalg.lstsq(a, xy_b.ravel(), rcond=None)
    v = a @ sol - xy_b.ravel()
    r = len(v) - a.shape[1]
    s0 = np.sqrt(v @ v / r)
    qvv = np.eye(len(v)) - a @ np.linalg.inv(a.T @ a) @ a.T
    tau = -v / (s0 * np.sqrt(np.diag(qvv)))
    assert t.sigma0 * np.hypot(0.005, 0.005) == pytest.approx(s0, rel=1e-9)
    assert t.redundancy == r
    assert t.value[0] == pytest.approx(np.abs(tau[:2]).max(), rel=1e-9)


def test_tolerance_keeps_errors_smaller_than_the_relief_parallax():
    rng = np.random.default_rng(3)
    xy_a = rng.uniform(-100, 100, (10, 2))
    xy_b = xy_a + (-92.0, 0.0) + rng.normal(0, 0.05, (10, 2))
    xy_b[2, 0] += 1.0
    block = pair_block(xy_a, xy_b)
    rows = np.arange(10), 10 + np.arange(10)
    assert fit_pair(block, 0, 1, *rows, "similarity", tests=PAIR_TESTS).rejected[2]
    t = fit_pair(block, 0, 1, *rows, "similarity", tests=PAIR_TESTS, tolerance_mm=2.0)
    assert not t.rejected.any()


def fake(a, b, points, rejected):
    k = len(points)
    return PairTest(a, b, "affine", np.array(points), np.ones(k, bool), np.array(rejected),
                    np.zeros(k), np.zeros(k), 3.0, 0.0, 1.0, 10)


def test_blame_singles_out_the_photo_that_all_its_pairs_reject():
    tests = [fake(1, 2, [7], [True]), fake(2, 3, [7], [True]), fake(1, 3, [7], [False])]
    photos, bad = blame(tests)[7]
    assert photos == [2] and len(bad) == 2


def test_blame_cannot_tell_with_one_rejecting_pair():
    tests = [fake(1, 2, [7], [True]), fake(2, 3, [7], [False])]
    assert blame(tests)[7][0] == [1, 2]
    assert 8 not in blame([fake(1, 2, [8], [False])])


def test_numbering_error_in_a_block_is_removed_from_its_photo():
    """Two points swapped on one photo (a numbering error): removed there, nothing else."""
    plan = FlightPlan(strips=2, photos_per_strip=5, pattern=5, side_overlap=0.6, relief_m=5,
                      sigma_image_um=3.0, seed=5)
    block, _ = simulate_block(plan)
    im = block.image
    photo = block.photo_index["01003"]
    rays = block.rays()
    rows = np.flatnonzero((im.photo == photo) & (rays[im.point] >= 4))
    r1, r2 = rows[0], rows[-1]
    assert np.linalg.norm(im.xy_mm[r1] - im.xy_mm[r2]) > 50
    im.xy_mm[[r1, r2]] = im.xy_mm[[r2, r1]]
    log = ScreeningLog()
    keep, tests = screen_pairs(block, np.ones(len(im), bool), log)
    assert set(np.flatnonzero(~keep).tolist()) == {int(r1), int(r2)}
    assert {e.photo for e in log.removed("image")} == {"01003"}
    within = sum(block.photos.strip[t.a] == block.photos.strip[t.b] for t in tests)
    assert within > 0 and len(tests) > within  # pairs within and across strips
