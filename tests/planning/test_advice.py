"""Advice names the weak places of a plan; the remedies recomputed improve them."""

import numpy as np

from baarda.planning.advice import advise, what_if
from baarda.planning.design import ControlLayout, design_block
from baarda.planning.design_reliability import analyse_design
from baarda.planning.gruen_study import study_plan
from baarda.simulate.aerial import FlightPlan


def test_gruen_43_block_advice():
    flight = study_plan(4, 3)
    plan = analyse_design(design_block(flight, ControlLayout(spacing=1.5)))
    adv = {a.topic: a for a in advise(plan, flight)}
    half = adv["perimeter photos with part coverage"]
    assert sorted(half.where) == sorted(p for p in plan.block.photos.ids
                                        if p.endswith(("001", "004")))
    assert len(adv["2-ray points"].where) == 4
    assert "cross strips" in adv["2-ray points"].remedy  # 60 % side overlap already
    assert len(adv["uncontrolled observations"].where) == 4  # R2(x) = 0
    assert "twin control" in adv["single control"].remedy
    assert "monocomparator mode" not in adv
    weak = adv["weakly controlled observations"]
    assert "RO3(x)" in weak.finding and "R2(y)" in weak.finding


def test_mono_low_sidelap_plan_and_what_if():
    flight = FlightPlan(strips=3, photos_per_strip=4, side_overlap=0.3, pattern=3)
    layout = ControlLayout(spacing=1.0, spacing_y=0.5)
    plan = analyse_design(design_block(flight, layout))
    adv = {a.topic: a for a in advise(plan, flight)}
    assert "monocomparator mode" in adv
    assert adv["2-ray points"].remedy.startswith("fly 60 % side overlap")
    wi = what_if(flight, layout).set_index("variant")
    assert list(wi.index) == ["as planned", "twin control", "5x5 points per photo",
                              "60 % side overlap", "stereo mode"]
    base = wi.loc["as planned"]
    for v in ("twin control", "stereo mode", "60 % side overlap"):
        assert wi.loc[v, "mean_sqrt_qvv"] > base["mean_sqrt_qvv"]
    assert wi.loc["60 % side overlap", "photos"] > base["photos"]  # same area, more strips
    assert np.isfinite(wi["max_mdb_um"]).all()
