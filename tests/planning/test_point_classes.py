"""Gruen's point classes: ray counting with twin rays once, inner and outer rays, control."""

import numpy as np

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.planning.design import ControlLayout, design_block
from baarda.planning.gruen_study import study_plan
from baarda.planning.point_classes import class_name, classify, half_coverage_photos, ray_counts


def _block():
    """3 photos of a strip, stereo models 0-1 and 1-2; points:
    A in model 0-1 only (2 rays); B in both models (photo 1 twice: 3 rays, inner on 1);
    C seen by four photos once each (4 rays, mono); D = B's twin as height control."""
    rows = [  # photo, point, model
        (0, 0, "m1"), (1, 0, "m1"),
        (0, 1, "m1"), (1, 1, "m1"), (1, 1, "m2"), (2, 1, "m2"),
        (0, 2, ""), (1, 2, ""), (2, 2, ""), (3, 2, ""),
        (0, 3, "m1"), (1, 3, "m1"), (1, 3, "m2"), (2, 3, "m2"),
    ]
    ph = np.array([r[0] for r in rows])
    pt = np.array([r[1] for r in rows])
    sigma = np.full((4, 3), np.nan)
    sigma[3, 2] = 0.1
    role = np.array(["tie", "tie", "tie", "control"], dtype=object)
    return Block(Settings(), Cameras(["c"], np.array([150.0]), np.zeros((1, 2))),
                 Photos(["p0", "p1", "p2", "p3"], np.zeros(4, int),
                        np.array(["1"] * 4, dtype=object), np.zeros((4, 6))),
                 ImagePoints(ph, pt, np.zeros((len(rows), 2)), np.full(len(rows), 0.005),
                             np.array([r[2] for r in rows], dtype=object)),
                 GroundPoints(["A", "B", "C", "D"], np.zeros((4, 3)), sigma, role))


def test_rays_count_twins_once():
    rays, inner = ray_counts(_block())
    assert rays.tolist() == [2, 3, 4, 3]
    assert inner.tolist() == [False, False, False, True, True, False, False, False, False,
                              False, False, True, True, False]


def test_class_labels():
    rc = classify(_block())
    assert rc.label.tolist() == ["R2", "R2", "RO3", "RI3", "RI3", "RO3",
                                 "RO4/9", "RO4/9", "RO4/9", "RO4/9",
                                 "CRO3", "CRI3", "CRI3", "CRO3"]
    # only full control counts when asked so
    rc_full = classify(_block(), partial_as_control=False)
    assert rc_full.label[-1] == "RO3"
    lab, comp = rc.component_labels()
    assert lab[:4].tolist() == ["R2", "R2", "R2", "R2"] and comp[:3].tolist() == ["x", "y", "x"]


def test_class_names():
    assert class_name(2, False, True) == "CR2"
    assert class_name(9, True, False) == "RI4/9"
    assert class_name(12, False, True) == "CRO4/9"
    assert class_name(1, False, False) == "R1"


def test_gruen_43_block_classes():
    """43 block: 4 two-ray points at the block corners (outside the outer strip axes),
    4 three-ray points on the edges, the 8 strip-end photos with half coverage."""
    blk = design_block(study_plan(4, 3), ControlLayout(spacing=1.0))
    rc = classify(blk)
    rays = blk.rays()
    r2 = [blk.points.ids[j] for j in np.flatnonzero(np.bincount(
        blk.image.point[rc.label == "R2"], minlength=len(rays)))]
    assert len(r2) == 4
    # 4 three-ray points, each 2 outer rays and a twin (2 inner rays) on the middle photo
    assert np.sum(rc.label == "RO3") == 8 and np.sum(rc.label == "RI3") == 8
    half = half_coverage_photos(blk)
    ids = np.asarray(blk.photos.ids)
    assert sorted(ids[half]) == sorted(i for i in ids if i.endswith("001") or i.endswith("004"))
    # every strip-end photo measures 6 points, the others 9 distinct points
    distinct = [len(set(blk.image.point[blk.image.photo == k])) for k in range(len(ids))]
    assert sorted(set(np.array(distinct)[half])) == [6]
    assert sorted(set(np.array(distinct)[~half])) == [9]
