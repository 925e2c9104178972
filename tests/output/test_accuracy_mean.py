"""The mean miss of the check points and its standard deviation from the adjustment
(bundle/check_mean.py): checked against the dense cofactors of every check coordinate, and on
simulated blocks whose check points are the truth and whose control is unbiased (issue 42:
std / sqrt(n) treats the correlated misses as independent and called a 3,000-photo block's
mean a systematic shift)."""

from dataclasses import replace

import numpy as np
import pytest

from baarda.block.photo_block import Distances
from baarda.bundle.check_mean import check_mean_cofactor
from baarda.output.accuracy import FREE_SIMILARITY
from baarda.output.bundle_results import accuracy_of, points_table
from baarda.pipeline import adjust, prepare
from baarda.simulate.aerial import FlightPlan, simulate_block


def dense_mean_cofactor(res, points: np.ndarray) -> np.ndarray:
    """(1/n^2) sum_ij Q_ij from N^-1 e_k for every check coordinate (solve_normal)."""
    pb, s = res.problem, res.factor.system
    start = pb.global_layout.start("points") if s.ng else 0
    n = len(points)
    q = np.zeros((3 * n, 3 * n))

    def pick(out, j):
        e = pb.eremap[j]
        if e >= 0:
            return out[1][e, :, 0]
        return out[2][start + 3 * pb.bremap[j] + np.arange(3), 0]

    for k, j in enumerate(points):
        for a in range(3):
            gf, gp = np.zeros((s.nf, s.b, 1)), np.zeros((s.np, s.d, 1))
            gg = np.zeros((s.ng, 1)) if s.ng else None
            if pb.eremap[j] >= 0:
                gp[pb.eremap[j], a, 0] = 1.0
            else:
                gg[start + 3 * pb.bremap[j] + a, 0] = 1.0
            out = res.factor.solve_normal(gf, gp, gg)
            for k2, j2 in enumerate(points):
                q[3 * k2:3 * k2 + 3, 3 * k + a] = pick(out, j2)
    g = np.tile(np.eye(3), (n, 1)) / n
    return g.T @ q @ g


def check_points_of(res) -> np.ndarray:
    pts = res.block.points
    return np.flatnonzero((pts.role == "check") & (res.problem.remap >= 0))


def test_cofactor_of_the_mean_equals_the_dense_one():
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=6, check_points=5,
                                         seed=1))
    res = adjust(block)
    idx = check_points_of(res)
    q = check_mean_cofactor(res)
    np.testing.assert_allclose(q, dense_mean_cofactor(res, idx), rtol=1e-9, atol=1e-15)
    # one point: its own cofactor block (the selected inverse's)
    one = check_mean_cofactor(res, idx[:1])
    np.testing.assert_allclose(one, res.point_covariance()[res.problem.remap[idx[0]]],
                               rtol=1e-9)
    # the misses are correlated: the mean's variance exceeds the independent sum / n^2
    indep = res.point_covariance()[res.problem.remap[idx]].sum(axis=0) / len(idx) ** 2
    assert (np.diag(q) > 1.5 * np.diag(indep)).all()


def test_cofactor_of_the_mean_with_check_points_in_the_border():
    """A distance between two check points makes them global unknowns of the factor."""
    block, truth = simulate_block(FlightPlan(strips=3, photos_per_strip=6, check_points=5,
                                             seed=1))
    idx = np.flatnonzero(block.points.role == "check")
    a, b = idx[:2]
    length = float(np.linalg.norm(block.points.xyz[a] - block.points.xyz[b]))
    block = replace(block, distances=Distances(["d1"], np.array([a]), np.array([b]),
                                               np.array([length]), np.array([0.01])))
    res = adjust(block)
    assert res.factor.system.ng and (res.problem.bremap[[a, b]] >= 0).all()
    pts = check_points_of(res)
    np.testing.assert_allclose(check_mean_cofactor(res), dense_mean_cofactor(res, pts),
                               rtol=1e-9, atol=1e-15)


def test_free_network_has_no_mean_to_test():
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=6, check_points=5,
                                         seed=1))
    res = adjust(prepare(block, free=True))
    assert res.free_network and check_mean_cofactor(res) is None
    acc = accuracy_of(res, points_table(res))
    assert acc.datum == FREE_SIMILARITY and acc.stated and acc.mean_covariance is None


