"""A free network whose GNSS positions or IMU attitudes fix part of its datum (issue 41):
minimal constraints only for what they leave free (bundle/datum_share.py), so that v'Pv,
every w and every redundancy number do not depend on which unknowns are held (v'Pv to
1e-9; w and r to the rounding floor of two minimal datums without GNSS, 1e-7),
and observations that fix a direction only weakly are left out of a free network."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from degenerate_blocks import flat_strip_camera_per_photo

from baarda.block.photo_block import GnssObservations, ImuObservations
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.datum_share import datum_share
from baarda.bundle.free_network import FreeBundleProblem, without_weak_datum_observations
from baarda.pipeline import assess, localized, with_approximations
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def sim():
    plan = FlightPlan(strips=2, photos_per_strip=4, pattern=3, control="none", height_chains=0,
                      relief_m=80.0, seed=5, gnss_sigma_m=0.05, imu_sigma_deg=0.005)
    b, truth = simulate_block(plan)
    return with_approximations(localized(b)), b


def _gnss(block, photos, offsets="none"):
    g = block.gnss
    sel = np.isin(g.photo, photos)
    out = replace(block, gnss=GnssObservations(g.photo[sel], g.xyz[sel], g.sigma[sel]),
                  imu=ImuObservations(np.zeros(0, np.int64), np.zeros((0, 3)),
                                      np.zeros((0, 3))))
    return replace(out, settings=replace(out.settings, gnss_offsets=offsets))


def _stats(problem):
    res = problem.fit()
    assert res.converged
    q = assess(res).quality
    return res, q


def _same(a, b):
    (ra, qa), (rb, qb) = a, b
    assert ra.redundancy == rb.redundancy
    assert rb.vtpv == pytest.approx(ra.vtpv, rel=1e-9)
    # w and r: the rounding floor of the normal equations, as between two minimal datums of
    # the block without GNSS (w 7e-8, r 3e-8 here)
    assert np.allclose(qa.w, qb.w, rtol=0, atol=1e-6, equal_nan=True)
    assert np.allclose(qa.redundancy_number, qb.redundancy_number, rtol=0, atol=1e-7)


def test_two_gnss_positions_leave_the_roll_about_their_line(sim):
    """Two GNSS positions (opposite corners) fix translation, scale and two rotations: one
    constraint holds the roll about their line, and the statistics are the same whichever
    unknown it is; the old seven constraints over-constrain the GNSS rows (v'Pv larger)."""
    block, _ = sim
    n = len(block.photos)
    b = _gnss(block, [0, n - 1])
    share = datum_share(b)
    assert share.d == 7 and share.carried == 6 and share.free.shape == (7, 1)
    assert not share.weak
    # the free direction is a rotation about the line through the two positions
    axis = block.photos.eo[n - 1, :3] - block.photos.eo[0, :3]
    w = share.free[3:6, 0]
    assert abs(np.dot(w, axis)) / np.linalg.norm(w) / np.linalg.norm(axis) == \
        pytest.approx(1, abs=1e-6)
    p1 = FreeBundleProblem(b, datum=(0, 1, 0))
    p2 = FreeBundleProblem(b, datum=(2, 5, 1))
    assert int(p1.held.sum()) == int(p2.held.sum()) == 1
    assert not np.array_equal(p1.held, p2.held)
    s1 = _stats(p1)
    _same(s1, _stats(p2))
    # six GNSS rows and six datum parameters fewer held: the redundancy of the block
    # without them
    r0 = FreeBundleProblem(_gnss(block, [])).fit().redundancy
    assert s1[0].redundancy == r0
    # the old seven constraints over-constrain the GNSS rows: v'Pv larger, other per photo
    old = np.zeros((n, 6), bool)
    old[0], old[1, 0] = True, True
    old2 = np.zeros((n, 6), bool)
    old2[2], old2[5, 1] = True, True
    va = BundleProblem(b, held=old).fit().vtpv
    vb = BundleProblem(b, held=old2).fit().vtpv
    assert va > s1[0].vtpv + 1e-6 and abs(va - vb) > 1e-6
    text = p1.datum_text()
    assert "the GNSS positions fix 6 of its 7 datum parameters" in text
    assert "minimal constraints hold the 1 direction(s) they leave free" in text
    assert "do not depend on the datum" in text


def test_a_gnss_shift_leaves_the_translation(sim):
    """GNSS on every photo with a shift per block: the shift takes the translation, the
    positions fix rotation and scale: three constraints, invariant statistics."""
    block, _ = sim
    b = _gnss(block, np.arange(len(block.photos)), offsets="block")
    share = datum_share(b)
    assert share.carried == 4 and not share.weak
    assert np.allclose(np.abs(share.free[3:]), 0, atol=1e-9)  # translations only
    p1, p2 = FreeBundleProblem(b, datum=(0, 1, 0)), FreeBundleProblem(b, datum=(6, 2, 1))
    assert int(p1.held.sum()) == 3
    _same(_stats(p1), _stats(p2))


def test_imu_attitudes_leave_translation_and_scale(sim):
    """IMU attitudes alone fix the three rotations: four constraints (translation, scale)."""
    block, _ = sim
    b = replace(block, gnss=GnssObservations(np.zeros(0, np.int64), np.zeros((0, 3)),
                                             np.zeros((0, 3))))
    share = datum_share(b)
    assert share.carried == 3 and share.by == "IMU attitudes"
    p1, p2 = FreeBundleProblem(b, datum=(0, 1, 0)), FreeBundleProblem(b, datum=(5, 3, 2))
    assert int(p1.held.sum()) == 4
    _same(_stats(p1), _stats(p2))


def test_gnss_on_every_photo_fixes_the_whole_datum(sim):
    """GNSS on all eight photos of two strips: no constraints at all (the datum line says so)
    and the adjusted projection centres are where the GNSS put them."""
    block, _ = sim
    b = _gnss(block, np.arange(len(block.photos)))
    share = datum_share(b)
    assert share.carried == 7 and not share.weak
    p = FreeBundleProblem(b)
    assert not p.held.any()
    res, _ = _stats(p)
    assert "no constraints" in p.datum_text()
    assert np.abs(res.eo[:, :3] - b.gnss.xyz).max() < 0.2  # 5 cm GNSS noise


def test_gnss_near_a_line_is_weak_and_left_out(sim):
    """Three GNSS positions of one strip (5 cm noise about its line): the roll about the
    strip is determined only weakly; a free network leaves them out (note) and holds the
    seven parameters, instead of letting them rotate the block."""
    block, _ = sim
    b = _gnss(block, [0, 1, 3])  # photos of the first strip
    share = datum_share(b)
    assert share.weak and share.carried == 7
    out = without_weak_datum_observations(b)
    assert len(out.gnss) == 0
    assert "GNSS positions left out of the adjustment" in out.notes[-1]
    assert without_weak_datum_observations(_gnss(block, [0, len(block.photos) - 1])) \
        .gnss.photo.tolist() == [0, len(block.photos) - 1]


def test_a_divergence_names_the_unknowns_that_are_not_determined():
    """Issue 41: a flat block of nadir photos, each with a camera of its own whose c, x0 and
    y0 are free: the message said 'the exterior orientation of photo ... is not determined:
    the block has a datum defect' (whatever the datum held).  It now names the unknowns
    whose columns are dependent (the null space of the photo's block of the reduced normal
    equations), and they are: the image Jacobian's columns of X0 and x0 are parallel."""
    from baarda.errors import GeometryError
    from baarda.pipeline import prepare

    b = flat_strip_camera_per_photo()
    p = prepare(b)
    with pytest.raises(GeometryError) as e:
        p.fit()
    msg = str(e.value)
    assert msg.startswith("X0 of photo 01002 and x0 of camera cam01002 cannot be told apart")
    assert "datum defect" not in msg and "01001" not in msg  # 01001: held by the datum
    # independently, densely: photo 01002's block of the normal equations with its points
    # eliminated (every photo's rays on them) has a null vector in X0 and x0
    lin = p.linearize(p.approximations)
    k = 1
    jf, jp, w = lin.jf, lin.jp, lin.w
    h = np.zeros((p.b, p.b))
    for j in np.unique(p.obs_point[p.obs_photo == k]):
        on = p.obs_point == j
        hpp = np.einsum("mka,mk,mkc->ac", jp[on], w[on], jp[on])
        mine = on & (p.obs_photo == k)
        hfp = np.einsum("mka,mk,mkc->ac", jf[mine], w[mine], jp[mine])
        h += np.einsum("mka,mk,mkc->ac", jf[mine], w[mine], jf[mine]) \
            - hfp @ np.linalg.solve(hpp, hfp.T)
    sc = 1 / np.sqrt(np.diag(h))
    lam, vec = np.linalg.eigh(sc[:, None] * h * sc[None, :])
    assert lam[0] < 1e-7 < lam[1]
    assert set(np.flatnonzero(np.abs(vec[:, 0]) > 0.2)) == {0, 7}  # X0 and x0


def test_a_gnss_datum_that_does_not_converge_says_why(sim):
    """Berlin's 3 GPS positions as the whole datum (no constraints): the least-squares
    datum turns the block by 134 degrees and scales it by 2.1, Gauss-Newton diverges and
    Levenberg-Marquardt does not arrive within its iterations; the notes say that the GPS
    carry the datum, how weakly, and what to do."""
    import baarda
    from baarda.pipeline import prepare

    src = Path(__file__).resolve().parents[1] / "data" / "opensfm_berlin"
    p = prepare(baarda.read(src))
    b = replace(p.block, gnss=baarda.read(src).gnss)  # the GPS rows back, no constraints
    q = FreeBundleProblem(b)
    assert not q.held.any() and q.share.carried == 7
    res = q.fit()
    assert not res.converged
    note = [n for n in res.notes if "carry 7 of the 7 datum parameters" in n]
    assert len(note) == 1 and "--datum control" in note[0] and "602 m" in note[0]
