import numpy as np
import pytest

from baarda.block.rotation import (
    angle_to_rad,
    angles_from_matrix,
    rodrigues,
    rotation_matrix,
    rotation_vector,
)
from baarda.bundle.collinearity import project


def test_known_point_through_known_photo():
    # photo at (1000, 2000, 1500), c = 150 mm, looking down; point 100 m east, 50 m north
    eo = np.array([[1000.0, 2000.0, 1500.0, 0.0, 0.0, 0.0]])
    xyz = np.array([[1100.0, 2050.0, 0.0]])
    xy = project(eo, xyz, np.array([150.0]), np.zeros((1, 2)))
    assert xy[0] == pytest.approx([10.0, 5.0], abs=1e-12)
    # kappa = 100 gon: the image x axis points to object +Y
    eo[0, 5] = angle_to_rad(100.0, "gon")
    xy = project(eo, xyz, np.array([150.0]), np.array([[0.01, -0.02]]))
    assert xy[0] == pytest.approx([5.0 + 0.01, -10.0 - 0.02], abs=1e-12)


def test_omega_tilts_about_x():
    # omega = +0.1 rad: R = Rx(omega); the nadir point appears at y = c tan(omega) ... sign
    eo = np.array([[0.0, 0.0, 1000.0, 0.1, 0.0, 0.0]])
    xy = project(eo, np.array([[0.0, 0.0, 0.0]]), np.array([100.0]), np.zeros((1, 2)))
    # u = Rx^T (0, 0, -1000) = (0, -1000 sin w, -1000 cos w) -> y = -c u2/u3 = -c tan w
    assert xy[0] == pytest.approx([0.0, -100.0 * np.tan(0.1)], abs=1e-12)


def test_matrix_elements_and_inverse():
    o, p, k = 0.1, -0.2, 0.3
    r = rotation_matrix(o, p, k)
    assert r[0, 2] == pytest.approx(np.sin(p))
    assert r[2, 2] == pytest.approx(np.cos(o) * np.cos(p))
    assert r[0, 0] == pytest.approx(np.cos(p) * np.cos(k))
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-15)
    assert angles_from_matrix(r) == pytest.approx([o, p, k], abs=1e-14)


@pytest.mark.parametrize("unit,value,rad", [("gon", 200.0, np.pi), ("deg", 90.0, np.pi / 2),
                                            ("rad", 1.0, 1.0)])
def test_angle_units(unit, value, rad):
    assert angle_to_rad(value, unit) == pytest.approx(rad)


def test_rodrigues():
    th = np.array([0.1, -0.05, 0.3])
    r = rodrigues(th)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(r @ th, th, atol=1e-14)  # the axis stays
    a = np.linalg.norm(th)
    assert np.arccos((np.trace(r) - 1) / 2) == pytest.approx(a)


def test_rotation_vector_inverts_rodrigues_near_0_and_pi():
    rng = np.random.default_rng(2)
    axes = rng.normal(size=(6, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    for angle in (0.0, 1e-9, 0.3, 3.0, np.pi - 1e-5, np.pi):
        r = rodrigues(axes * angle)
        np.testing.assert_allclose(rodrigues(rotation_vector(r)), r, atol=1e-12)
