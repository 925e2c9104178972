"""Issue 14 acceptance on simulated blocks of 20 strips x 30 photos, GNSS sigma 5 cm with a
shift per strip, control only at the four corners."""

from dataclasses import replace

import numpy as np
import pytest

from baarda.options import TestOptions
from baarda.pipeline import adjust, assess, snoop
from baarda.simulate.aerial import FlightPlan, simulate_block

pytestmark = pytest.mark.slow


def _plan(seed: int, **kw) -> FlightPlan:
    return FlightPlan(strips=20, photos_per_strip=30, control="corners", relief_m=100.0,
                      gnss_sigma_m=0.05, seed=seed, **kw)


def test_check_points_as_the_covariance_predicts():
    """Squared check-point errors pooled over 8 blocks (200 check points each) against the
    mean variance the adjustment predicts for them (sigma0 a priori): within 20 % per
    axis.  One block alone is not enough: with control at the corners only, the errors of
    its check points are strongly correlated."""
    se, var = [], []
    for seed in range(8):
        block, _ = simulate_block(_plan(seed, gnss_offset_m=0.3, check_points=200))
        r = adjust(block)
        pb, pts = r.problem, block.points
        _, d = r.check_points()
        idx = np.flatnonzero((pts.role == "check") & (pb.remap >= 0))
        assert len(d) == len(idx) == 200 and r.converged
        se.append((d**2).mean(axis=0))
        var.append((r.xyz_std[pb.remap[idx]] ** 2).mean(axis=0) / r.sigma0**2)
    ratio = np.sqrt(np.mean(se, axis=0) / np.mean(var, axis=0))
    assert np.all(np.abs(ratio - 1) < 0.2), ratio


def test_a_gnss_blunder_is_found_and_nothing_else():
    """1 m in one GNSS height: snooping rejects it first and nothing else at alpha0 1e-5
    (a level for a block of 13,000 observations: at 0.001 about 13 false rejections are
    expected, and 8 come, the blunder still the first)."""
    block, _ = simulate_block(_plan(1, gnss_offset_m=0.3))
    g = block.gnss
    xyz = g.xyz.copy()
    k = 317
    xyz[k, 2] += 1.0
    s = snoop(replace(block, gnss=replace(g, xyz=xyz)), TestOptions(alpha0=1e-5, beta0=0.8))
    log = s.to_dict()["rejection_log"]
    assert [e["observations"] for e in log] == [[f"gnss photo {block.photos.ids[k]} Z"]]


def test_the_strip_shift_hypothesis():
    """A shift of 0.3 m in the heights of one strip's GNSS positions: its test is
    significant; without it, not."""
    block, _ = simulate_block(_plan(2))
    block = replace(block, settings=replace(block.settings, gnss_offsets="strip"))
    strips = np.asarray(block.photos.strip, dtype=object)
    g = block.gnss
    xyz = g.xyz.copy()
    xyz[strips[g.photo] == "7", 2] += 0.3
    name = "GNSS shift of strip 7"
    planted = {h.name: h for h in assess(adjust(replace(block, gnss=replace(g, xyz=xyz))))
               .hypotheses}
    plain = {h.name: h for h in assess(adjust(block)).hypotheses}
    assert planted[name].rejected and not plain[name].rejected
    assert abs(planted[name].nabla[2] - 0.3) < 0.1
