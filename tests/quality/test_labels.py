"""The snooping log's words for many components at once (`labels`, joined by pyarrow for the
partners of millions of rows: issue 40) are those of `label`, component by component: image
rows with their photo, control points, GNSS and IMU rows (a photo, no point), distances
(a point pair, no photo) and model coordinates (a model, not a photo)."""

from types import SimpleNamespace

import numpy as np
from gnss_blocks import gnss_imu_block_with_a_distance

from baarda.bundle.bundle_model import BundleModel
from baarda.pipeline import adjust
from baarda.quality.iterative import label, labels


def same_words(model) -> list[str]:
    rows = np.arange(len(model.kind))[::-1]  # any order
    words = labels(model, rows)
    assert words == [label(model, i) for i in rows]
    return words


def test_labels_of_every_kind_are_label_row_by_row():
    model = BundleModel(adjust(gnss_imu_block_with_a_distance()[0]))
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