def test_a_true_block_with_unbiased_control_is_not_called_shifted():
    """120 photos, 40 check points equal to the truth: the old test (|mean| > 2 std /
    sqrt(n)) calls the mean in X a systematic shift, the adjustment's covariance does not."""
    block, _ = simulate_block(FlightPlan(strips=10, photos_per_strip=12, check_points=40,
                                         seed=0))
    res = adjust(block)
    acc = accuracy_of(res, points_table(res))
    t = acc.table.set_index("axis")
    n = acc.n
    assert n == 40
    mean, std = t["mean m"], t["std m"]
    old = mean / (std / np.sqrt(n))
    assert mean["X"] == pytest.approx(-0.0368, abs=1e-4)
    assert old["X"] == pytest.approx(-3.82, abs=0.01)  # the old rule: "significant"
    assert t.loc["X", "sd of mean m"] == pytest.approx(0.0261, abs=2e-4)
    assert std["X"] / np.sqrt(n) == pytest.approx(0.0096, abs=2e-4)
    assert t.loc["X", "mean / sd"] == pytest.approx(-1.41, abs=0.01)
    assert not any("a systematic shift" in w for w in acc.warnings)


@pytest.mark.slow
def test_false_alarms_of_the_mean_test_over_40_blocks():
    """40 simulated blocks (120 photos, 40 true check points, control with noise): the old
    rule flags 25 of 40 X means and 24 of 40 Y means, the test with the adjustment's covariance
    3 and 1 (5 % expected: 2); the spread of the means over the blocks is the adjustment's
    prediction (0.027 .. 0.031 m), not std / sqrt(n) (0.008 m in X and Y)."""
    means, sd_adj, sd_old, z = [], [], [], []
    for seed in range(40):
        block, _ = simulate_block(FlightPlan(strips=10, photos_per_strip=12,
                                             check_points=40, seed=seed))
        res = adjust(block)
        t = accuracy_of(res, points_table(res)).table
        means.append(t["mean m"])
        sd_adj.append(t["sd of mean m"])
        sd_old.append(t["std m"] / np.sqrt(40))
        z.append(t["mean / sd"])
    means, sd_adj, sd_old, z = (np.array(a) for a in (means, sd_adj, sd_old, z))
    old_alarms = (np.abs(means) > 2 * sd_old).sum(axis=0)
    new_alarms = (np.abs(z) > 1.96).sum(axis=0)
    spread = means.std(axis=0, ddof=1)
    assert old_alarms.tolist() == [25, 24, 5]
    assert new_alarms.tolist() == [3, 1, 2]
    predicted = np.sqrt((sd_adj ** 2).mean(axis=0))
    np.testing.assert_allclose(spread, [0.0323, 0.0255, 0.0223], atol=5e-4)
    np.testing.assert_allclose(predicted, [0.0273, 0.0306, 0.0268], atol=5e-4)
    np.testing.assert_allclose(np.sqrt((sd_old ** 2).mean(axis=0)), [0.0080, 0.0078, 0.0176],
                               atol=5e-4)
    assert (np.abs(spread / predicted - 1) < 0.25).all()  # 40 samples: within their spread
    assert np.abs(means.mean(axis=0)).max() < 2.5 * spread.max() / np.sqrt(40)  # unbiased


@pytest.mark.slow
def test_the_3000_photo_block_of_the_issue():
    """50 x 60 photos, 40 true check points (issue 42): the old rule calls the mean in X a
    systematic shift, the adjustment's covariance (about twice std / sqrt(n)) does not."""
    block, _ = simulate_block(FlightPlan(strips=50, photos_per_strip=60, check_points=40,
                                         seed=2))
    res = adjust(block)
    acc = accuracy_of(res, points_table(res))
    t = acc.table.set_index("axis")
    old = t["mean m"] / (t["std m"] / np.sqrt(acc.n))
    assert len(block.photos) == 3000 and acc.n == 40
    assert old["X"] == pytest.approx(-2.94, abs=0.01)
    assert t.loc["X", "sd of mean m"] == pytest.approx(0.0167, abs=2e-4)
    assert t.loc["X", "mean / sd"] == pytest.approx(-1.65, abs=0.01)
    assert not any("a systematic shift" in w for w in acc.warnings)
