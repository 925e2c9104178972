"""The chain's bundle snooping: rejections removed with what cannot be told from them."""

import sys
from pathlib import Path

import numpy as np

from baarda.screening.separable import snoop_separable

sys.path.insert(0, str(Path(__file__).parents[2] / "examples" / "lugnani"))
from lugnani_block import build  # noqa: E402


def rows_of(block, point, photo):
    im = block.image
    return int(np.flatnonzero((im.photo == block.photo_index[photo])
                              & (im.point == block.point_index[point]))[0])


def test_separable_error_removes_its_image_point_only():
    """A y error on a four-ray point (two strips): located, that image point alone."""
    block, _ = build(1, blunders=False)
    block.image.xy_mm[rows_of(block, "616", "7"), 1] -= 0.050
    qc, final, log = snoop_separable(block)
    assert {(e.photo, e.point) for e in log.removed("image")} == {("7", "616")}
    assert len(final.image) == len(block.image) - 1
    assert not np.any(~qc.quality.active)  # the last pass rejects nothing


def test_two_ray_parallax_removes_both_rays():
    """A y-parallax of a two-ray point: the two y-tests correlate -1, both rays go."""
    block, _ = build(1, blunders=False)
    block.image.xy_mm[rows_of(block, "635", "12"), 1] += 0.040
    _, _, log = snoop_separable(block)
    removed = {(e.photo, e.point) for e in log.removed("image")}
    assert removed == {("11", "635"), ("12", "635")}
    partner = [e for e in log.removed("image") if not e.statistic]  # removed with it
    assert len(partner) == 1


def test_clean_block_keeps_everything():
    block, _ = build(1, blunders=False)
    qc, final, log = snoop_separable(block)
    assert not log.entries and len(final.image) == len(block.image)
