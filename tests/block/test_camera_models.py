"""Camera models of block/camera_models.py.

Jacobians against central differences for every model (one random coefficient set per
row), inverses by round trips, the equalities with camera.py's fixed models, DBAT's
residual chain written out step by step as DBAT composes it, the orthogonality of Ebner's
and of the Gruen-type fields over their grids, and the DBAT principal-point helpers.
"""

import zlib

import numpy as np
import pytest
from lens_reference import brown_terms, distort

from baarda.block import camera_models as cm
from baarda.block import field_models as fm

M = 300


def _sample(name: str, rng: np.random.Generator):
    """(u (M, 2), coef (M, k), const (M, nc) or None, length unit of u in mm)."""
    model = cm.MODELS[name]
    k = model.n_params
    if name == "none":
        return rng.uniform(-18, 18, (M, 2)), np.zeros((M, 0)), None, 1.0
    if name == "brown_forward":
        u = rng.uniform(-0.6, 0.6, (M, 2))
        coef = rng.normal(0, 1, (M, k)) * [0.1, 0.05, 0.01, 0.005, 0.005, 0.01]
        return u, coef, None, 50.0  # normalised: c = 50 mm
    if name == "fisheye_forward":
        u = rng.uniform(-1.2, 1.2, (M, 2))  # up to 60 degrees off the axis
        u[:3] *= 1e-6  # the series near the axis
        coef = rng.normal(0, 1, (M, k)) * [0.05, 0.01, 0.005, 0.001, 0.01]
        return u, coef, None, 50.0
    if name == "ebner":
        b = rng.uniform(6, 12, (M, 1))
        u = rng.uniform(-1.5, 1.5, (M, 2)) * b
        scale = np.array([1e-4, 1e-4, 1e-5, 1e-5, 1e-5, 1e-5, 1e-6, 1e-6, 1e-6, 1e-6,
                          1e-7, 1e-7])
        return u, rng.normal(0, 1, (M, k)) * scale, b, 1.0
    if name == "gruen":
        b = rng.uniform(4, 9, (M, 1))
        u = rng.uniform(-2, 2, (M, 2)) * b
        return u, rng.normal(0, 0.004, (M, k)), b, 1.0
    u = rng.uniform(-18, 18, (M, 2))
    if name == "aicon":
        coef = rng.normal(0, 1, (M, k)) * [1e-4, 1e-7, 1e-10, 1e-5, 1e-5, 1e-4, 1e-4]
        return u, coef, rng.uniform(5, 15, (M, 1)), 1.0
    coef = rng.normal(0, 1, (M, k)) * [1e-4, 1e-7, 1e-10, 1e-5, 1e-5, 1e-3, 1e-3]
    return u, coef, None, 1.0


