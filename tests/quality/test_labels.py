"""The snooping log's words for many components at once (`labels`, joined by pyarrow for the
partners of millions of rows: issue 40) are those of `label`, component by component: image
rows with their photo, control points, GNSS and IMU rows (a photo, no point), distances
(a point pair, no photo) and model coordinates (a model, not a photo)."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from baarda.block.photo_block import Distances
from baarda.bundle.bundle_model import BundleModel
from baarda.pipeline import adjust
from baarda.quality.iterative import label, labels
from baarda.simulate.aerial import FlightPlan, simulate_block


def same_words(model) -> list[str]:
    rows = np.arange(len(model.kind))[::-1]  # any order
    words = labels(model, rows)
    assert words == [label(model, i) for i in rows]
    return words


def test_labels_of_every_kind_are_label_row_by_row():
    block, truth = simulate_block(FlightPlan(strips=2, photos_per_strip=6, seed=5,
                                             gnss_sigma_m=0.05, gnss_offset_m=0.3,
                                             imu_sigma_deg=0.005))
    pts = block.points
    tie = np.flatnonzero(pts.role == "tie")
    a, b = tie[1], tie[-2]
    xa, xb = (np.array(truth["points"][pts.ids[j]]) for j in (a, b))
    dist = Distances(["bar"], np.array([a]), np.array([b]),
                     np.array([float(np.linalg.norm(xa - xb))]), np.array([0.01]))
    model = BundleModel(adjust(replace(block, distances=dist)))
    words = same_words(model)
    kinds = set(np.asarray(model.kind, str))
    assert {"image", "control", "gnss", "imu"} <= kinds and len(kinds) >= 5, kinds
    assert any(w.startswith("gnss photo ") and " point " not in w for w in words)
    assert any(w.startswith("image photo ") and " point " in w for w in words)
    assert labels(model, np.zeros(0, np.int64)) == []


def test_labels_of_parts_that_are_not_text_are_made_row_by_row():
    """A frame that is None or a number is not joined by pyarrow: the words are then made
    row by row, as label() makes them."""
    stand_in = SimpleNamespace(  # what labels() reads of a model
        kind=np.array(["image", "gnss", "control", "image"], dtype=object),
        frame=np.array([None, "p1", "", 17], dtype=object),
        point=np.array(["a", "", "c", "d"], dtype=object),
        component=np.array(["x", "X", "Z", "y"], dtype=object))
    assert same_words(stand_in) == ["image photo 17 point d y", "control point c Z",
                                    "gnss photo p1 X", "image point a x"]
