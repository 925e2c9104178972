"""Stage 3: control checked by a 7-parameter similarity of each strip, with planted errors."""

import numpy as np
import pytest

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.block.rotation import rotation_matrix
from baarda.screening.control import (
    check_strip,
    closed_form,
    s_transform,
    similarity,
    strip_variances,
)
from baarda.screening.strips import Strip

PARAMS = np.array([4000.0, 2500.0, 950.0, 1.002, 0.01, -0.02, 0.3])


def test_similarity_jacobian_and_closed_form():
    rng = np.random.default_rng(0)
    d = rng.uniform(-1500, 1500, (6, 3))
    f, jac = similarity(PARAMS, d)
    for k in range(7):
        h = np.zeros(7)
        h[k] = 1e-6
        num = (similarity(PARAMS + h, d)[0] - similarity(PARAMS - h, d)[0]) / 2e-6
        np.testing.assert_allclose(jac[:, :, k], num, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(closed_form(d, f), PARAMS, rtol=1e-10, atol=1e-10)


def test_s_transform_removes_the_similarity_directions():
    rng = np.random.default_rng(1)
    xyz = rng.uniform(-1000, 1000, (5, 3))
    b = rng.normal(size=(15, 15))
    q, sd = s_transform(b @ b.T, xyz)
    # a shift, a scale change and a rotation (skew matrix) of all points are absorbed
    d = xyz - xyz.mean(axis=0)
    w = np.array([[0.0, -3.0, 2.0], [3.0, 0.0, -1.0], [-2.0, 1.0, 0.0]])
    for g in (np.tile([1.0, 2.0, 3.0], 5), d.ravel(), (d @ w.T).ravel()):
        assert np.max(np.abs(q @ g)) < 1e-9 * np.max(np.abs(q)) * np.linalg.norm(g)
    np.testing.assert_allclose(s_transform(q, xyz)[0], q, atol=1e-9 * np.max(np.abs(q)))
    assert np.sum(sd) == pytest.approx(15 - 7)  # trace of the projector: 3n - 7


def test_strip_variances_exact_for_independent_errors_and_free_of_the_datum():
    rng = np.random.default_rng(4)
    xyz = rng.uniform(-1000, 1000, (6, 3))
    np.testing.assert_allclose(strip_variances(0.04 * np.eye(18), xyz), 0.04, rtol=1e-12)
    # add a datum effect: a common random shift and rotation of every point
    d = xyz - xyz.mean(axis=0)
    g = np.zeros((6, 3, 6))
    g[:, :, :3] = np.eye(3)
    g[:, 0, 4], g[:, 0, 5] = d[:, 2], -d[:, 1]
    g[:, 1, 3], g[:, 1, 5] = -d[:, 2], d[:, 0]
    g[:, 2, 3], g[:, 2, 4] = d[:, 1], -d[:, 0]
    g = g.reshape(18, 6)
    q = 0.04 * np.eye(18) + g @ np.diag([4.0, 4.0, 9.0, 1e-6, 1e-6, 1e-6]) @ g.T
    np.testing.assert_allclose(strip_variances(q, xyz), 0.04, rtol=1e-9)


def strip_with_control(n_points, error=None, seed=2):
    """A strip of n full control points: strip coordinates from the truth by the inverse
    similarity, 3 cm noise; given coordinates with 5 cm noise (and the planted error)."""
    rng = np.random.default_rng(seed)
    truth = np.column_stack([rng.uniform(3000, 6000, n_points), rng.uniform(2000, 3000, n_points),
                             rng.uniform(940, 990, n_points)])
    truth[:, :2] = np.array([[3000, 2000], [6000, 2100], [4500, 2900], [3100, 2950],
                             [5900, 2950], [4400, 2050]])[:n_points]
    r = rotation_matrix(*PARAMS[4:])
    xs = ((truth - PARAMS[:3]) @ r) / PARAMS[3] + rng.normal(0, 0.03, truth.shape)
    given = truth + rng.normal(0, 0.05, truth.shape)
    if error is not None:
        given[error[0]] += error[1]
    ids = [f"c{i}" for i in range(n_points)]
    block = Block(Settings(), Cameras(["c"], np.array([153.0]), np.zeros((1, 2))),
                  Photos(["1"], np.zeros(1, int), np.array(["1"], dtype=object),
                         np.zeros((1, 6))),
                  ImagePoints(np.zeros(0, int), np.zeros(0, int), np.zeros((0, 2)),
                              np.zeros(0)),
                  GroundPoints(ids, given, np.full((n_points, 3), 0.05),
                               np.full(n_points, "control", dtype=object)))
    strip = Strip("1", [0], np.zeros((1, 6)),
                  {i: xs[i] for i in range(n_points)},
                  {i: np.full(3, 0.03**2) for i in range(n_points)})
    return block, strip


def test_no_error_nothing_rejected_and_parameters_recovered():
    block, strip = strip_with_control(6)
    chk = check_strip(block, strip)
    assert chk.rejected == [] and chk.unlocated == []
    assert chk.params[3] == pytest.approx(PARAMS[3], rel=1e-4)
    np.testing.assert_allclose(chk.params[4:], PARAMS[4:], atol=1e-4)


def test_planimetric_error_is_located():
    block, strip = strip_with_control(6, (2, [1.0, 0.0, 0.0]))
    chk = check_strip(block, strip)
    assert chk.rejected == [2]


def test_height_error_among_four_points_is_not_located():
    """Four heights, a plane of three parameters: one condition; any point could be it."""
    block, strip = strip_with_control(4, (1, [0.0, 0.0, 3.0]))
    chk = check_strip(block, strip)
    assert chk.rejected == []
    assert len(chk.unlocated) == 1 and chk.unlocated[0][3]  # alternatives named


def test_height_error_among_six_points_is_located():
    block, strip = strip_with_control(6, (4, [0.0, 0.0, -3.0]))
    assert check_strip(block, strip).rejected == [4]


def test_fewer_than_three_full_points_are_not_checked():
    block, strip = strip_with_control(2)
    assert check_strip(block, strip) is None
