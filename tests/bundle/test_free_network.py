"""Free-network adjustment (bundle/free.py) against a dense brute-force computation.

For a small simulated block without control, the residuals, sigma0 and redundancy numbers
of the minimal-constraint solution must equal those of the dense inner solution computed
with the pseudo-inverse of the (singular) full normal matrix, and must not depend on the
choice of the datum photos.
"""

from dataclasses import replace

import numpy as np
import pytest

from baarda.bundle.bundle_problem import SOLVE
from baarda.bundle.collinearity import project_with_jacobians
from baarda.bundle.free_network import adjust_free
from baarda.errors import GeometryError
from baarda.pipeline import assess
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def block():
    plan = FlightPlan(strips=2, photos_per_strip=3, pattern=3, control="none", height_chains=0,
                      relief_m=80.0, seed=3)
    b, _ = simulate_block(plan)
    assert not b.points.controlled.any()
    return b


def _dense(block, res):
    """Full Jacobian (all 6 n + 3 k unknowns) at the solution, weights."""
    pb = res.problem
    im = block.image
    obs = pb.obs
    ph, pt = im.photo[obs], pb.remap[im.point[obs]]
    cam = block.photos.camera[ph]
    _, je, jp = project_with_jacobians(res.eo[ph], res.xyz[pt], block.cameras.focal_mm[cam],
                                       block.cameras.principal_point_mm[cam])
    nf, npt = len(block.photos), len(pb.point_ids)
    a = np.zeros((2 * len(obs), 6 * nf + 3 * npt))
    for i in range(len(obs)):
        a[2 * i:2 * i + 2, 6 * ph[i]:6 * ph[i] + 6] = je[i]
        a[2 * i:2 * i + 2, 6 * nf + 3 * pt[i]:6 * nf + 3 * pt[i] + 3] = jp[i]
    p = np.repeat(1 / im.sigma_mm[obs] ** 2, 2)
    return a, p


def test_free_network_matches_dense_inner_solution(block):
    res = adjust_free(block)
    assert res.converged
    a, p = _dense(block, res)
    n = a.T @ (p[:, None] * a)
    sc = 1 / np.sqrt(np.diag(n))
    rank = np.linalg.matrix_rank(sc[:, None] * n * sc[None, :], tol=1e-8)
    assert n.shape[0] - rank == 7  # datum defect of a free network
    assert res.n_unknowns == rank and res.redundancy == len(p) - rank
    # at the solution the gradient vanishes (also in the held directions: minimal datum)
    v = res.image_residuals.ravel()
    assert np.abs(a.T @ (p * v)).max() < 1e-6 * np.abs(a.T @ (p * np.abs(v))).max()
    # redundancy numbers from the pseudo-inverse
    ninv = sc[:, None] * np.linalg.pinv(sc[:, None] * n * sc[None, :], rcond=1e-10) * sc[None, :]
    r_dense = 1 - p * np.einsum("ij,jk,ik->i", a, ninv, a)
    qc = assess(res)
    assert np.allclose(qc.quality.redundancy_number, r_dense, atol=1e-7)
    assert np.isclose(qc.quality.sum_redundancy_numbers, res.redundancy, atol=1e-6)


def test_datum_choice_does_not_change_observation_statistics(block):
    r1 = adjust_free(block, datum=(0, 5, 0))
    r2 = adjust_free(block, datum=(2, 3, 1))
    assert np.allclose(r1.image_residuals, r2.image_residuals, atol=1e-9)
    assert np.isclose(r1.sigma0, r2.sigma0, rtol=1e-9)
    q1, q2 = assess(r1), assess(r2)
    assert np.allclose(q1.quality.w, q2.quality.w, atol=1e-6, equal_nan=True)
    assert np.allclose(q1.quality.redundancy_number, q2.quality.redundancy_number, atol=1e-8)
    # the held photo does not move, its standard deviations are zero
    assert np.allclose(r1.eo[0], block.photos.eo[0]) and np.all(r1.eo_std[0] < 1e-9)


def test_free_network_refuses_control():
    b, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=3, seed=1))
    with pytest.raises(GeometryError, match="control"):
        adjust_free(b)


def test_similarity_recovers_a_known_transformation():
    from baarda.block.rotation import rotation_matrix, similarity

    rng = np.random.default_rng(5)
    src = rng.normal(size=(6, 3)) * 100
    r = rotation_matrix(0.3, -0.2, 1.1)
    dst = 1.7 * src @ r.T + np.array([10.0, -20.0, 5.0])
    s, r2, t = similarity(src, dst)
    assert np.isclose(s, 1.7, rtol=1e-12) and np.allclose(r2, r, atol=1e-12)
    assert np.allclose(t, [10.0, -20.0, 5.0], atol=1e-9)


