"""Noise-only simulated blocks: estimates agree with the truth within their precision."""

import numpy as np
import pytest
from scipy import stats

from baarda.pipeline import adjust
from baarda.simulate.aerial import FlightPlan, simulate_block


def truth_arrays(block, truth, result):
    eo = np.array([[truth["photos"][p][k] for k in ("X0", "Y0", "Z0", "omega", "phi", "kappa")]
                   for p in block.photos.ids])
    xyz = np.array([truth["points"][block.points.ids[j]] for j in result.problem.point_ids])
    return eo, xyz


@pytest.mark.parametrize("seed,stereo", [(1, False), (2, True)])
def test_noise_only_block_within_three_sigma(seed, stereo):
    plan = FlightPlan(strips=4, photos_per_strip=6, relief_m=60.0, stereo=stereo,
                      side_overlap=0.6 if stereo else 0.3, check_points=4, seed=seed)
    block, truth = simulate_block(plan)
    res = adjust(block)
    assert res.converged
    eo_t, xyz_t = truth_arrays(block, truth, res)
    z = np.concatenate([((res.eo - eo_t) / res.eo_std).ravel(),
                        ((res.xyz - xyz_t) / res.xyz_std).ravel()])
    assert np.mean(np.abs(z) <= 3.0) >= 0.99
    lo, hi = stats.chi2.ppf([0.005, 0.995], res.redundancy) / res.redundancy
    assert lo <= res.sigma0**2 <= hi
    # unbiased: the standardised errors have unit spread
    assert 0.7 < np.std(z) < 1.3


def test_sigma0_distribution_over_many_blocks():
    """sigma0^2 * r follows chi2(r): the mean over 12 blocks is r within 3 standard errors."""
    vals = []
    for seed in range(12):
        block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=5, relief_m=30,
                                             seed=100 + seed))
        res = adjust(block)
        vals.append(res.vtpv / res.redundancy)
    r = res.redundancy
    assert abs(np.mean(vals) - 1.0) < 3 * np.sqrt(2 / r) / np.sqrt(len(vals))


def test_noise_free_block_recovers_truth_exactly():
    block, truth = simulate_block(FlightPlan(strips=3, photos_per_strip=4, relief_m=50,
                                             noise=False, seed=5))
    res = adjust(block)
    eo_t, xyz_t = truth_arrays(block, truth, res)
    assert np.max(np.abs(res.eo[:, :3] - eo_t[:, :3])) < 1e-6
    assert np.max(np.abs(res.eo[:, 3:] - eo_t[:, 3:])) < 1e-9
    assert np.max(np.abs(res.xyz - xyz_t)) < 1e-6
    assert res.iterations <= 8
