"""Design blocks: error-free observations, control layouts, twin control, and the
redundancy numbers against an independent dense computation with numerical derivatives."""

import numpy as np
import pytest

from baarda.bundle.collinearity import project
from baarda.planning.design import ControlLayout, design_block, design_from_project
from baarda.planning.design_reliability import analyse_design
from baarda.planning.gruen_study import spacings, study_plan
from baarda.simulate.aerial import FlightPlan, simulate_block


def _numerical_redundancy(plan):
    """r = diag(I - A (A^T P A)^-1 A^T P) with A by central differences of project(),
    in the flat order of the bundle model; the projection is taken from a QR of P^1/2 A."""
    m = plan.qc.model
    res = plan.adjustment
    blk = res.block
    pb = res.problem
    eo, xyz = res.eo, res.xyz
    nf, npt = len(eo), len(xyz)
    a = np.zeros((m.n, 6 * nf + 3 * npt))
    img = np.flatnonzero(m.image_row >= 0)
    r = m.image_row[img]
    k = np.where(m.component[img] == "x", 0, 1)
    f, j = blk.image.photo[r], pb.remap[blk.image.point[r]]
    c = blk.cameras.focal_mm[blk.photos.camera[f]]
    pp = np.zeros((len(img), 2))
    for q in range(9):
        h = 1e-3 if q < 3 or q >= 6 else 1e-7
        d = np.zeros(9)
        d[q] = h
        up = project(eo[f] + d[:6], xyz[j] + d[6:], c, pp)[np.arange(len(img)), k]
        dn = project(eo[f] - d[:6], xyz[j] - d[6:], c, pp)[np.arange(len(img)), k]
        col = 6 * f + q if q < 6 else 6 * nf + 3 * j + (q - 6)
        a[img, col] = (up - dn) / (2 * h)
    ctl = np.flatnonzero(m.image_row < 0)
    comp = np.array(["XYZ".index(c) for c in m.component[ctl]])
    a[ctl, 6 * nf + 3 * pb.remap[m.control_index[ctl]] + comp] = 1.0
    q, _ = np.linalg.qr(a / m.sigma[:, None])
    return 1.0 - np.sum(q**2, axis=1)


def test_redundancy_numbers_equal_numerical_dense():
    plan = analyse_design(design_block(study_plan(4, 3), ControlLayout(spacing=1.5)))
    r_ref = _numerical_redundancy(plan)
    r = plan.observations["redundancy"].to_numpy()
    assert np.max(np.abs(r - r_ref)) < 1e-6
    assert abs(r_ref.sum() - plan.redundancy) < 1e-6


@pytest.mark.parametrize("pattern", [3, 5])
@pytest.mark.parametrize("twin", [False, True])
def test_4x4_blocks_r2x_zero_and_sum_of_r(pattern, twin):
    plan = study_plan(4, pattern)
    for i in spacings(4):
        res = analyse_design(design_block(plan, ControlLayout(spacing=i, twin=twin)))
        assert res.adjustment.iterations == 1 and res.adjustment.converged
        obs = res.image()
        assert np.max(np.abs(res.qc.quality.residual)) < 1e-9  # error-free observations
        r2x = obs[(obs["class"] == "R2") & (obs["component"] == "x")]
        assert len(r2x) > 0 and r2x["redundancy"].max() < 1e-9
        assert abs(res.sum_redundancy_numbers - res.redundancy) < 1e-8


def test_control_layouts_of_the_7x7_block():
    plan = study_plan(7, 3)
    expect = {2.0: (12, 4), 3.0: (8, 1), 6.0: (4, 1)}  # full perimeter, interior height
    for i, (n_full, n_height) in expect.items():
        blk = design_block(plan, ControlLayout(spacing=i))
        ctl = blk.points.controlled
        assert int(ctl.all(axis=1).sum()) == n_full
        assert int((ctl[:, 2] & ~ctl[:, 0]).sum()) == n_height
        full = blk.points.xyz[ctl.all(axis=1)]
        base = 0.4 * 230.0 * 10.0  # 60 % overlap, 230 mm, 1:10 000 in m
        # on the perimeter of the area between the outer nadir lines, every i bases
        assert np.all(np.isin(np.round(full[:, 0] / base, 6), np.arange(0, 6.5, i)))
        on_edge = (np.isclose(full[:, 0], 0) | np.isclose(full[:, 0], 6 * base)
                   | np.isclose(full[:, 1], 0) | np.isclose(full[:, 1], 6 * base))
        assert on_edge.all()


def test_twin_control_points_share_the_rays():
    plan = study_plan(4, 3)
    single = design_block(plan, ControlLayout(spacing=3.0))
    twin = design_block(plan, ControlLayout(spacing=3.0, twin=True))
    n_ctl = int(np.sum(single.points.role == "control"))
    assert len(twin.points) == len(single.points) + n_ctl
    idx = twin.point_index
    for pid in [p for p, r in zip(single.points.ids, single.points.role, strict=True)
                if r == "control"]:
        a, b = idx[pid], idx[pid + "T"]
        assert sorted(twin.image.photo[twin.image.point == a]) == \
            sorted(twin.image.photo[twin.image.point == b])
        d = twin.points.xyz[b] - twin.points.xyz[a]
        assert 0 < np.hypot(d[0], d[1]) < 0.05 * 920.0 and d[2] == 0


def test_project_design_does_not_depend_on_measured_values():
    """The same block with different measurement noise and blunders: the same r."""
    plan = FlightPlan(strips=3, photos_per_strip=4, side_overlap=0.6, stereo=True,
                      relief_m=30.0, seed=4)
    block, truth = simulate_block(plan)
    rng = np.random.default_rng(1)
    other = design_from_project(block)
    noisy = block.select_image(np.ones(len(block.image), bool))
    noisy.image.xy_mm = noisy.image.xy_mm + rng.normal(0, 0.005, noisy.image.xy_mm.shape)
    noisy.image.xy_mm[5, 0] += 0.2  # a blunder
    r1 = analyse_design(other).observations["redundancy"].to_numpy()
    r2 = analyse_design(design_from_project(noisy)).observations["redundancy"].to_numpy()
    assert np.max(np.abs(r1 - r2)) < 1e-3  # only the approximate tie points move a little
    eo = np.array([[truth["photos"][p][k] for k in ("X0", "Y0", "Z0", "omega", "phi", "kappa")]
                   for p in block.photos.ids])
    xyz = np.array([truth["points"][p] for p in block.points.ids])
    r3 = analyse_design(design_from_project(noisy, (eo, xyz))).observations["redundancy"]
    r4 = analyse_design(design_from_project(block, (eo, xyz))).observations["redundancy"]
    assert np.max(np.abs(r3.to_numpy() - r4.to_numpy())) < 1e-12
