"""A photo taken out at the end of a strip and added back with its correct points: its
tests are the batch adjustment's with it.  Without it, photo 02005 and its two-ray points
form a nearly critical relative orientation (points near a plane): the block's least
squares minimum has 02005 at phi -0.09 rad (sigma0 1.2755; from the full block's estimates
it stops at 1.3353).  Refined to that block, the returning photo came out at phi -0.71 rad
and the warm-started adjustment stopped in a local minimum (sigma0 122 against the batch's
1.2555, |w| 229 to 1398 on correct observations); as a new photo (02006N) its resection
from the block's points was as bad.  A refactorisation whose sigma0 jumps is tried again
from the approximations (factorised.py `_better_cold`, approximations.py
`resected_again`)."""

import numpy as np
import pytest

from baarda.online.bundle import OnlineBundle
from baarda.simulate.aerial import FlightPlan, simulate_block
from tests.online.test_equivalence import TIGHT, batch, labels


@pytest.fixture(scope="module")
def block():
    return simulate_block(FlightPlan(strips=2, photos_per_strip=6, pattern=4, relief_m=30.0,
                                     seed=4))[0]


def added_back(block, name):
    i = list(block.photos.ids).index("02006")
    rows = np.flatnonzero(block.image.photo == i)
    pts = {block.points.ids[block.image.point[r]]: tuple(block.image.xy_mm[r]) for r in rows}
    ob = OnlineBundle(block.select_image(block.image.photo != i), solve=TIGHT)
    return ob, ob.add_photo(name, pts)


@pytest.fixture(scope="module")
def reference(block):
    """The batch adjustment of the block with 02006 (cold, from the approximations)."""
    ob, _ = added_back(block, "02006")
    res, model, q, _ = batch(ob)
    return res.sigma0, {k: q.w[n] for n, k in enumerate(labels(model))}


@pytest.mark.parametrize("name", ["02006", "02006N"])
def test_end_photo_added_back_is_tested_as_the_batch(block, reference, name):
    sigma0, w = reference
    assert sigma0 == pytest.approx(1.2554519, abs=1e-6)
    ob, a = added_back(block, name)
    assert len(a.tested) == 16 and a.refactorised  # 6 points and the 2 second rays on 02005
    assert not any(t.verdict == "reject" for t in a.tested)
    for t in a.tested:
        ref = w[(t.kind, t.photo.replace("N", ""), t.point, t.component)]
        assert np.isfinite(t.w) == np.isfinite(ref)
        if np.isfinite(ref):
            assert abs(t.w - ref) < 1e-6
    assert ob.result().adjustment.sigma0 == pytest.approx(sigma0, rel=1e-8)
    eo, _ = ob.estimates()
    assert abs(eo[ob.m.photo_at[name], 4]) < 0.01  # phi: a vertical photo again
