"""OnlineBundle's rules: what is held, what is refused, removals that cannot be made."""

from dataclasses import replace

import numpy as np
import pytest

import baarda
from baarda.errors import GeometryError
from baarda.online.answers import verdict
from baarda.online.bundle import OnlineBundle
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def block():
    return simulate_block(FlightPlan(strips=2, photos_per_strip=6, pattern=4, relief_m=30.0,
                                     seed=4))[0]


def test_a_first_ray_is_held_until_the_second(block):
    im, pts = block.image, block.points
    rays = np.bincount(im.point, minlength=len(pts))
    j = int(np.flatnonzero((rays == 3) & (pts.role == "tie"))[0])
    rows = np.flatnonzero(im.point == j)
    ob = OnlineBundle(block.select_image(im.point != j))
    ids = block.photos.ids
    a = ob.add_image_point(ids[im.photo[rows[0]]], pts.ids[j], *im.xy_mm[rows[0]])
    assert a.verdict == "held" and not a.tested
    assert a.held == (f"point {pts.ids[j]} on photo {ids[im.photo[rows[0]]]}: its first ray",)
    a = ob.add_image_point(ids[im.photo[rows[1]]], pts.ids[j], *im.xy_mm[rows[1]])
    assert [(t.photo, t.component) for t in a.tested] == [
        (ids[im.photo[r]], c) for r in rows[:2] for c in "xy"]
    assert all(np.isnan(t.predicted) for t in a.tested)  # a new point: no prediction
    a = ob.add_image_point(ids[im.photo[rows[2]]], pts.ids[j], *im.xy_mm[rows[2]])
    assert len(a.tested) == 2 and np.isfinite(a.tested[0].predicted)


def test_refused_blocks(block):
    with pytest.raises(ValueError, match=r"GNSS shifts per strip .*baarda adjust"):
        OnlineBundle(replace(block, settings=replace(block.settings, gnss_offsets="strip")))
    with pytest.raises(ValueError, match=r"GNSS drifts per strip \(.*\) and an estimated IMU bore"):
        OnlineBundle(replace(block, settings=replace(block.settings, gnss_drift=True,
                                                     imu_boresight="estimated")))
    with pytest.raises(ValueError, match="free network"):
        OnlineBundle(replace(block, settings=replace(block.settings, datum="free")))
    sig = block.points.sigma.copy()
    j = np.flatnonzero(block.points.role == "control")[0]
    sig[j] = 0.0
    with pytest.raises(ValueError, match=rf"sigma 0.*\(point {block.points.ids[j]}\)"):
        OnlineBundle(replace(block, points=replace(block.points, sigma=sig)))


def test_bad_measurements_lose_nothing(block):
    ob = OnlineBundle(block)
    n = ob.steps
    with pytest.raises(ValueError, match="photo X is not known"):
        ob.add_image_point("X", "p", 0.0, 0.0)
    r = 0
    with pytest.raises(ValueError, match="measured on photo .* already"):
        ob.add_image_point(block.photos.ids[block.image.photo[r]],
                           block.points.ids[block.image.point[r]], 0.0, 0.0)
    with pytest.raises(ValueError, match="sigma 0"):
        ob.add_control(block.points.ids[0], [0, 0, 0], [0.0, 0.1, 0.1])
    assert ob.steps == n
    assert ob.result().adjustment.redundancy == baarda.adjust(block).redundancy


def test_a_removal_that_leaves_the_block_undetermined_is_not_made(block):
    ob = OnlineBundle(block)
    before = ob.result()
    ctrl = [block.points.ids[j] for j in np.flatnonzero(block.points.controlled.any(axis=1))]
    with pytest.raises(GeometryError, match="cannot be taken out"):
        for pid in ctrl:  # take the control away until the datum goes
            ob.remove_control(pid)
    removed = [pid for pid in ctrl if ob.m.ctrl_status[ob.m.point_at[pid]] == "removed"]
    assert 0 < len(removed) < len(ctrl)
    after = ob.result()
    assert after.adjustment.redundancy == before.adjustment.redundancy - sum(
        int(np.isfinite(block.points.sigma[block.points.ids.index(p)]).sum()) for p in removed)


def test_removing_what_is_held_factors_nothing(block):
    im, pts = block.image, block.points
    rays = np.bincount(im.point, minlength=len(pts))
    j = int(np.flatnonzero((rays == 3) & (pts.role == "tie"))[0])
    r = np.flatnonzero(im.point == j)[0]
    ob = OnlineBundle(block.select_image(im.point != j))
    ob.add_image_point(block.photos.ids[im.photo[r]], pts.ids[j], *im.xy_mm[r])
    a = ob.remove_image_point(block.photos.ids[im.photo[r]], pts.ids[j])
    assert not a.refactorised and a.note == "it was not in the block"


