"""A group of more rows than a factorisation takes, with new unknowns, while rows are in
the low-rank update (OnlineBundle._take_in_factored)."""

import warnings

import numpy as np
import pytest

import baarda
from baarda.online.bundle import OnlineBundle
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def block():
    return simulate_block(FlightPlan(strips=2, photos_per_strip=6, pattern=4, relief_m=30.0,
                                     seed=4))[0]


def test_a_large_new_photo_after_a_small_addition_is_the_batch_adjustment(block):
    """A group of more rows than max_rows with a new photo, while rows added since the
    last factorisation are in the low-rank update (no new unknowns among them): the
    new factorisation starts the new photo and points at their approximations (it crashed
    reading their corrections from the update: the `online` strategy's trial 1 of a 3 x 8
    block, pattern 5, 5 blunders of 1-3 MDB)."""
    im, pts, ids = block.image, block.points, block.photos.ids
    mid = 2  # photo 01003: its neighbours 01004-01006 wait for it
    rays = np.bincount(im.point, minlength=len(pts))
    r0 = int(np.flatnonzero((im.photo >= 6) & (rays[im.point] >= 3) & (pts.role[im.point]
             == "tie") & ~np.isin(im.point, im.point[im.photo == mid]))[0])
    keep = im.photo != mid
    keep[r0] = False
    ob = OnlineBundle(block.select_image(keep), max_rows=20, linear_limit=1.0)
    a = ob.add_image_point(ids[im.photo[r0]], pts.ids[im.point[r0]], *im.xy_mm[r0])
    assert len(a.tested) == 2 and not a.refactorised and ob._f.lowrank.r == 2
    rows = np.flatnonzero(im.photo == mid)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no square root of a variance never computed
        b = ob.add_photo(ids[mid], {pts.ids[im.point[r]]: tuple(im.xy_mm[r]) for r in rows})
    assert b.refactorised and len(b.tested) == 119 and not b.held
    # every row of the new photo: no prediction; all tested in the new factorisation
    assert all(np.isnan(t.sigma_predicted) for t in b.tested if t.photo == ids[mid])
    q, ref = ob.result().adjustment, baarda.adjust(block)
    assert q.redundancy == ref.redundancy == 22
    assert q.sigma0 == pytest.approx(ref.sigma0, rel=1e-9)
