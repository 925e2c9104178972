"""The projection with a camera model (bundle/collinearity.py camera_projection): analytic
Jacobians with respect to orientation, point and every camera parameter against central
differences for every model; the forward model against the BAL formula written out
independently and against pycolmap's OPENCV camera; a-priori lens corrections of the block
(block/camera.py)."""

import numpy as np
import pytest

from baarda.block.camera import corrected_observations, ideal_image_coordinates, model_of
from baarda.block.camera_models import MODELS
from baarda.block.rotation import rotation_matrix
from baarda.bundle.collinearity import camera_projection, project

rng = np.random.default_rng(7)

COEF = {  # plausible coefficients per model (mm units for the photogrammetric ones)
    "none": [],
    "brown": [2e-4, -3e-7, 1e-10, 4e-6, -3e-6, 2e-4, -1e-4],
    "dbat3": [2e-4, -3e-7, 1e-10, 4e-6, -3e-6, 2e-4, -1e-4],
    "dbat5": [2e-4, -3e-7, 1e-10, 4e-6, -3e-6, 2e-4, -1e-4],
    "brown_forward": [-0.12, 0.05, -0.01, 1e-3, -2e-3, 3e-3],
    "fisheye_forward": [0.03, -0.01, 0.004, -0.001, 2e-4],
    "aicon": [-1.1e-4, 1.5e-7, 1e-11, 5.8e-6, -8.6e-6, -7e-5, -3e-5],
    "ebner": list(rng.normal(0, 1e-4, 12)),
    "gruen": list(rng.normal(0, 1e-3, 44)),
}
CONST = {"aicon": [13.5], "ebner": [8.0], "gruen": [4.0]}


def _scene(m=30):
    eo = np.column_stack([rng.normal(0, 5, (4, 3)) + [0, 0, 100], rng.normal(0, 0.1, (4, 3))])
    photo = rng.integers(0, 4, m)
    r = rotation_matrix(eo[photo, 3], eo[photo, 4], eo[photo, 5])
    # points in front of each photo, within about a 60 degree cone
    d = np.column_stack([rng.uniform(-0.5, 0.5, (m, 2)), -np.ones(m)]) * rng.uniform(60, 90, (
        m, 1))
    xyz = eo[photo, :3] + np.einsum("mij,mj->mi", r, d)
    return eo, xyz, photo


def _numeric(f, x, h):
    cols = []
    for k in range(x.size):
        e = np.zeros(x.size)
        e[k] = h
        cols.append((f(x + e.reshape(x.shape)) - f(x - e.reshape(x.shape))) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("name", sorted(MODELS))
def test_jacobians_of_every_model(name):
    model = MODELS[name]
    eo, xyz, photo = _scene()
    c = 24.0
    params = np.concatenate([[c, 0.12, -0.08], COEF[name]])
    const = np.array(CONST.get(name, []), float)
    observed = project(eo, xyz, np.full(len(photo), c), np.zeros((len(photo), 2)),
                       photo=photo) + rng.normal(0, 0.01, (len(photo), 2))

    def f_of(eo_=eo, xyz_=xyz, p_=params):
        return camera_projection(eo_, xyz_, photo, p_, model, const, observed)[0]

    f, je, jp, jpar = camera_projection(eo, xyz, photo, params, model, const, observed)
    assert np.allclose(f, f_of())
    # per row: the photo's 6 unknowns, the point's 3 unknowns
    for i in range(5):
        def with_eo(e, i=i):
            return f_of(eo_=np.vstack([eo[:photo[i]], e[None, :], eo[photo[i] + 1:]]))[i]

        def with_point(p, i=i):
            return f_of(xyz_=np.vstack([xyz[:i], p[None, :], xyz[i + 1:]]))[i]

        ne = _numeric(with_eo, eo[photo[i]], 1e-7)
        assert np.allclose(je[i], ne, rtol=1e-6, atol=1e-9 * np.abs(je[i]).max())
        npt = _numeric(with_point, xyz[i], 1e-5)
        assert np.allclose(jp[i], npt, rtol=1e-6, atol=1e-9 * np.abs(jp[i]).max())
    steps = np.maximum(np.abs(params), 1e-3) * 1e-4
    for k in range(len(params)):
        e = np.zeros(len(params))
        e[k] = steps[k]
        num = (f_of(p_=params + e) - f_of(p_=params - e)) / (2 * steps[k])
        scale = max(np.abs(num).max(), np.abs(jpar[:, :, k]).max(), 1e-12)
        assert np.allclose(jpar[:, :, k], num, rtol=1e-5, atol=1e-7 * scale), (name, k)
    assert model.side in ("forward", "backward")


def test_forward_model_is_bal_formula():
    """BAL: P = R X + t, p = -P/P.z, x = f (1 + k1 |p|^2 + k2 |p|^4) p (independent code)."""
    m = 30
    eo, xyz, photo = _scene(m)
    f, k1, k2 = 500.0, -0.2, 0.05
    r = rotation_matrix(eo[photo, 3], eo[photo, 4], eo[photo, 5])
    rb = np.swapaxes(r, 1, 2)  # BAL rotation maps world -> camera
    pc = np.einsum("mij,mj->mi", rb, xyz - eo[photo, :3])
    p = -pc[:, :2] / pc[:, 2:3]
    n2 = np.sum(p**2, axis=1)
    expect = (f * (1 + k1 * n2 + k2 * n2**2))[:, None] * p
    got = camera_projection(eo, xyz, photo, np.array([f, 0, 0, k1, k2, 0, 0, 0, 0]),
                            MODELS["brown_forward"], np.zeros(0), np.zeros((m, 2)))[0]
    assert np.allclose(got, expect, rtol=1e-12, atol=1e-9)


def test_forward_model_matches_pycolmap_opencv():
    pycolmap = pytest.importorskip("pycolmap")
    f, cx, cy = 1200.0, 640.3, 479.7
    k1, k2, p1, p2 = -0.21, 0.07, 0.0013, -0.0021
    cam = pycolmap.Camera(model="OPENCV", width=1280, height=960,
                          params=[f, f, cx, cy, k1, k2, p1, p2])
    pts = np.column_stack([rng.uniform(-0.4, 0.4, (20, 2)), np.ones(20)])
    pix = cam.img_from_cam(pts)
    # baarda: camera looking down -z with y up; a point at camera coordinates (x, -y, -1)
    eo = np.zeros((1, 6))
    xyz = np.column_stack([pts[:, 0], -pts[:, 1], -np.ones(20)])
    params = np.array([f, 0.0, 0.0, k1, k2, 0.0, p2, -p1, 0.0])  # OpenCV order, y flipped
    got = camera_projection(eo, xyz, np.zeros(20, int), params, MODELS["brown_forward"],
                            np.zeros(0), np.zeros((20, 2)))[0]
    assert np.allclose(got[:, 0] + cx, pix[:, 0], atol=1e-9)
    assert np.allclose(cy - got[:, 1], pix[:, 1], atol=1e-9)


def test_backward_residual_is_corrected_minus_projected():
    """For a backward model e = observed - f is the corrected observation minus the
    projection (the residual DBAT forms), and the block's corrected observations agree."""
    from baarda.simulate.aerial import FlightPlan, simulate_block

    block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=3, seed=1))
    block.cameras.model = np.array(["brown"], dtype=object)
    block.cameras.coefficients = np.array([COEF["brown"]])
    corrected = corrected_observations(block)
    im = block.image
    pts = block.points
    xyz = np.where(np.isfinite(pts.xyz), pts.xyz, 0.0)[im.point]
    c = block.cameras
    params = np.concatenate([[c.focal_mm[0]], c.principal_point_mm[0], COEF["brown"]])
    f = camera_projection(block.photos.eo, xyz, im.photo, params, model_of("brown"),
                          np.zeros(0), im.xy_mm)[0]
    proj = project(block.photos.eo, xyz, np.full(len(im), c.focal_mm[0]),
                   np.tile(c.principal_point_mm[0], (len(im), 1)), photo=im.photo)
    assert np.allclose(im.xy_mm - f, corrected - proj, atol=1e-12)
    assert np.allclose(ideal_image_coordinates(block), corrected)