def test_verdicts():
    assert verdict(3.3, 0.2, 3.29) == "reject"
    assert verdict(-3.2, 0.2, 3.29) == "accept"
    assert verdict(float("nan"), 5e-4, 3.29) == "suspect"
    assert verdict(10.0, 5e-4, 3.29) == "suspect"


def test_add_camera_refusals(block):
    """A camera the block has, or one whose parameters are to be estimated, is refused and
    nothing changes; a new one with its interior orientation held is taken."""
    ob = OnlineBundle(block)
    n, steps = len(ob.m.cameras), ob.steps
    with pytest.raises(ValueError, match="is in the block already"):
        ob.add_camera(block.cameras, 0)
    other = replace(block.cameras, ids=["other"])
    with pytest.raises(ValueError, match="does not estimate the parameters of a new camera"):
        ob.add_camera(other, 0, ("c",))
    assert len(ob.m.cameras) == n and ob.steps == steps
    a = ob.add_camera(replace(block.cameras, ids=["second"]), 0)
    assert a.what == "camera second" and a.refactorised and not a.changed
    assert ob.m.cameras.ids[-1] == "second" and len(ob.m.cameras) == n + 1


def test_remeasure_names_the_largest_w_among_the_rejected_and_the_changed():
    """Answer.remeasure(): a verdict the step changed to reject counts as a tested one does
    (the demo's step 5: the new ray on 01005 rejected at 4.09, the ray on 01004 changed to
    reject at -4.23: 01004 is the one to re-measure); a component both tested and changed
    once, with its test; nothing rejected, nothing to re-measure."""
    from baarda.online.answers import Answer, Change, ComponentTest

    def t(photo, w, v):
        return ComponentTest("image", photo, "002005", "x", 0.0, 0.0, 0.0, 0.0, 0.2, w, 0.05, v)

    a = Answer(step=5, action="add", what="photo 01005", k_w=3.29,
               tested=(t("01005", 4.09, "reject"), t("01006", 1.0, "accept")),
               changed=(Change("image", "01004", "002005", "x", "accept", "reject", -4.23),
                        Change("image", "01003", "002005", "x", "reject", "accept", -9.0),
                        Change("image", "01005", "002005", "x", "held", "reject", 4.09)))
    assert [(r.photo, r.w) for r in a.remeasure()] == [("01004", -4.23), ("01005", 4.09)]
    assert isinstance(a.remeasure()[1], ComponentTest)
    assert "REMEASURE POINT 002005 ON PHOTO 01004 (x: SIGF 4.23 > 3.29)" in a.text()
    assert replace(a, changed=a.changed[1:2]).remeasure()[0].photo == "01005"
    assert replace(a, tested=a.tested[1:], changed=a.changed[1:2]).remeasure() == []


def test_a_control_point_before_any_image_point_is_answered(block):
    """add_control on a block with no image point yet: an Answer that says why nothing is
    adjusted (it returned None: `_start` has nothing to adjust)."""
    empty = block.select_image(np.zeros(len(block.image), bool))
    ob = OnlineBundle(empty)
    assert ob.steps == 0 and not ob.started
    tie = int(np.flatnonzero(~block.points.controlled.any(axis=1))[0])
    ans = ob.add_control(block.points.ids[tie], [0.0, 0.0, 0.0], [0.1, 0.1, 0.1])
    assert ans is not None and ans.step == 1 and ans.action == "add"
    assert ans.note == "the block cannot be adjusted yet: nothing measured"
    assert not ob.started


@pytest.mark.parametrize("shift, said", [
    (1e4, "photo 02006N: point 005009 at (9906.93, -55.3513) mm lies 246 times as far from "
          "the middle of the photo's points as the others: outside the format, a mistyped "
          "coordinate? (remove it or measure it again)"),
    (100.0, "photo 02006N: its 4 points in the block fit no one orientation (no resection "
            "puts them in front of the camera)")])
def test_a_held_photo_says_what_is_wrong(block, shift, said):
    """A new photo with one point 10 m outside the format (or 100 mm off) was held as 'not
    determined yet (4 of its points in the block, 3 needed)': it had them."""
    im, ids = block.image, block.photos.ids
    i = len(ids) - 1
    ob = OnlineBundle(block.select_image(im.photo != i))
    rows = np.flatnonzero(im.photo == i)
    points = {block.points.ids[im.point[r]]: tuple(im.xy_mm[r]) for r in rows}
    a = ob.add_photo(ids[i] + "N", points)  # as measured: taken in
    assert not a.held and {t.photo for t in a.tested} >= {ids[i] + "N"}
    ob = OnlineBundle(block.select_image(im.photo != i))
    first = next(iter(points))
    points[first] = (points[first][0] + shift, points[first][1])
    a = ob.add_photo(ids[i] + "N", points)
    assert not a.tested and len(a.held) == len(rows)
    assert a.held[0] == f"point {first} on photo {ids[i]}N: {said}"
