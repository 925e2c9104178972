"""Group statistics (VAN): Salsig's Figure 1 and a small set checked by hand."""

import numpy as np
import pandas as pd
import pytest
from salsig import (
    FIG1_AVERAGE,
    FIG1_CONTROL,
    FIG1_MAXIMUM,
    FIG1_MINIMUM,
    FIG1_NUMBER,
    FIG1_RMS,
)

from baarda.io.residual_listings import read_residuals
from baarda.report.stats import (
    describe,
    group_statistics,
    per_photo,
    per_strip,
    vector_statistics,
    worst,
)


def test_salsig_figure1_control_summary(tmp_path):
    f = tmp_path / "control.csv"
    f.write_text(FIG1_CONTROL)
    rs = read_residuals([f])
    g = {s.name: s for s in group_statistics(rs.obs, rs.units)}
    for k, c in enumerate("XYZ"):
        s = g[f"control {c}"]
        assert s.count == FIG1_NUMBER[k]
        assert round(s.rms, 3) == FIG1_RMS[k]
        assert round(s.mean, 3) + 0.0 == FIG1_AVERAGE[k]
        assert s.minimum == FIG1_MINIMUM[k] and s.maximum == FIG1_MAXIMUM[k]
        assert s.unit == "m"
    assert g["control X"].min_at == "point 304 X" and g["control X"].max_at == "point 301 X"
    assert g["control Y"].max_at == "point 312 Y"
    assert g["control Z"].min_at == "point 307 Z" and g["control Z"].max_at == "point 117 Z"
    xy = g["control X+Y"]
    assert xy.count == 26 and xy.maximum == 0.103 and xy.minimum == -0.052


def small_set() -> pd.DataFrame:
    """Two photos in two strips, three image points, one rejected y, two control points."""
    rows = [  # kind, photo, point, component, residual, rejected
        ("image", "a1", "p1", "x", 3.0, False), ("image", "a1", "p1", "y", -4.0, False),
        ("image", "a1", "p2", "x", -1.0, False), ("image", "a1", "p2", "y", 2.0, False),
        ("image", "b1", "p1", "x", 2.0, False), ("image", "b1", "p1", "y", 40.0, True),
        ("control", "", "c1", "X", 0.02, False), ("control", "", "c1", "Y", -0.01, False),
        ("control", "", "c1", "Z", 0.05, False), ("control", "", "c2", "Z", -0.03, False),
    ]
    df = pd.DataFrame(rows, columns=["kind", "photo", "point", "component", "residual",
                                     "rejected"])
    df["flagged"] = False
    df["w"] = np.nan
    return df


def test_groups_by_hand():
    g = {s.name: s for s in group_statistics(small_set())}
    # image x: 3, -1, 2 -> mean 4/3, RMS sqrt(14/3)
    x = g["image x"]
    assert x.count == 3 and x.rejected == 0
    assert x.mean == pytest.approx(4 / 3) and x.rms == pytest.approx(np.sqrt(14 / 3))
    assert (x.minimum, x.min_at) == (-1.0, "photo a1 point p2 x")
    assert (x.maximum, x.max_at) == (3.0, "photo a1 point p1 x")
    # image y: -4, 2 (40 rejected, left out) -> mean -1, RMS sqrt(10)
    y = g["image y"]
    assert y.count == 2 and y.rejected == 1
    assert y.mean == pytest.approx(-1.0) and y.rms == pytest.approx(np.sqrt(10.0))
    xy = g["image x+y"]
    assert xy.count == 5 and xy.mean == pytest.approx(2 / 5)
    assert xy.rms == pytest.approx(np.sqrt(34 / 5))
    assert (xy.minimum, xy.maximum) == (-4.0, 3.0)
    z = g["control Z"]
    assert z.count == 2 and z.mean == pytest.approx(0.01)
    assert z.rms == pytest.approx(np.sqrt((0.05**2 + 0.03**2) / 2))
    assert g["control X+Y"].count == 2 and g["control X+Y"].rms == pytest.approx(
        np.sqrt((0.02**2 + 0.01**2) / 2))


def test_per_photo_and_strip_by_hand():
    df = small_set()
    t = per_photo(df).set_index("photo")
    assert t.loc["a1", "points"] == 2 and t.loc["b1", "points"] == 1
    assert t.loc["a1", "mean_x"] == pytest.approx(1.0)
    assert t.loc["a1", "rms_y"] == pytest.approx(np.sqrt(10.0))
    assert t.loc["a1", "rms_xy"] == pytest.approx(np.sqrt(30 / 4))
    assert t.loc["a1", "max_abs"] == 4.0 and t.loc["a1", "max_at"] == "photo a1 point p1 y"
    assert t.loc["b1", "rejected"] == 1 and np.isnan(t.loc["b1", "rms_y"])
    assert t.loc["b1", "rms_xy"] == pytest.approx(2.0)
    s = per_strip(df, {"a1": "1", "b1": "1"}).set_index("strip")
    assert s.loc["1", "rms_x"] == pytest.approx(np.sqrt(14 / 3))
    assert s.loc["1", "rejected"] == 1


def test_vector_statistics_and_worst():
    df = small_set()
    v = vector_statistics(df)
    # image points with both components active: a1/p1 (3, -4) -> 5, a1/p2 (-1, 2) -> sqrt 5
    assert v.count == 2 and v.maximum == pytest.approx(5.0)
    assert v.max_at == "photo a1 point p1" and v.rms == pytest.approx(np.sqrt(15.0))
    w = worst(df, 2)
    assert list(w.loc[w["kind"] == "image", "residual"]) == [-4.0, 3.0]
    assert list(w.loc[w["kind"] == "control", "residual"]) == [0.05, -0.03]


def test_describe_empty():
    s = describe(np.array([]), np.array([]), "none", "µm")
    assert s.count == 0 and np.isnan(s.rms)
