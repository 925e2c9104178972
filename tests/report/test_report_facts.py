"""What a client expects to read about a block (issue 42): flying height, covered area,
overlap per ground cell, orientation spread, GCPs' images and reprojection errors."""

import numpy as np
import pytest

from baarda.io.result_folder import read_results
from baarda.report.coverage import coverage
from baarda.report.facts import gcp_images, orientation_spread, project_facts


def square(x, y, side):
    return np.array([[x, y], [x + side, y], [x + side, y + side], [x, y + side]], float)


def test_coverage_counts_photos_per_ground_cell():
    # two 1000 m squares overlapping by 600 m along X: 1,400,000 m^2, 600,000 of it twice
    cov = coverage({"a": square(0, 0, 1000), "b": square(400, 0, 1000)}, cells=280)
    assert cov.area_m2 == pytest.approx(1.4e6, rel=0.01)
    assert cov.share(2) == pytest.approx(0.6 / 1.4, abs=0.01)
    assert cov.share(3) == 0.0 and cov.counts.max() == 2
    # a hole between two photos shows (photos per point would not)
    gap = coverage({"a": square(0, 0, 1000), "b": square(1500, 0, 1000)}, cells=250)
    assert gap.area_m2 == pytest.approx(2e6, rel=0.02)
    assert (gap.counts[:, gap.counts.shape[1] // 2] == 0).all()


def test_facts_of_a_simulated_block(report_case):
    res = read_results(report_case.out)
    facts = dict(project_facts(res))
    # 1:10,000 with c = 153 mm: 1,530 m above the mean terrain (relief 30 m)
    h = float(facts["flying height above ground"].split(" m")[0].replace(",", ""))
    assert 1490 <= h <= 1570
    assert facts["photos"] == "15 in 3 strip(s), 1 camera(s)"
    assert "covered area" in facts and "km²" in facts["covered area"]
    assert facts["processing time"].endswith("s (adjustment and tests)")
    # orientation spread: the mean and the spread of sigma_X0 over the photos
    s = res.photos["sigma_X0"].to_numpy(float)
    assert orientation_spread(res).startswith(f"X0 {np.mean(s):.3g} ± {np.std(s):.2g} m")
    # GCPs: the photos each is measured on, counted from the observations
    g = gcp_images(res).set_index("point")
    o = res.obs[res.obs["kind"] == "image"]
    for p, row in g.iterrows():
        assert row["images"] == o.loc[o["point"].astype(str) == p, "photo"].nunique()
    assert "GCPs" in facts and f"{len(g)} measured on" in facts["GCPs"]
