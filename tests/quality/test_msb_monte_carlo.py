"""The minimal separable bias against Monte Carlo on the 3 x 8 block (issue 30): the bias at
which one step of data snooping (the largest |w|, significant) picks the erroneous
observation with probability beta0, simulated on the block's own linearised model."""

import numpy as np
import pytest
from dense import dense_system
from docs_text import doc_says

from baarda.bundle.bundle_model import BundleModel
from baarda.pipeline import adjust
from baarda.quality.statistics import analyse
from baarda.simulate.aerial import FlightPlan, simulate_block

TRIALS = 3000


@pytest.mark.slow
def test_msb_equals_the_monte_carlo_bias_of_one_step_identification():
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=8, pattern=5, seed=1))
    model = BundleModel(adjust(block))
    q = analyse(model)
    a, p = dense_system(model)
    hat = a @ np.linalg.solve(a.T @ (p[:, None] * a), a.T * p[None, :])
    tested = q.controlled
    sd = np.sqrt(np.where(tested, q.qvv, 1.0))
    # w = (I - H) e / sd for observation noise e; a bias b in j adds rho_ij E(w_j)
    rng = np.random.default_rng(5)
    noise = rng.standard_normal((model.n, TRIALS)) * model.sigma[:, None]
    w0 = ((noise - hat @ noise) / sd[:, None])[tested]
    qvv = (np.eye(model.n) - hat) * model.sigma[None, :] ** 2
    rho = (qvv / np.outer(sd, sd))[np.ix_(tested, tested)]
    rows = np.flatnonzero(tested)
    mdb = q.mdb / q.delta0  # sigma / sqrt(r): the bias of E(w) = 1
    ratios = []
    for j in rng.choice(np.flatnonzero(q.rho_max[rows] < 0.9), 12, replace=False):
        def correct(delta, j=j):
            w = np.abs(w0 + delta * rho[:, j][:, None])
            return np.mean((np.argmax(w, axis=0) == j) & (w[j] > q.k_w))
        lo, hi = q.delta0, 3 * q.delta0
        for _ in range(20):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if correct(mid) < q.beta0 else (lo, mid)
        ratios.append(q.msb[rows[j]] / (0.5 * (lo + hi) * mdb[rows[j]]))
    ratios = np.array(ratios)
    assert np.all(np.abs(ratios - 1) < 0.05), ratios
    assert np.all(q.msb[tested] >= q.mdb[tested])
    assert doc_says("docs/quality.md", f"twelve components with rho_max < 0.9: MSB / Monte "
                    f"Carlo {ratios.min():.3f} to {ratios.max():.3f}")