def test_free_network_check_points_after_a_similarity(tmp_path, capsys):
    """`--free` on the demo: the control becomes check points compared after a 7-parameter
    similarity, so the comparison does not depend on where the free datum put the block:
    the same block moved, turned and scaled as a whole gives the same check RMS."""
    from dataclasses import replace
    from pathlib import Path

    from baarda.block.photo_block import Photos
    from baarda.block.rotation import angles_from_matrix, rotation_matrix
    from baarda.pipeline import adjust, read

    demo = Path(__file__).parents[2] / "examples" / "demo"
    block = read(demo, datum="free")
    first = adjust(block)
    assert first.check_similarity() is not None
    r = rotation_matrix(0.0, 0.0, 0.5)
    eo = block.photos.eo.copy()
    eo[:, :3] = 1.3 * eo[:, :3] @ r.T + np.array([5000.0, -300.0, 40.0])
    for i in range(len(eo)):
        eo[i, 3:] = angles_from_matrix(r @ rotation_matrix(*eo[i, 3:]))
    moved = replace(block, photos=Photos(block.photos.ids, block.photos.camera,
                                         block.photos.strip, eo))
    second = adjust(moved)
    assert np.allclose(second.check_rms(), first.check_rms(), rtol=1e-6)
    raw = second.xyz[second.problem.remap[np.flatnonzero(block.points.role == "check")]]
    assert np.abs(raw - block.points.xyz[block.points.role == "check"]).max() > 1000


def test_inner_datum_is_the_same_from_every_minimal_datum():
    """The S-transformation to the inner datum gives the same point covariances whichever
    minimal constraints the adjustment used, with the least trace; redundancy numbers, w
    and MDB are the same under every datum."""
    from baarda.bundle.bundle_model import BundleModel
    from baarda.bundle.free_network import FreeBundleProblem
    from baarda.bundle.inner_datum import inner_datum
    from baarda.pipeline import assess
    from baarda.simulate.aerial import FlightPlan, simulate_block

    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=5, relief_m=60.0,
                                         control="none", height_chains=0, seed=4))
    # both at the minimum: the solver stops when the correction at an estimate is below its
    # tolerance, and that estimate can be 1e-6 m from the minimum, more than this test's
    # tolerances; final_step applies the last correction
    a = FreeBundleProblem(block).fit(options=replace(SOLVE, final_step=True))
    b = FreeBundleProblem(block, datum=(7, 12, 1)).fit(options=replace(SOLVE, final_step=True))
    assert a.problem.datum != b.problem.datum
    qa, qb = assess(a).quality, assess(b).quality
    for name in ("redundancy_number", "w", "mdb"):
        assert np.allclose(getattr(qa, name), getattr(qb, name), rtol=1e-7, atol=1e-9,
                           equal_nan=True)
    ia, ib = inner_datum(a), inner_datum(b)
    xa, ca, xb, cb = ia.xyz, ia.point_cofactors, ib.xyz, ib.point_cofactors
    scale = np.abs(ca).max()
    assert np.allclose(ca, cb, rtol=1e-6, atol=1e-9 * scale)
    assert np.allclose(xa, xb, atol=1e-6)
    assert np.allclose(ia.eo, ib.eo, atol=1e-7)
    fs = np.abs(ia.frame_cofactors).max()
    assert np.allclose(ia.frame_cofactors, ib.frame_cofactors, rtol=1e-6, atol=1e-9 * fs)
    trace = lambda q: float(np.trace(q, axis1=1, axis2=2).sum())  # noqa: E731
    assert trace(ca) < trace(a.point_covariance()) and trace(ca) < trace(b.point_covariance())
    # S is a projector: the inner datum of the inner datum is itself (dense check)
    assert BundleModel(a).n == BundleModel(b).n


