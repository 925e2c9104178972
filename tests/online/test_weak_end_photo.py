"""A photo taken out at the end of a strip and added back with its correct points: its
tests are the batch adjustment's with it.  Without it, photo 02005 and its two-ray points
form a nearly critical relative orientation (points near a plane) and the block settles in
the other minimum (02005 phi -0.09 rad, sigma0 1.275); refined to that block, the returning
photo came out at phi -0.71 rad and the warm-started adjustment stopped in a local minimum
(sigma0 122 against the batch's 1.2555, |w| 229 to 1398 on correct observations).  A
refactorisation whose sigma0 jumps is tried again from the approximations (factorised.py
`_better_cold`)."""

import numpy as np
import pytest

from baarda.online.bundle import OnlineBundle
from baarda.simulate.aerial import FlightPlan, simulate_block
from tests.online.test_equivalence import TIGHT, batch, labels


@pytest.fixture(scope="module")
def end_photo():
    block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=6, pattern=4,
                                         relief_m=30.0, seed=4))
    i = list(block.photos.ids).index("02006")
    rows = np.flatnonzero(block.image.photo == i)
    pts = {block.points.ids[block.image.point[r]]: tuple(block.image.xy_mm[r]) for r in rows}
    ob = OnlineBundle(block.select_image(block.image.photo != i), solve=TIGHT)
    return ob, ob.add_photo("02006", pts)


def test_end_photo_added_back_is_tested_as_the_batch(end_photo):
    ob, a = end_photo
    assert len(a.tested) == 16 and a.refactorised  # 6 points and the 2 second rays on 02005
    assert not any(t.verdict == "reject" for t in a.tested)
    res, model, q, _ = batch(ob)
    assert res.sigma0 == pytest.approx(1.2554519, abs=1e-6)
    at = dict(zip(labels(model), range(model.n), strict=True))
    for t in a.tested:
        n = at[(t.kind, t.photo, t.point, t.component)]
        assert np.isfinite(t.w) == np.isfinite(q.w[n])
        if np.isfinite(q.w[n]):
            assert abs(t.w - q.w[n]) < 1e-6
    qc = ob.result()
    assert qc.adjustment.sigma0 == pytest.approx(res.sigma0, rel=1e-8)
    eo, _ = ob.estimates()
    assert abs(eo[ob.m.photo_at["02006"], 4]) < 0.01  # phi: a vertical photo again
