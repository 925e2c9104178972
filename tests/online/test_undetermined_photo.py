"""A photo the adjustment finds undetermined is named by the error's frame (not by the words
of its message, which name camera parameters where the photo's own are free): the on-line
bundle leaves that photo out and factors the block again, at the start and on a removal."""


import numpy as np
import pytest
from degenerate_blocks import flat_strip_camera_per_photo

from baarda.bundle.bundle_problem import BundleProblem
from baarda.errors import GeometryError
from baarda.online.bundle import OnlineBundle
from baarda.online.factorised import undetermined_photo
from baarda.simulate.aerial import FlightPlan, simulate_block

WORDS = "X0 of photo {} and x0 of camera c cannot be told apart"


@pytest.fixture(scope="module")
def block():
    return simulate_block(FlightPlan(strips=2, photos_per_strip=6, pattern=4, relief_m=30.0,
                                     seed=4))[0]


def test_the_schur_factor_names_the_frame_it_cannot_determine():
    """A flat block, each photo with a camera of its own whose c, x0 and y0 are free: the
    message names the unknowns (no 'orientation of photo ... is not determined') and the
    error carries the photo (frame 1, 01002)."""
    from baarda.pipeline import prepare

    b = flat_strip_camera_per_photo()
    with pytest.raises(GeometryError, match="cannot be told apart") as e:
        prepare(b).fit()
    assert "is not determined:" not in str(e.value)
    assert e.value.frame == 1 and undetermined_photo(e.value) == 1


def _failing_once(monkeypatch, frame: int) -> list:
    """BundleProblem.fit raises the camera parameters' GeometryError for `frame` once."""
    fit, calls = BundleProblem.fit, []

    def once(self, *args, **kwargs):
        if not calls:
            calls.append(self.block.photos.ids[frame])
            raise GeometryError(WORDS.format(calls[0]), frame=frame)
        return fit(self, *args, **kwargs)

    monkeypatch.setattr(BundleProblem, "fit", once)
    return calls


def test_the_start_leaves_the_undetermined_photo_out(block, monkeypatch):
    calls = _failing_once(monkeypatch, 11)
    ob = OnlineBundle(block)
    assert calls == [block.photos.ids[11]]
    assert ob._f is not None
    assert [i for i, p in enumerate(ob.m.photo_in) if not p] == [11]


def test_a_removal_leaves_the_undetermined_photo_out(block, monkeypatch):
    ob = OnlineBundle(block)
    r = int(np.flatnonzero(block.image.photo == 0)[0])
    calls = _failing_once(monkeypatch, 7)
    a = ob.remove_image_point(block.photos.ids[0], block.points.ids[block.image.point[r]])
    assert calls == [block.photos.ids[7]]
    assert a.note == f"photo(s) {block.photos.ids[7]} no longer determined: held"
    assert not ob.m.photo_in[7]
