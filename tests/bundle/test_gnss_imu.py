"""GNSS positions and IMU attitudes as observations of the bundle (issue 14): analytic
Jacobians against central differences, redundancy numbers against dense brute force,
shifts, drifts and boresight recovered and tested."""

import numpy as np
import pytest
from gnss_blocks import with_gnss

from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.gnss_imu import attitude
from baarda.pipeline import adjust, assess, prepare
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def base():
    return simulate_block(FlightPlan(strips=3, photos_per_strip=6, pattern=5, relief_m=100.0,
                                     control="corners", seed=3))


def test_attitude_derivatives_by_central_differences():
    rng = np.random.default_rng(1)
    a = rng.uniform(-0.4, 0.4, (5, 3))
    a[:, 2] = rng.uniform(-3, 3, 5)
    b = np.array([0.01, -0.02, 0.015])
    _, da, db = attitude(a, b)
    h = 1e-6
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        num_a = (attitude(a + e, b)[0] - attitude(a - e, b)[0]) / (2 * h)
        num_b = (attitude(a, b + e)[0] - attitude(a, b - e)[0]) / (2 * h)
        assert np.allclose(da[:, :, k], num_a, atol=1e-8)
        assert np.allclose(db[:, :, k], num_b, atol=1e-8)


def test_rows_by_central_differences(base):
    block, truth = base
    b = with_gnss(block, truth, offsets="strip", drift=True, boresight="estimated")
    pb = prepare(b)
    gi = pb.gnss_imu
    assert gi.n == 3 * 3 + 3 * 3 + 3 and gi.m == 6 * len(b.photos)
    rng = np.random.default_rng(2)
    eo = pb.approximations[0].copy()
    ng = pb.system.ng
    g = rng.normal(0, 0.01, ng)
    e, jf, jg = gi.rows(eo, g, ng)
    h = 1e-4  # misclosures of positions of about 1000 m: round-off eps 1e3 / h
    for i in range(len(eo)):
        rows = np.flatnonzero(gi.photos == i)
        for k in range(6):
            p, m = eo.copy(), eo.copy()
            p[i, k] += h
            m[i, k] -= h
            num = -(gi.rows(p, g, ng)[0] - gi.rows(m, g, ng)[0]) / (2 * h)
            assert np.allclose(jf[rows, 0, k], num[rows], atol=1e-7, rtol=1e-7)
    for c in range(gi.first, gi.first + gi.n):
        p, m = g.copy(), g.copy()
        p[c] += h
        m[c] -= h
        num = -(gi.rows(eo, p, ng)[0] - gi.rows(eo, m, ng)[0]) / (2 * h)
        assert np.allclose(jg[:, 0, c], num, atol=1e-7)


def test_redundancy_numbers_equal_dense_brute_force(base):
    """Every observation (image, control, GNSS, IMU) with shifts per strip, drifts and an
    estimated boresight: Qll and the redundancy numbers equal a dense computation."""
    from dense import dense_system

    block, truth = base
    res = adjust(with_gnss(block, truth, offsets="strip", drift=True, boresight="estimated"))
    model = BundleModel(res)
    a, p = dense_system(model)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    qll = np.einsum("ij,jk,ik->i", a, qxx, a)
    assert np.allclose(model.adjusted_cofactor_diag(), qll, rtol=1e-9, atol=1e-12 * qll.max())
    q = assess(res).quality
    r = 1 - p * qll
    for kind in ("image", "control", "gnss", "imu"):
        sel = (model.kind == kind) & q.controlled
        assert sel.any() and np.allclose(q.redundancy_number[sel], r[sel], atol=1e-9)
    assert abs(q.redundancy_number.sum() - res.redundancy) < 1e-6


def test_shifts_drifts_and_boresight_recovered_and_tested(base):
    block, truth = base
    strips = sorted({str(s) for s in block.photos.strip})
    shift = {strips[1]: (0.3, -0.2, 0.4)}
    bs = (0.002, -0.001, 0.003)
    res = adjust(with_gnss(block, truth, offsets="strip", boresight="estimated",
                           shift_by_strip=shift, true_boresight=bs, sigma_m=0.02))
    gi = res.problem.gnss_imu
    g = res.state[2]
    std = np.sqrt(np.diag(res.factor.global_covariance())) * res.sigma0
    for (name, cols), lab in zip(gi.parameter_groups()[:3], strips, strict=True):
        expected = np.asarray(shift.get(lab, (0, 0, 0)))
        assert np.all(np.abs(g[cols] - expected) < 4 * std[cols]), name
    cols = gi.parameter_groups()[-1][1]
    assert np.all(np.abs(g[cols] - bs) < 4 * std[cols])
    tests = {h.name: h for h in assess(res).hypotheses}
    assert tests[f"GNSS shift of strip {strips[1]}"].rejected
    assert tests["IMU boresight"].rejected
    assert not tests[f"GNSS shift of strip {strips[0]}"].rejected