def test_with_camera_widens_the_tables():
    """A camera of another block appended (OnlineBundle.add_camera): its model, coefficients
    and constants kept, the first block's tables widened (coefficients 0, constants and
    pixel sizes NaN where it has none)."""
    from baarda.block.camera import coefficients, kinds, parameter_names, with_camera
    from baarda.block.photo_block import Cameras

    a = Cameras(["1"], np.array([153.0]), np.array([[0.01, -0.02]]))
    b = Cameras(["7", "8"], np.array([35.0, 24.0]), np.array([[0.0, 0.0], [0.1, 0.2]]),
                model=np.array(["none", "brown"], dtype=object),
                coefficients=np.array([[0, 0, 0, 0, 0], [1e-4, -2e-7, 0, 3e-6, 0]], float),
                pixel_mm=np.array([0.004, 0.005]))
    c = with_camera(a, b, 1)
    assert c.ids == ["1", "8"] and c.focal_mm.tolist() == [153.0, 24.0]
    assert c.principal_point_mm.tolist() == [[0.01, -0.02], [0.1, 0.2]]
    assert kinds(c).tolist() == ["none", "brown"]
    assert coefficients(c, 1).tolist() == [1e-4, -2e-7, 0.0, 3e-6, 0.0, 0.0, 0.0]  # b1 b2
    assert parameter_names(c, 0) == ("c", "x0", "y0")
    assert np.isnan(c.pixel_mm[0]) and c.pixel_mm[1] == 0.005
    assert with_camera(a, a, 0).model is None  # no models: still none


def test_what_is_free_is_a_setting_not_camera_data():
    """The cameras are data only (issue 37): the parameters a self-calibration estimates
    are the block's settings.calibration_free, split with the cameras per strip and cleared
    with a new camera model (io/configuration.py decides them again)."""
    from dataclasses import fields, replace

    from baarda.block.camera import cameras_per_strip, with_camera_model
    from baarda.block.photo_block import Cameras
    from baarda.simulate.aerial import FlightPlan, simulate_block

    assert "free" not in {f.name for f in fields(Cameras)}
    block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=4, seed=2))
    b = replace(block, settings=replace(block.settings, calibration_free=(("c", "x0"),)))
    split = cameras_per_strip(b)
    assert len(split.cameras) == 2
    assert split.settings.calibration_free == (("c", "x0"), ("c", "x0"))
    assert with_camera_model(b, "brown").settings.calibration_free is None
