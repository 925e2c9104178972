"""Data snooping on simulated blocks: residual response, detection, restoring."""

import numpy as np
import pytest

from baarda.pipeline import adjust, assess, snoop
from baarda.simulate.aerial import FlightPlan, simulate_block


def test_blunder_changes_residual_by_minus_r_times_d():
    """Kratky eq. 5 / Gruen eq. 6: dv_i = -r_i d for an error d in observation i."""
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=5, relief_m=40, seed=4))
    qc = assess(adjust(block))
    q, m = qc.quality, qc.model
    d = 0.002  # mm = 2 µm: small, so the re-adjustment stays linear
    for i in np.flatnonzero(q.controlled & (m.kind == "image"))[::17][:6]:
        row, comp = m.image_row[i], "xy".index(m.component[i])
        block.image.xy_mm[row, comp] += d
        try:
            res2 = adjust(block)
        finally:
            block.image.xy_mm[row, comp] -= d
        v2 = res2.image_residuals.ravel()[i]
        assert v2 - q.residual[i] == pytest.approx(-q.redundancy_number[i] * d, abs=2e-3 * d)


@pytest.mark.slow
def test_snooping_finds_blunders_and_nothing_else():
    """1 % of image observations blundered by 6-20 sigma in a 6 x 10 block."""
    plan = FlightPlan(strips=6, photos_per_strip=10, relief_m=50, pattern=5, seed=7,
                      side_overlap=0.6, blunders=0)
    block, _ = simulate_block(plan)
    n_img = 2 * len(block.image)
    plan.blunders = int(round(0.01 * n_img))
    block, truth = simulate_block(plan)
    qc = snoop(block)
    m = qc.model
    gone = np.flatnonzero(~qc.quality.active)
    rejected = {(m.frame[i], m.point[i], m.component[i]) for i in gone}
    planted = {(b["photo"], b["point"], b["component"]) for b in truth["blunders"]}
    found = planted & rejected
    false = rejected - planted
    # the numbers of this block (kept from getting worse): see the closing note of issue 3.
    # False rejections: about alpha0 * n = 3 are expected by the test itself.
    n_tested = int(np.sum(qc.quality.controlled))
    assert len(found) >= 0.9 * len(planted)
    assert len(false) <= 0.001 * n_tested + 3 * np.sqrt(0.001 * n_tested)
    # sigma0 after cleaning: chi2(r)/r within its 99.9 % interval
    r = qc.quality.redundancy
    assert abs(qc.quality.sigma0_hat**2 - 1) < 3.3 * np.sqrt(2 / r)
    assert qc.run.converged


def test_rejected_observation_returns_when_not_significant():
    """Force a rejection of a good observation: the next snooping step restores it."""
    from baarda.bundle.bundle_model import BundleModel
    from baarda.quality.iterative import iterative_snooping
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=5, relief_m=40, seed=9))
    first = BundleModel(adjust(block))
    good = int(np.flatnonzero(assess(first.result).quality.redundancy_number > 0.5)[0])
    start = first.active.copy()
    start[good] = False
    run = iterative_snooping(first, active=start)
    assert first.active.all()  # the model snooping started from is unchanged
    assert run.active[good]
    assert [s.action for s in run.log] == ["restore"]
    assert run.log[0].rows == [good]


def test_danish_prescreening_then_snooping_finds_many_large_blunders():
    plan = FlightPlan(strips=4, photos_per_strip=8, relief_m=50, pattern=5, side_overlap=0.6,
                      blunders=25, blunder_sigma=(20.0, 60.0), seed=31)
    block, truth = simulate_block(plan)
    planted = {(b["photo"], b["point"], b["component"]) for b in truth["blunders"]}
    found = {}
    for robust in (False, True):
        qc = snoop(block, robust=robust)
        m = qc.model
        rejected = {(m.frame[i], m.point[i], m.component[i])
                    for i in np.flatnonzero(~qc.quality.active)}
        found[robust] = len(planted & rejected)
        assert len(rejected - planted) <= 3
        assert qc.run.converged
    assert found[True] >= found[False]
    assert found[True] >= 0.9 * len(planted)


def test_component_the_block_needs_is_kept_and_reported():
    """If rejecting the worst component leaves the model undetermined, it stays in."""
    from baarda.errors import GeometryError
    from baarda.quality.dense_model import DenseModel
    from baarda.quality.iterative import iterative_snooping
    rng = np.random.default_rng(3)
    a = rng.normal(size=(30, 3))
    x = np.array([1.0, -2.0, 0.5])
    obs = a @ x + rng.normal(0, 0.01, 30)
    obs[4] += 0.5  # a blunder of 50 sigma in a component the "block" cannot lose
    obs[9] -= 0.3  # and one it can
    sigma = np.full(30, 0.01)

    def fit(active):
        if not active[4]:
            raise GeometryError("the exterior orientation of photo 7 is not determined")
        p = active / sigma**2
        xh = np.linalg.solve(a.T @ (p[:, None] * a), a.T @ (p * obs))
        return NeedsFour(a, sigma, a @ xh - obs, active)

    class NeedsFour(DenseModel):
        """The component 4 determines an unknown of the 'block'."""

        def refit(self, active, factors=None):
            return fit(active)

    run = iterative_snooping(fit(np.ones(30, bool)))
    assert run.active[4] and not run.active[9]
    assert any("cannot be tested by removing it: without it the exterior orientation of "
               "photo 7 is not determined" in n for n in run.quality.notes)
    kept = run.refused
    assert [s.rows for s in kept] == [[4]] and "photo 7" in kept[0].reason
    assert "removal(s) refused" in run.summary_lines()[0]
