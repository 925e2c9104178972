"""The Lugnani & Mitishita experiment (examples/lugnani): the result is kept here."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parents[2] / "examples" / "lugnani"))
import experiment  # noqa: E402
from lugnani_block import CONTROL, EMPTY, IMAGE_BLUNDERS, ROWS, build  # noqa: E402


@pytest.fixture(scope="module")
def results():
    return experiment.run(1)


def test_block_is_the_papers():
    """3 strips x 4 photos, 46 ground points (8 control), 134 image points."""
    block, truth = build(1)
    assert len(block.photos) == 12 and len(set(block.photos.strip)) == 3
    assert len(block.points) == 46 and len(block.image) == 134
    assert int(np.sum(block.points.role == "control")) == len(CONTROL) == 8
    assert len(ROWS) * 7 - len(EMPTY) == 46
    assert len(IMAGE_BLUNDERS) == 8 and len(truth["blunders"]) == 10
    # the blunders are the paper's Table 1: e.g. 669 on photo 2, x + 24.000 mm
    clean, _ = build(1, blunders=False)
    diff = block.image.xy_mm - clean.image.xy_mm
    assert np.sum(np.abs(diff) > 0) == 12  # eight image points, twelve coordinates
    assert np.max(np.abs(diff)) == pytest.approx(24.0)
    dz = block.points.xyz - clean.points.xyz
    assert sorted(np.round(dz[np.isfinite(dz) & (dz != 0)], 6).tolist()) == [-3, -2, -1]


def test_screening_then_snooping_finds_all_ten(results):
    oc, sc = results["screening+snooping"]
    assert sc.missed == [] and len(sc.found) == 10
    assert len(sc.improper_points) <= 1  # the paper removed two good points
    # the adjusted points agree with the truth at the level of the noise
    _, ref = results["same obs, no errors"]
    np.testing.assert_allclose(sc.rms, ref.rms, rtol=1e-6)  # no blunder effect is left
    assert np.all(sc.normalised < 1.5)  # |adjusted - true| / sigma as without blunders
    noise = results["noise only"][1]
    assert np.all(sc.rms < 2.0 * noise.rms) and np.all(sc.max < 0.5)
    stages = {e.stage for e in oc.screening.log.removed("image")}
    assert {1, 4} <= stages  # the pairs catch the gross ones, the bundle the rest


def test_residual_analysis_and_plain_snooping_do_worse(results):
    ra = results["residual analysis"][1]
    assert len(ra.found) < 10 and len(ra.improper_points) >= 2
    assert ra.max[2] > 2.0  # metres off, as the paper's Table 3
    ds = results["data snooping"][1]
    assert len(ds.found) < 10
    ch = results["screening+snooping"][1]
    assert ds.rms[2] > 1.2 * ch.rms[2]


def test_table_prints_every_strategy(results):
    text = experiment.table(results)
    for name in results:
        assert name[:19] in text
    assert "blunders found (of 10)" in text and "RMS d/sigma" in text