def test_gnss_position_tested_as_a_whole_equals_dense(base):
    """The 3D test of each GNSS position (point_test of its rows in observations.csv):
    T = v' Qvv^-1 v / 3 with the 3 x 3 block of Qvv from a dense computation."""
    from dense import dense_system

    block, truth = base
    res = adjust(with_gnss(block, truth, offsets="strip", boresight="estimated"))
    qc = assess(res)
    model = BundleModel(res)
    a, p = dense_system(model)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    table = qc.table()
    rows = np.flatnonzero(model.kind == "gnss").reshape(-1, 3)
    assert len(rows) == len(block.photos)
    v = model.residuals
    for r in rows:
        qvv = np.diag(1.0 / p[r]) - a[r] @ qxx @ a[r].T
        t = float(v[r] @ np.linalg.solve(qvv, v[r])) / 3
        assert np.allclose(table["point_test"].to_numpy()[r], t, rtol=1e-8)


def test_native_project_round_trip_and_report(tmp_path):
    """`baarda simulate --gnss --gnss-offset --imu` writes gnss.csv, imu.csv and [gnss]; the
    project reads back with the same observations; observations.csv has their rows (photo
    set, point empty) and the report their statistics per strip."""
    import contextlib
    import io

    import pandas as pd

    from baarda.cli import main
    from baarda.io.project import read_project

    proj = tmp_path / "p"
    assert main(["simulate", "-o", str(proj), "--strips", "4", "--photos", "8", "--pattern",
                 "5", "--control", "corners", "--gnss", "0.05", "--gnss-offset", "0.3",
                 "--imu", "0.005", "--relief", "100"]) == 0
    b = read_project(proj)
    assert len(b.gnss) == len(b.imu) == 32 and b.settings.gnss_offsets == "strip"
    assert np.allclose(b.gnss.sigma, 0.05) and np.allclose(np.degrees(b.imu.sigma), 0.005)
    assert main(["adjust", str(proj), "-o", str(tmp_path / "o"), "-q"]) == 0
    obs = pd.read_csv(tmp_path / "o" / "observations.csv", keep_default_na=False)
    g = obs[obs["kind"] == "gnss"]
    assert len(g) == 96 and set(g["component"]) == {"X", "Y", "Z"} and (g["point"] == "").all()
    assert len(obs[obs["kind"] == "imu"]) == 96
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["report", str(tmp_path / "o"), "--text"]) == 0
    text = out.getvalue()
    part = text[text.index("GNSS AND IMU PER STRIP"):text.index("PER PHOTO")]
    assert part.count("\n      ") == 8  # 4 strips, GNSS and IMU


def test_external_reliability_of_gnss_and_imu_equals_dense(base):
    """The effect of each GNSS/IMU component's MDB on the projection centre of its photo
    (external_max): the column of Qxx A' P restricted to that photo, times the MDB."""
    from dense import dense_system

    block, truth = base
    res = adjust(with_gnss(block, truth, offsets="block", boresight="estimated"))
    model = BundleModel(res)
    q = assess(res).quality
    a, p = dense_system(model)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    held = res.problem.held
    assert held is None  # columns of photo i: 6 i .. 6 i + 5
    ids = list(block.photos.ids)
    rows = np.flatnonzero(np.isin(model.kind, ["gnss", "imu"]))
    for r in rows[::7]:
        i = ids.index(model.frame[r])
        col = qxx[6 * i:6 * i + 3] @ a[r] * p[r]
        assert np.isclose(q.external_max[r], np.abs(col * q.mdb[r]).max(), rtol=1e-8)
        assert q.external_point[r] == f"photo {model.frame[r]}"


def test_points_tied_by_a_distance_in_a_block_with_gnss_imu_unknowns():
    """The coordinates of points carried as global unknowns (tied by a distance) are read from
    their own columns, not from those of the GNSS/IMU shifts that follow them."""
    from gnss_blocks import gnss_imu_block_with_a_distance

    from baarda.pipeline import adjust

    block, truth = gnss_imu_block_with_a_distance()
    res = adjust(block)
    pb = res.problem
    assert pb.gnss_imu.n > 0 and len(pb.border_ids) == 2
    xyz = res.xyz
    assert xyz.shape == (len(pb.point_ids), 3)
    border = xyz[pb.remap[pb.border_ids]]
    np.testing.assert_array_equal(
        border, res.state[2][pb.global_layout.columns("points")].reshape(-1, 3))
    # and they are where the simulation put them (5 µm image noise: a few cm at most)
    for k, j in enumerate(pb.border_ids):
        assert np.linalg.norm(border[k] - np.array(truth["points"][pb.block.points.ids[j]])) < 0.2
