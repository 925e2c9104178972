"""The on-line session: Kratky's Table 2 situation in a simulated strip, remeasuring, the
strip growing model by model, and the API's refusals."""

import numpy as np
import pytest

from baarda.errors import GeometryError
from baarda.relative.session import OnlineSession
from baarda.simulate.online_strip import simulate_strip


def _with_blunder(meas, point, dy):
    meas = dict(meas)
    x1, y1, x2, y2 = meas[point]
    meas[point] = (x1, y1, x2, y2 + dy)
    return meas


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("point", ["31", "33"])
def test_flags_the_blunder_not_the_largest_parallax(seed, point):
    """Nine points, three tie points (Figure 4(d)): 100 µm in y'' at a corner tie point
    shows its largest y-parallax at the neighbouring point (critical transfer 0.35 > 0.27),
    yet the largest standardized residual, and so the point to remeasure, is the right one."""
    st = simulate_strip(3, "9", sigma_x=5.0, seed=seed, attitude=0.02)
    s = OnlineSession(152.0, sigma_x=5.0)
    s.add_model(*st.models[0])
    s.accept()
    name, meas = st.models[1]
    qc = s.add_model(name, _with_blunder(meas, point, 0.100))
    o = qc.orientation
    largest = o.points[int(np.argmax(np.abs(o.y_parallax)))]
    assert largest != point  # the parallaxes point at the wrong place ...
    assert qc.remeasure == point  # ... the standardized residuals do not
    i = qc.remeasure_index
    assert o.obs_component[i] == "y"
    assert any(t.source == i for t in qc.transfers)  # a critical transfer from it
    # remeasured correctly: the point is no longer significant
    qc2 = s.remeasure(point, *meas[point])
    assert qc2.remeasure_index != i
    j = [k for k in range(len(o.residuals)) if o.points[o.obs_point[k]] == point
         and o.obs_component[k] == "y"][0]
    assert abs(qc2.significance[j]) < qc2.critical_value


def test_strip_grows_as_models_are_accepted():
    st = simulate_strip(3, "13", sigma_x=3.0, seed=4)
    s = OnlineSession(152.0, sigma_x=3.0, qtie=5.0)
    sizes = []
    for name, meas in st.models:
        qc = s.add_model(name, meas)
        assert len(qc.orientation.setup.tie_index) == (0 if not s.accepted else 5)
        assert s.coordinates.keys() == {p for m in s.accepted for p in m.orientation.points}
        s.accept()
        sizes.append(len(s.coordinates))
    assert sizes == [13, 21, 29]
    # scale carried through: the strip coordinates agree with the truth (photo-scale mm)
    scale = st.base / s.accepted[0].orientation.base
    err = max(np.max(np.abs(s.coordinates[p] * scale - st.points[p])) for p in st.points)
    assert err < 0.1  # mm at photo scale, after three models with 3 µm noise


def test_drop_and_explicit_ties():
    st = simulate_strip(2, "9", sigma_x=5.0, seed=1)
    s = OnlineSession(152.0, sigma_x=5.0)
    s.add_model(*st.models[0])
    s.accept()
    name, meas = st.models[1]
    qc = s.add_model(name, meas, ties=["31", "33"])
    assert [qc.orientation.points[i] for i in qc.orientation.setup.tie_index] == ["31", "33"]
    qc = s.drop("52")
    assert "52" not in qc.orientation.points
    assert qc.quality.redundancy == 8 + 2 - 6


def test_refusals():
    st = simulate_strip(2, "6", sigma_x=5.0, seed=2)
    s = OnlineSession(152.0)
    with pytest.raises(ValueError, match="no model is on the instrument"):
        s.remeasure("1", 0, 0, 0, 0)
    s.add_model(*st.models[0])
    with pytest.raises(ValueError, match="still on the instrument"):
        s.add_model(*st.models[1])
    with pytest.raises(ValueError, match="four finite numbers"):
        s.remeasure("11", 1.0, 2.0, np.nan, 3.0)
    s.accept()
    name, meas = st.models[1]
    with pytest.raises(ValueError, match="tie point"):
        s.add_model(name, meas, ties=["99"])
    few = {p: meas[p] for p in list(meas)[:2]}
    with pytest.raises(GeometryError, match="no redundancy"):
        s.add_model(name, few)
    assert s.current is None  # a failed model does not stay on the instrument
    no_ties = {p: v for p, v in meas.items() if not p.startswith("2")}
    with pytest.raises(GeometryError, match="at least one tie point"):
        s.add_model(name, no_ties)


def test_tie_weight_calibration():
    """Simulated strips, no blunders: with Kratky's q_tie = 1 the w of x'' at tie points
    spread about twice as wide as N(0, 1) (the tie coordinates carry the preceding model's
    x-parallax error, seen doubled); q_tie = 5 makes them standard."""
    sd = {}
    for qtie in (1.0, 5.0):
        wx, wy = [], []
        for seed in range(25):
            st = simulate_strip(3, "9", sigma_x=5.0, seed=100 + seed, attitude=0.02)
            s = OnlineSession(152.0, sigma_x=5.0, qtie=qtie)
            for k, (name, meas) in enumerate(st.models):
                qc = s.add_model(name, meas)
                s.accept()
                if k:
                    comp = qc.orientation.obs_component
                    wx += list(qc.quality.w[comp == "x"])
                    wy += list(qc.quality.w[comp == "y"])
        sd[qtie] = (np.std(wx), np.std(wy))
    assert sd[1.0][0] > 1.6
    assert 0.8 < sd[5.0][0] < 1.25 and 0.8 < sd[5.0][1] < 1.25


def test_degenerate_geometry_is_refused():
    """All points in one column across the model: phi and beta_z are not separable."""
    s = OnlineSession(152.0)
    ys = [-90.0, -45.0, 0.0, 20.0, 45.0, 90.0]
    with pytest.raises(GeometryError, match="not determined"):
        s.add_model("m", {str(i): (0.0, y, -92.0, y) for i, y in enumerate(ys)})
    assert s.current is None
