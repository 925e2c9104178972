"""Photo outlines: ground corners must project back onto the image corners."""

import numpy as np
import pandas as pd
import pytest

from baarda.block.rotation import rad_to_angle
from baarda.bundle.collinearity import project
from baarda.report.footprint import footprints, image_extent


@pytest.mark.parametrize("unit", ["gon", "deg"])
def test_outline_corners_project_to_image_corners(unit):
    eo = np.array([[1000.0, 2000.0, 1600.0, 0.0, 0.0, 0.0],
                   [1900.0, 2050.0, 1580.0, 0.03, -0.02, 1.2]])
    ang = rad_to_angle(eo[:, 3:], unit)
    photos = pd.DataFrame({"photo": ["p1", "p2"], "camera": ["c", "c"], "X0": eo[:, 0],
                           "Y0": eo[:, 1], "Z0": eo[:, 2], "omega": ang[:, 0],
                           "phi": ang[:, 1], "kappa": ang[:, 2]})
    cams = {"c": {"focal_mm": 153.0, "x0_mm": 0.1, "y0_mm": -0.2}}
    obs = pd.DataFrame({"kind": ["image"] * 3, "photo": ["p1", "p2", "p1"],
                        "x_mm": [95.1, -20.0, 3.0], "y_mm": [10.0, -80.2, 5.0]})
    ext = image_extent(obs, photos, cams)
    assert ext["c"] == pytest.approx((95.0, 80.0))
    out = footprints(photos, cams, unit, ext, ground_z=100.0)
    assert set(out) == {"p1", "p2"}
    # the vertical photo: corner (+x, -y) at X0 + 95 mm * H / c, Y0 - 80 mm * H / c
    scale = (1600.0 - 100.0) / 153.0  # m per mm of image
    np.testing.assert_allclose(out["p1"][1], [1000.0 + 95.0 * scale, 2000.0 - 80.0 * scale])
    corners = np.array([[-95, -80], [95, -80], [95, 80], [-95, 80]], float) + [0.1, -0.2]
    for i, p in enumerate(("p1", "p2")):
        xyz = np.column_stack([out[p], np.full(4, 100.0)])
        xy = project(np.repeat(eo[i:i + 1], 4, axis=0), xyz, np.full(4, 153.0),
                     np.array([0.1, -0.2]))
        np.testing.assert_allclose(xy, corners, atol=1e-9)


def test_unknown_unit_or_camera_gives_no_outlines():
    photos = pd.DataFrame({"photo": ["p"], "camera": ["c"], "X0": [0.0], "Y0": [0.0],
                           "Z0": [1000.0], "omega": [0.0], "phi": [0.0], "kappa": [0.0]})
    assert footprints(photos, {"c": {"focal_mm": 100.0}}, None, {"c": (1, 1)}, 0.0) == {}
    assert footprints(photos, {}, "gon", {}, 0.0) == {}
