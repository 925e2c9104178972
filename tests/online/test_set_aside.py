"""Rays the test cannot tell apart: OnlineBundle.inseparable (the correlation of two w-tests
in the block as it is now) against the batch adjustment's Qvv columns, set_aside, and the
replay's operator who sets a point aside until a ray can tell which one is wrong."""

from dataclasses import replace

import numpy as np
import pytest

from baarda.online.bundle import OnlineBundle
from baarda.online.replay import replay
from baarda.pipeline import adjust
from baarda.quality.iterative import inseparable_partners
from baarda.simulate.aerial import FlightPlan, simulate_block


def _block(noise=True):
    return simulate_block(FlightPlan(strips=2, photos_per_strip=6, pattern=4, relief_m=30.0,
                                     seed=4, noise=noise))[0]


def _keys(model):
    return [(str(k), str(f), str(p), str(c)) for k, f, p, c in zip(
        model.kind, model.frame, model.point, model.component, strict=True)]


def test_inseparable_equals_the_batch_qvv_columns():
    """Rows of the factorisation, rows added since and the cross terms between them: rho of
    every pair equals one column of the batch Qvv (Gruen's identity column) to 1e-7.  The
    block is noise-free, so the rows added since the factorisation are linearised where the
    batch linearises them (with noise the low-rank state is the first-order one)."""
    block = _block(noise=False)
    im, pts, ids = block.image, block.points, block.photos.ids
    rays = np.bincount(im.point, minlength=len(pts))
    late, keep = [], np.ones(len(im), bool)
    for j in np.flatnonzero((rays >= 3) & (pts.role == "tie"))[:3]:  # third rays late
        rows = np.flatnonzero(im.point == j)
        keep[rows[2:]] = False
        late += rows[2:].tolist()
    j2 = int(np.flatnonzero((rays == 2) & (pts.role == "tie"))[0])  # a new two-ray point
    keep[im.point == j2] = False
    late += np.flatnonzero(im.point == j2).tolist()
    ob = OnlineBundle(block.select_image(keep), max_rows=10_000)
    for r in late:
        a = ob.add_image_point(ids[im.photo[r]], pts.ids[im.point[r]], *im.xy_mm[r])
        assert not a.refactorised
    asked = [("image", ids[im.photo[r]], pts.ids[im.point[r]], c)
             for r in late[::2] for c in "xy"]
    got = {t: dict(ob.inseparable(*t, threshold=0.0)) for t in asked}
    res = ob.result()
    model, q = res.model, res.quality
    keys = _keys(model)
    compared = 0
    for t in asked:
        idx, rho = inseparable_partners(model, q, keys.index(t), np.ones(model.n, bool),
                                        threshold=0.0)
        ref = {keys[k]: float(r) for k, r in zip(idx, rho, strict=True)
               if keys[k][2] == t[2] and r != 0.0}
        assert set(ref) == set(got[t])
        for k, r in ref.items():
            assert got[t][k] == pytest.approx(r, abs=1e-7)
            compared += 1
    assert compared >= 20
    # a two-ray point: every tested component of it is one test (|rho| = 1)
    t = ("image", ids[im.photo[late[-1]]], pts.ids[j2], "y")
    assert [abs(r) for _, r in ob.inseparable(*t)] == pytest.approx([1.0], abs=1e-9)


def test_set_aside_until_the_next_ray():
    block = _block()
    im, pts, ids = block.image, block.points, block.photos.ids
    rays = np.bincount(im.point, minlength=len(pts))
    j = int(np.flatnonzero((rays >= 3) & (pts.role == "tie"))[0])
    rows = np.flatnonzero(im.point == j)
    ob = OnlineBundle(block.select_image(im.point != j))
    for r in rows[:-1]:
        ob.add_image_point(ids[im.photo[r]], pts.ids[j], *im.xy_mm[r])
    assert all(ob.is_in("image", ids[im.photo[r]], pts.ids[j]) for r in rows[:-1])
    a = ob.set_aside(pts.ids[j])
    assert a.refactorised and ob.waiting(pts.ids[j])
    assert not any(ob.is_in("image", ids[im.photo[r]], pts.ids[j]) for r in rows)
    # the block without the point, as the batch adjusts it
    ref = adjust(block.select_image(im.point != j))
    res = ob.result()
    assert res.adjustment.redundancy == ref.redundancy
    assert float(res.adjustment.sigma0) == pytest.approx(float(ref.sigma0), rel=1e-8)
    # a new measurement on one of its photos does not bring it back; its next ray does,
    # with every ray tested again
    other = next(r for r in np.flatnonzero(im.photo == im.photo[rows[0]]) if im.point[r] != j)
    ob.remove_image_point(ids[im.photo[other]], pts.ids[im.point[other]])
    b = ob.add_image_point(ids[im.photo[other]], pts.ids[im.point[other]], *im.xy_mm[other])
    assert ob.waiting(pts.ids[j]) and all(t.point != pts.ids[j] for t in b.tested)
    c = ob.add_image_point(ids[im.photo[rows[-1]]], pts.ids[j], *im.xy_mm[rows[-1]])
    assert not ob.waiting(pts.ids[j])
    assert sorted((t.photo, t.component) for t in c.tested if t.point == pts.ids[j]) == \
        sorted((ids[im.photo[r]], x) for r in rows for x in "xy")
    res = ob.result()
    full = adjust(block)
    assert res.adjustment.redundancy == full.redundancy
    assert float(res.adjustment.sigma0) == pytest.approx(float(full.sigma0), rel=1e-8)


def test_the_replay_sets_aside_what_it_cannot_tell_and_finds_it_with_the_next_ray():
    """A 40 µm error in y on the first ray of point 003015 (the middle row, seen by photos
    01008-01010 of strip 1, long after the first adjustment; no noise): when its second ray
    comes the two y's are one test (rejected, the test cannot tell which); the operator
    sets the point aside instead of re-measuring both; the third ray tells: the wrong ray
    alone is taken out and the point is back in the block with its two good rays."""
    block = simulate_block(FlightPlan(strips=2, photos_per_strip=10, pattern=4,
                                      relief_m=30.0, seed=4, noise=False))[0]
    im, pts, ids = block.image, block.points, block.photos.ids
    j = pts.ids.index("003015")
    rows = np.flatnonzero(im.point == j)
    assert [ids[i] for i in im.photo[rows]] == ["01008", "01009", "01010"]
    xy = im.xy_mm.copy()
    xy[rows[0], 1] += 0.040
    rp = replay(replace(block, image=replace(im, xy_mm=xy)), remove="worst")
    said = [a for a in rp.answers if "set aside" in a.what]
    assert len(said) == 1 and said[0].what.startswith("point 003015 (set aside")
    assert "the test cannot tell it from y on photo" in said[0].what
    assert [r[1:5] for r in rp.removed] == [("image", "01008", "003015", "y")]
    assert rp.removed[0][0] > said[0].step  # found when the third ray came
    assert rp.aside == ()
    assert rp.online.is_in("image", "01009", "003015")
    assert rp.online.is_in("image", "01010", "003015")
    # what is left is the block without the wrong ray
    ref = adjust(block.select_image(np.arange(len(im)) != rows[0]))
    res = rp.online.result()
    assert res.adjustment.redundancy == ref.redundancy
    assert float(res.adjustment.sigma0) < 1e-6  # no noise: nothing wrong is left in it
