"""Kratky and El-Hakim (1983) as tests: the adjustment itself, redundancy numbers, Table 1
(a 100 µm error changes its residual by exactly -r_i x 100 µm), Qvv P against re-orientation."""

import numpy as np
import pytest

from baarda.relative.orientation import orient
from baarda.relative.point_pattern import design, standard_pattern
from baarda.relative.session import OnlineSession
from baarda.simulate.online_strip import simulate_strip


def test_noise_free_strip_recovers_the_truth():
    """Scale transfer model by model: poses and coordinates of the true strip to 1e-9 mm."""
    st = simulate_strip(4, "9", sigma_x=0.0, relief=6.0, attitude=0.02, seed=5)
    s = OnlineSession(152.0, sigma_x=5.0, base=st.base)
    for name, meas in st.models:
        s.add_model(name, meas)
        s.accept()
    for k, m in enumerate(s.accepted, 1):
        np.testing.assert_allclose(m.orientation.right.centre, st.centres[k], atol=1e-9)
        np.testing.assert_allclose(m.orientation.right.rotation, st.rotations[k], atol=1e-12)
        np.testing.assert_allclose(m.orientation.residuals, 0.0, atol=1e-6)
    assert set(s.coordinates) == set(st.points)
    for p, xyz in s.coordinates.items():
        np.testing.assert_allclose(xyz, st.points[p], atol=1e-9)
    assert [len(m.orientation.setup.unknowns) for m in s.accepted] == [5, 6, 6, 6]


def test_six_point_corners_show_8_percent():
    """'the residuals at all corners of the six-point pattern (a) will show only 8 percent'."""
    d = design(standard_pattern("6"))
    r = d.redundancy_number
    np.testing.assert_allclose(r[[0, 2, 3, 5]], 1 / 12, atol=1e-9)  # 0.083
    np.testing.assert_allclose(r[[1, 4]], 1 / 3, atol=1e-9)
    # Figure 3: the listed Qvv are twice Qvv P (P_yy = 0.5 with q_yy = 2 q_xx)
    qvv = d.qvvp * 2.0
    np.testing.assert_allclose(np.diag(qvv)[[0, 1]], [1 / 6, 2 / 3], atol=1e-9)


@pytest.mark.parametrize("spec", ["6", "9", "10", "12", "15", "13", "3x4+corners",
                                  "2x3+edges"])
def test_r0_without_scale_transfer(spec):
    d = design(standard_pattern(spec))
    n = len(d.points)
    assert d.r0 == pytest.approx((n - 5) / n, abs=1e-9)


@pytest.mark.parametrize("spec", ["6", "9", "4x3", "5x3"])
def test_r0_with_three_tie_points(spec):
    d = design(standard_pattern(spec, 3))
    n = len(d.points)
    assert d.r0 == pytest.approx((n - 3) / (n + 3), abs=1e-9)


@pytest.mark.parametrize("spec", ["10", "13", "15"])
def test_r0_with_five_tie_points(spec):
    d = design(standard_pattern(spec, 5))
    n = len(d.points)
    assert d.r0 == pytest.approx((n - 1) / (n + 5), abs=1e-9)


def _strip_model(pattern, k, seed=2, noise=5.0, **kw):
    """Model k of a simulated strip: (qc, orientation, measurements (n, 4))."""
    st = simulate_strip(k + 1, pattern, sigma_x=noise, relief=6.0, seed=seed, **kw)
    s = OnlineSession(152.0, sigma_x=5.0)
    for name, meas in st.models[:k]:
        s.add_model(name, meas)
        s.accept()
    qc = s.add_model(*st.models[k])
    o = qc.orientation
    arr = np.array([st.models[k][1][p] for p in o.points])
    return qc, o, arr


def _shifted(o, arr, i, size):
    """Orient again with `size` µm added to observation i (x'' or y'' of its point)."""
    right = arr[:, 2:].copy()
    right[o.obs_point[i], 1 if o.obs_component[i] == "y" else 0] += size / 1000.0
    return orient(o.name, o.points, arr[:, :2], right, o.setup, o.params)