def test_inner_datum_equals_the_dense_inner_constraint_solution():
    """Independent oracle: the design matrix of every orientation and point unknown (the
    held ones too) by central differences of the problem's own misclosures, its null space
    (the 7 datum directions) from the dense normal matrix, and the cofactors of the
    solution constrained to move the points least: top-left of [[N, C], [C', 0]]^-1 with C
    the null space restricted to the points (Baarda's inner constraints)."""
    from baarda.bundle.bundle_model import BundleModel
    from baarda.bundle.free_network import FreeBundleProblem
    from baarda.bundle.inner_datum import inner_datum
    from baarda.simulate.aerial import FlightPlan, simulate_block

    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=4, relief_m=150.0,
                                         side_overlap=0.6, control="none", height_chains=0,
                                         seed=5))
    res = FreeBundleProblem(block).fit()
    pb = res.problem
    inner = inner_datum(res)
    rows = pb.remap[pb.elim_ids]
    # linearised at the inner-datum solution (the same solution moved by a similarity)
    state = [inner.eo.copy(), inner.xyz[rows].copy()]
    nf, npt = len(state[0]), len(state[1])

    def misclosure(st):
        lin = pb.linearize(tuple(st))
        return pb.layout.flat(lin.e, lin.ec, lin.ex)

    e0 = misclosure(state)
    assert np.allclose(e0, misclosure(res.state), atol=1e-9)  # the same residuals
    cols = [(0, k) for k in range(6 * nf)] + [(1, k) for k in range(3 * npt)]
    a = np.zeros((len(e0), len(cols)))
    for j, (part, k) in enumerate(cols):
        h = 1e-6 * max(1.0, abs(state[part].ravel()[k]))
        plus, minus = [x.copy() for x in state], [x.copy() for x in state]
        plus[part].ravel()[k] += h
        minus[part].ravel()[k] -= h
        a[:, j] = (misclosure(plus) - misclosure(minus)) / (2 * h)
    model = BundleModel(res)
    p = np.where(model.active, 1.0 / model.sigma**2, 0.0)
    dcol = np.sqrt(p @ a**2)  # column scaling (metres and radians)
    n = (a / dcol).T @ (p[:, None] * (a / dcol))
    val, vec = np.linalg.eigh(n)
    assert val[6] < 1e-12 * val[-1] and val[7] > 1e-10 * val[-1]  # a 7-parameter defect
    c = vec[:, :7] / dcol[:, None] ** 2  # the datum directions, as constraints on y = D x
    c[:6 * nf] = 0.0  # the datum points: every point
    u = len(cols)
    bordered = np.block([[n, c], [c.T, np.zeros((7, 7))]])
    q = np.linalg.inv(bordered)[:u, :u] / np.outer(dcol, dcol)
    for i in range(npt):
        qi = q[6 * nf + 3 * i:6 * nf + 3 * i + 3, 6 * nf + 3 * i:6 * nf + 3 * i + 3]
        assert np.allclose(inner.point_cofactors[rows[i]], qi, rtol=1e-6,
                           atol=1e-6 * np.abs(qi).max())
    for f in range(nf):
        qf = q[6 * f:6 * f + 6, 6 * f:6 * f + 6]
        sd = np.sqrt(np.diag(qf))
        assert np.allclose(inner.frame_cofactors[f] / np.outer(sd, sd), qf / np.outer(sd, sd),
                           atol=1e-6)
    # the inner datum moves the points least: their mean correction from the approximations
    # is zero and so is their mean rotation (linear inner constraints, to first order)
    d = inner.xyz[rows] - pb.approximations[1]
    assert np.abs(d.mean(axis=0)).max() < 1e-9


def test_inner_datum_from_the_command_line(tmp_path):
    """`--datum inner`: the same residuals and check-point differences as `--free`, points.csv
    and photos.csv in the inner datum (the least sum of point variances), the summary says
    so; project.toml datum = "inner" does the same."""
    import pandas as pd

    from baarda.cli import main

    proj = tmp_path / "proj"
    assert main(["simulate", "-o", str(proj), "--pattern", "5", "--relief", "100"]) == 0
    assert main(["adjust", str(proj), "-o", str(tmp_path / "inner"), "--datum", "inner",
                 "-q"]) == 0
    assert main(["adjust", str(proj), "-o", str(tmp_path / "free"), "--free", "-q"]) == 0
    pi, pf = (pd.read_csv(tmp_path / f / "points.csv") for f in ("inner", "free"))
    var = lambda d: float((d[["sigma_X", "sigma_Y", "sigma_Z"]] ** 2).sum().sum())  # noqa
    assert var(pi) < 0.1 * var(pf)
    assert np.allclose(pi[["dX", "dY", "dZ"]], pf[["dX", "dY", "dZ"]], atol=1e-6,
                       equal_nan=True)
    oi, of = (pd.read_csv(tmp_path / f / "observations.csv") for f in ("inner", "free"))
    assert np.allclose(oi["w"], of["w"], atol=1e-6, equal_nan=True)
    assert "INNER DATUM" in (tmp_path / "inner" / "summary.json").read_text()
    toml = proj / "project.toml"
    toml.write_text('datum = "inner"\n' + toml.read_text())
    assert main(["adjust", str(proj), "-o", str(tmp_path / "toml"), "-q"]) == 0
    pt = pd.read_csv(tmp_path / "toml" / "points.csv")
    assert np.allclose(pt[["X", "Y", "Z"]], pi[["X", "Y", "Z"]], atol=1e-9)
    assert main(["adjust", str(proj), "-o", str(tmp_path / "x"), "--free", "--datum",
                 "control"]) == 2


def test_a_point_whose_rays_are_behind_the_camera_is_named_as_such():
    """Issue 41: a point whose every ray was left out as behind the camera was said to be
    'not measured on any photo'; the notes now say which points lost their rays and why."""
    from baarda.bundle.free_network import drop_points_behind
    from baarda.bundle.geometry import usable_points

    block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=4, seed=5))
    pts = block.points
    j = int(np.flatnonzero((pts.role == "tie") & (block.rays() >= 2))[0])
    n_rays = int(block.rays()[j])
    xyz = pts.xyz.copy()  # above every camera: behind each of them
    xyz[j] = [*block.photos.eo[:, :2].mean(axis=0), 3 * block.photos.eo[:, 2].max()]
    out, dropped = drop_points_behind(replace(block, points=replace(pts, xyz=xyz)))
    assert dropped == n_rays and out.rays()[j] == 0
    assert out.notes[-1].endswith(f"1 point(s) left with fewer than two rays by it: "
                                  f"{pts.ids[j]}")
    _, notes = usable_points(out)
    assert notes == [f"tie point {pts.ids[j]} has no ray (measured on no photo, or its rays "
                     "left out: see the notes above): left out"]