def _central(f, x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """d f / d x (m, 2, n) by central differences, step h (n,) per column of x (m, n)."""
    cols = []
    for j in range(x.shape[1]):
        e = np.zeros_like(x)
        e[:, j] = h[j]
        cols.append((f(x + e) - f(x - e)) / (2 * h[j]))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("name", list(cm.MODELS))
def test_jacobians_against_central_differences(name):
    rng = np.random.default_rng(zlib.crc32(name.encode()))
    model = cm.get_model(name)
    u, coef, const, _ = _sample(name, rng)
    delta, jac, dcoef = model.correction(u, coef, const)
    assert delta.shape == (M, 2) and jac.shape == (M, 2, 2)
    assert dcoef.shape == (M, 2, model.n_params)
    hu = np.full(2, 1e-5 * np.abs(u).max())
    num_u = _central(lambda v: model.correction(v, coef, const)[0], u, hu)
    assert np.abs(jac - num_u).max() <= 1e-6 * np.abs(jac).max()
    if model.n_params:
        hc = 1e-4 * np.abs(coef).max(axis=0)
        num_c = _central(lambda c: model.correction(u, c, const)[0], coef, hc)
        err = np.abs(dcoef - num_c).max(axis=(0, 1))
        assert np.all(err <= 1e-6 * np.abs(dcoef).max(axis=(0, 1)))


@pytest.mark.parametrize("name", list(cm.MODELS))
def test_invert_apply_round_trip(name):
    rng = np.random.default_rng(3 + zlib.crc32(name.encode()))
    model = cm.get_model(name)
    u, coef, const, unit = _sample(name, rng)
    target, jac = cm.apply(model, u, coef, const)
    delta, dj, _ = model.correction(u, coef, const)
    assert np.array_equal(target, u + delta) and np.allclose(jac, dj + np.eye(2))
    back = cm.invert(model, target, coef, const)
    assert np.abs(back - u).max() * unit < 1e-12  # mm


def test_brown_equals_camera_brown_backward():
    rng = np.random.default_rng(11)
    u, coef, _, _ = _sample("brown", rng)
    coef[:, 5:] = 0.0
    d0, j0 = brown_terms(u, coef[:, :5])
    for name in ("brown", "dbat3", "dbat5"):
        delta, jac, _ = cm.MODELS[name].correction(u, coef)
        assert np.allclose(delta, d0, rtol=1e-14, atol=1e-17), name
        assert np.allclose(jac, j0, rtol=1e-14, atol=1e-17), name


def test_brown_forward_equals_camera_brown_forward():
    rng = np.random.default_rng(12)
    n, coef, _, _ = _sample("brown_forward", rng)
    coef[:, 5] = 0.0
    c = rng.uniform(20, 60, M)
    pp = rng.normal(0, 0.3, (M, 2))
    ideal = pp + c[:, None] * n
    xy0, j0 = distort(ideal, pp, c, coef[:, :5])
    nd, jac = cm.apply_forward(cm.MODELS["brown_forward"], n, coef)
    assert np.allclose(pp + c[:, None] * nd, xy0, rtol=0, atol=1e-12)
    assert np.allclose(jac, j0, rtol=1e-14, atol=1e-15)  # d n_d / d n = d xy / d ideal


def test_brown_forward_aspect_scales_y_after_distortion():
    rng = np.random.default_rng(13)
    n, coef, _, _ = _sample("brown_forward", rng)
    nd, _ = cm.apply_forward(cm.MODELS["brown_forward"], n, coef)
    plain = n + brown_terms(n, coef[:, :5])[0]
    assert np.allclose(nd, plain * np.column_stack([np.ones(M), 1 + coef[:, 5]]), atol=1e-15)


def _dbat_rhs(model: int, px: np.ndarray, sz: float, u0_int: np.ndarray, k_int, p_int, b):
    """DBAT's corrected observation (the rhs of its residual), step by step in DBAT's own
    order and internal conventions: pixels -> mm (scale2), y flipped (aniscale2 [1; -1]),
    then model 5: x scaled (aniscale2b), pp subtracted (xlat2 with -u0), Brown with -K, -P
    (brown_dist), skew [1, b2; 0, 1]; model 3: pp subtracted, affine [1+b1, b2; 0, 1]
    (affine2), Brown."""
    p = px * sz
    p = p * [1.0, -1.0]
    k, pt = -k_int, -p_int

    def brown_dist(w):
        r2 = (w**2).sum(axis=1)
        rad = r2 * (k[0] + r2 * (k[1] + r2 * k[2]))
        tang = pt[None, :] * r2[:, None] + 2 * (w @ pt)[:, None] * w
        return w + w * rad[:, None] + tang

    if model == 5:
        p = p * [1.0 + b[0], 1.0]
        lv = brown_dist(p - u0_int)
        return np.column_stack([lv[:, 0] + b[1] * lv[:, 1], lv[:, 1]])
    x = p - u0_int
    return brown_dist(np.column_stack([(1 + b[0]) * x[:, 0] + b[1] * x[:, 1], x[:, 1]]))


@pytest.mark.parametrize("model", [3, 5])
def test_dbat_models_follow_dbats_residual_chain(model):
    rng = np.random.default_rng(20 + model)
    iw, ih, sz = 4000, 3000, 0.009  # pixels; mm per pixel
    fmt = np.array([iw * sz, ih * sz])
    pix = rng.uniform(0, 1, (M, 2)) * [iw, ih]
    pp_ext = fmt / 2 + rng.normal(0, 0.2, 2)  # camera file: from the upper-left, y down
    k_ext = np.array([2e-4, -3e-7, 1e-10])
    p_ext = np.array([1e-5, -2e-5])
    b = np.array([3e-3, -2e-3])
    u0_int = pp_ext * [1.0, -1.0]  # DBAT keeps y of pp and K, P negated internally
    rhs = _dbat_rhs(model, pix, sz, u0_int, -k_ext, -p_ext, b)
    name = f"dbat{model}"
    pp = cm.principal_point_from_dbat(pp_ext, b[0], fmt, name)[0]
    obs = np.column_stack([pix[:, 0] * sz - fmt[0] / 2, fmt[1] / 2 - pix[:, 1] * sz])
    coef = np.concatenate([k_ext, p_ext, b])
    ideal_minus_pp, _ = cm.apply(cm.MODELS[name], obs - pp, coef)
    assert np.abs(ideal_minus_pp - rhs).max() < 1e-12


@pytest.mark.parametrize("name", ["dbat3", "dbat5"])
def test_dbat_principal_point_round_trip(name):
    rng = np.random.default_rng(30)
    fmt = rng.uniform(20, 40, (M, 2))
    pp_dbat = fmt / 2 + rng.normal(0, 0.3, (M, 2))
    b1 = rng.normal(0, 0.01, M)
    pp = cm.principal_point_from_dbat(pp_dbat, b1, fmt, name)
    assert np.allclose(cm.principal_point_to_dbat(pp, b1, fmt, name), pp_dbat, atol=1e-13)
    assert np.allclose(cm.principal_point_from_dbat(
        cm.principal_point_to_dbat(pp, b1, fmt, name), b1, fmt, name), pp, atol=1e-13)
    with pytest.raises(ValueError, match="dbat3, dbat5"):
        cm.principal_point_from_dbat(pp_dbat, b1, fmt, "brown")


def test_aicon_radial_vanishes_on_r0_and_matches_the_sum_of_its_parts():
    rng = np.random.default_rng(40)
    u, coef, r0, _ = _sample("aicon", rng)
    model = cm.MODELS["aicon"]
    on = u / np.linalg.norm(u, axis=1)[:, None] * r0
    radial_only = coef * [1, 1, 1, 0, 0, 0, 0]
    assert np.abs(model.correction(on, radial_only, r0)[0]).max() < 1e-15
    x, y = u[:, 0], u[:, 1]
    a1, a2, a3, b1, b2, c1, c2 = coef.T
    r2, q = x * x + y * y, r0[:, 0] ** 2
    rad = a1 * (r2 - q) + a2 * (r2**2 - q**2) + a3 * (r2**3 - q**3)
    dx = x * rad + b1 * (r2 + 2 * x * x) + 2 * b2 * x * y + c1 * x + c2 * y
    dy = y * rad + b2 * (r2 + 2 * y * y) + 2 * b1 * x * y
    assert np.allclose(model.correction(u, coef, r0)[0], np.column_stack([dx, dy]),
                       rtol=1e-13, atol=1e-17)


def _grid(n: int, b: float) -> np.ndarray:
    h = (n - 1) // 2
    return np.array([(i, j) for i in range(-h, h + 1) for j in range(-h, h + 1)]) * b


def _flat(fields: np.ndarray) -> np.ndarray:
    """(points, 2, k) -> (2 points, k): the fields as vectors over the grid."""
    return fields.reshape(-1, fields.shape[-1])


def test_ebner_fields_are_orthogonal_over_the_3x3_grid():
    b = 7.5
    g = _grid(3, b)
    f = _flat(cm.MODELS["ebner"].correction(g, np.zeros(12), [b])[2])
    e = _flat(fm.exterior_fields(g))
    gram = f.T @ f
    off = gram - np.diag(np.diag(gram))
    scale = np.sqrt(np.outer(np.diag(gram), np.diag(gram)))
    assert np.all(np.diag(gram) > 0)
    assert np.abs(off / scale).max() < 1e-14
    assert np.abs(f.T @ e / np.sqrt(np.outer(np.diag(gram), (e * e).sum(0)))).max() < 1e-14
    assert np.linalg.matrix_rank(np.column_stack([f, e])) == 18  # every field on 9 points


def test_gruen_fields_are_orthonormal_over_the_5x5_grid_and_extend_ebner():
    b = 5.0
    g = _grid(5, b)
    f = _flat(cm.MODELS["gruen"].correction(g, np.zeros(44), [b])[2])
    e = _flat(fm.exterior_fields(g))
    assert np.allclose(f.T @ f, 25 * np.eye(44), atol=1e-10)  # RMS 1 over the 25 points
    assert np.abs(f.T @ e).max() < 1e-10 * np.abs(e).max()
    assert np.linalg.matrix_rank(np.column_stack([f, e])) == 50  # every field on 25 points
    # the first 12 with the exterior orientation span Ebner's fields (as polynomials)
    pts = np.vstack([g, np.random.default_rng(50).uniform(-3 * b, 3 * b, (40, 2))])
    basis = np.column_stack([_flat(fm.gruen_fields(pts, np.full(len(pts), b))[:, :, :12]),
                             _flat(fm.exterior_fields(pts))])
    eb = _flat(fm.ebner_fields(pts, np.full(len(pts), b))[0])
    sol = np.linalg.lstsq(basis, eb, rcond=None)[0]
    assert np.abs(basis @ sol - eb).max() < 1e-9 * np.abs(eb).max()


def test_registry_and_arguments():
    assert set(cm.MODELS) == {"none", "brown", "dbat3", "dbat5", "brown_forward", "aicon",
                              "ebner", "gruen", "fisheye_forward"}
    with pytest.raises(ValueError, match="known: none, brown"):
        cm.get_model("fisheye")
    for m in cm.MODELS.values():
        assert m.side in ("backward", "forward") and len(set(m.params)) == m.n_params
    none = cm.get_model("none")
    u = np.ones((4, 2))
    delta, jac, dc = none.correction(u, None)
    assert not delta.any() and not jac.any() and dc.shape == (4, 2, 0)
    with pytest.raises(ValueError, match="needs the constants b"):
        cm.get_model("ebner").correction(u, np.zeros(12))
    with pytest.raises(ValueError, match=r"must be \(4, 7\)"):
        cm.get_model("brown").correction(u, np.zeros(5))
    with pytest.raises(ValueError, match="backward model"):
        cm.apply_forward(cm.get_model("brown"), u, np.zeros(7))
    one = cm.get_model("aicon").correction(u, np.arange(7) * 1e-5, [10.0])[0]
    assert np.allclose(one, one[0])  # one coefficient row broadcast to every row


def test_fisheye_forward_is_the_equidistant_fisheye():
    """theta_d = theta (1 + k1 theta^2 + ... + k4 theta^8), theta = atan(r), n_d = n theta_d
    / r, y times 1 + a: written out here; the series near the axis joins the closed form."""
    rng = np.random.default_rng(21)
    n = rng.uniform(-1.5, 1.5, (M, 2))
    n[0] = 0.0
    n[1] = [0.99e-4, 0.0]
    n[2] = [1.01e-4, 0.0]
    coef = rng.normal(0, 1, (M, 5)) * [0.05, 0.01, 0.005, 0.001, 0.01]
    nd, _ = cm.apply_forward(cm.MODELS["fisheye_forward"], n, coef)
    r = np.hypot(n[:, 0], n[:, 1])
    th = np.arctan(r)
    k = coef
    thd = th * (1 + k[:, 0] * th**2 + k[:, 1] * th**4 + k[:, 2] * th**6 + k[:, 3] * th**8)
    scale = np.ones(M)
    scale[r > 0] = thd[r > 0] / r[r > 0]
    want = n * scale[:, None]
    want[:, 1] *= 1 + k[:, 4]
    assert np.abs(nd - want).max() < 1e-15
    # with all coefficients 0: r -> atan(r), not the identity
    zero, _ = cm.apply_forward(cm.MODELS["fisheye_forward"], [[1.0, 0.0]], np.zeros(5))
    assert zero[0] == pytest.approx([np.pi / 4, 0.0], abs=1e-15)