@pytest.mark.parametrize("pattern,k", [("6", 0), ("9", 0), ("6", 1), ("9", 1), ("13", 1)])
def test_table1_error_changes_its_residual_by_minus_r(pattern, k):
    """Table 1: 100 µm added to each image coordinate in turn, the model oriented again
    (non-linear Gauss-Newton, noisy measurements, relief, photos in the normal position as in
    the paper's parallax-mode model): its own residual moves by -r_i x 100 µm to 0.1 µm and
    the whole residual vector by -Qvv P e_i x 100 µm."""
    qc, o, arr = _strip_model(pattern, k, attitude=0.0, position=0.0)
    r = qc.quality.redundancy_number
    assert np.min(r) > 0.05
    for i in range(len(o.residuals)):
        dv = _shifted(o, arr, i, 100.0).residuals - o.residuals
        assert dv[i] == pytest.approx(-r[i] * 100.0, abs=0.1)  # µm
        np.testing.assert_allclose(dv, -qc.qvvp[:, i] * 100.0, atol=0.1)


@pytest.mark.parametrize("pattern,k,noise,tol", [("9", 0, 0.0, 1e-7), ("9", 2, 0.0, 1e-7),
                                                 ("13", 1, 0.0, 1e-7), ("13", 1, 5.0, 1e-4)])
def test_qvvp_brute_force_in_a_rotated_strip(pattern, k, noise, tol):
    """With rotations and a wandering base the model's observations are y'' in coplanarity
    and x'' in the XZ collinearity (A diagonal, Kratky eq. 4): an error delta put into them
    and the model oriented again moves the residuals by -Qvv P delta (to 1e-7; with noisy
    measurements to 1e-4, the second-order term v d2v/dg2 that Gauss-Newton leaves out); real
    image errors do so up to the neglected cross partials dF_p/dx'', dF_L/dy'' (a few %)."""
    qc, o, arr = _strip_model(pattern, k, noise=noise, attitude=0.02)
    k_obs = len(o.residuals)
    brute = np.empty((k_obs, k_obs))
    real = np.empty((k_obs, k_obs))
    for i in range(k_obs):
        delta = np.zeros(k_obs)
        delta[i] = 0.01
        o2 = orient(o.name, o.points, arr[:, :2], arr[:, 2:], o.setup, o.params, delta=delta)
        brute[:, i] = -(o2.residuals - o.residuals) / 0.01
        real[:, i] = -(_shifted(o, arr, i, 0.01).residuals - o.residuals) / 0.01
    np.testing.assert_allclose(brute, qc.qvvp, atol=tol)
    np.testing.assert_allclose(real, qc.qvvp, atol=0.05)


def test_qvvp_against_dense_formula_and_figure5():
    """Qvv P from the quality layer equals I - A (A^T P A)^-1 A^T P computed here; for the
    nine-point pattern with three tie points (Figure 5) an x error at tie point 2 does not reach
    any y residual, and x errors at the side tie points shift critically to the centre."""
    d = design(standard_pattern("9", 3))
    a = d.orientation.design
    p = np.diag(1.0 / d.orientation.sigma**2)
    brute = np.eye(len(a)) - a @ np.linalg.inv(a.T @ p @ a) @ a.T @ p
    np.testing.assert_allclose(d.qvvp, brute, atol=1e-12)
    labels = [d.label(i) for i in range(d.n)]
    col = labels.index("2x")
    ys = [i for i, s in enumerate(labels) if s.endswith("y")]
    np.testing.assert_allclose(d.qvvp[ys, col], 0.0, atol=1e-12)
    pairs = {(d.label(t.source), d.label(t.target)) for t in d.transfers}
    assert {("1x", "2x"), ("3x", "2x")} <= pairs


def test_scale_transfer_strengthens_the_six_point_pattern():
    """Figure 4(a) vs 2(a): the y redundancy numbers increase with three tie points, and the
    design values are close to Kratky's Table 2 (real measurements, pattern (a) of Figure 4)."""
    ro = design(standard_pattern("6")).redundancy_number
    sc = design(standard_pattern("6", 3)).redundancy_number[:6]
    assert np.all(sc >= ro - 1e-12) and np.sum(sc) > np.sum(ro) + 0.5
    table2 = np.array([0.09, 0.77, 0.07, 0.32, 0.40, 0.23])
    assert np.max(np.abs(sc - table2)) < 0.06
