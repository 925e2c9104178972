"""Coplanarity and XZ collinearity: analytic partials against central differences, the
observation partials of Kratky's eq. 4, and the exact linearity in the observation."""

import numpy as np
import pytest

from baarda.block.rotation import rotation_matrix
from baarda.relative.coplanarity import coplanarity, image_vectors, right_rotation
from baarda.relative.orientation import ModelSetup, PhotoPose, residual_function
from baarda.relative.scale_transfer import collinearity_xz

C = 152.0


def _setup(rng, ties=3):
    left = PhotoPose(np.array([3.0, -1.0, 2.0]), rotation_matrix(0.02, -0.015, 0.03))
    xy1 = rng.uniform(-90, 90, (7, 2))
    xy2 = xy1 - [90.0, 0.0] + rng.normal(0, 2, (7, 2))
    tie_xyz = np.column_stack([rng.uniform(-10, 10, ties), rng.uniform(-90, 90, ties),
                               rng.uniform(-160, -140, ties)])
    setup = ModelSetup(C, left, 91.0, np.arange(ties), tie_xyz, scale=True)
    g = np.array([1.02, 0.03, -0.02, 0.05, -0.04, 0.03])
    return setup, xy1, xy2, g


def _num_jac(fun, g, h=1e-6):
    cols = []
    for k in range(len(g)):
        e = np.zeros(len(g))
        e[k] = h
        cols.append((fun(g + e) - fun(g - e)) / (2 * h))
    return np.column_stack(cols)


def _conditions(setup, xy1, xy2, g):
    x_left = image_vectors(xy1, C) @ setup.left.rotation.T
    u2 = image_vectors(xy2, C)
    rot, parts = right_rotation(g[3:6])
    cp = coplanarity(g[:3], x_left, u2, rot, parts)
    cl = collinearity_xz(g[:3], setup.base_ref, setup.left.centre, setup.tie_xyz,
                         u2[setup.tie_index], rot, parts)
    return cp, cl


def test_partials_of_both_conditions_against_numerical_derivatives():
    setup, xy1, xy2, g = _setup(np.random.default_rng(1))
    cp, cl = _conditions(setup, xy1, xy2, g)
    for which, lin in (("p", cp), ("l", cl)):
        def f(gg, which=which):
            a, b = _conditions(setup, xy1, xy2, gg)
            return (a if which == "p" else b).f

        def a(gg, which=which):
            a_, b_ = _conditions(setup, xy1, xy2, gg)
            return (a_ if which == "p" else b_).a

        np.testing.assert_allclose(lin.df_dg, _num_jac(f, g), rtol=1e-7, atol=1e-6)
        np.testing.assert_allclose(lin.da_dg, _num_jac(a, g), rtol=1e-7, atol=1e-6)


def test_observation_partials_and_exact_linearity():
    setup, xy1, xy2, g = _setup(np.random.default_rng(2))
    cp, cl = _conditions(setup, xy1, xy2, g)
    h = 1e-4
    for k, lin, comp in ((1, cp, slice(None)), (0, cl, setup.tie_index)):
        moved = xy2.copy()
        moved[comp, k] += h
        p2, l2 = _conditions(setup, xy1, moved, g)
        after = p2 if lin is cp else l2
        np.testing.assert_allclose((after.f - lin.f) / h, lin.a, rtol=1e-7)
        # linear in the observation: the correction -F/a makes the condition hold exactly
        fixed = xy2.copy()
        fixed[comp, k] += -lin.f / lin.a
        p3, l3 = _conditions(setup, xy1, fixed, g)
        assert np.max(np.abs((p3 if lin is cp else l3).f)) < 1e-9 * C**2


def test_kratky_pseudo_weights_eq4():
    """a_p = -z' and a_L = -dZ for photos without rotation and a base along x."""
    xy1 = np.array([[0.0, 90.0], [92.0, -90.0], [40.0, 0.0]])
    xy2 = xy1 - [92.0, 0.0]
    rot, parts = right_rotation(np.zeros(3))
    x_left = image_vectors(xy1, C)
    cp = coplanarity(np.array([1.0, 0.0, 0.0]), x_left, image_vectors(xy2, C), rot, parts)
    np.testing.assert_allclose(cp.a, -x_left[:, 2])  # -z' = c
    tie = np.array([[0.0, 90.0, -150.0]])
    cl = collinearity_xz(np.array([1.0, 0.0, 0.0]), 92.0, np.zeros(3), tie,
                         image_vectors(xy2[:1], C), rot, parts)
    np.testing.assert_allclose(cl.a, -(tie[0, 2] - 0.0))


def test_residual_jacobian_against_numerical_derivatives():
    setup, xy1, xy2, g = _setup(np.random.default_rng(3))
    v, jac = residual_function(g, setup, xy1, xy2)
    num = _num_jac(lambda gg: residual_function(gg, setup, xy1, xy2)[0], g)
    np.testing.assert_allclose(jac, num, rtol=1e-6, atol=1e-3)  # µm per unit
    assert v.shape == (7 + 3,)
    assert np.max(np.abs(jac)) > 1e3  # the test is not vacuous


@pytest.mark.parametrize("angles", [(0.0, 0.0, 0.0), (0.1, -0.05, 0.2)])
def test_right_rotation_order(angles):
    kappa, phi, omega = angles
    r, _ = right_rotation(np.array(angles))
    np.testing.assert_allclose(r, rotation_matrix(omega, phi, kappa))
