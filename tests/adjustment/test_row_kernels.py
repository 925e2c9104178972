"""The kernels of issue 32 against the code they stand for: the parallel assembly of the
normal equations equals the serial loop to the last bit; the cofactor blocks of the
observations formed row by row (large blocks) equal NumPy's products to rounding, with and
without a border; the step check equals camera_depth > 0; the brown_forward linearisation
equals collinearity.camera_projection to the last bit."""

import numpy as np
import pytest
from bal_reference import _synthetic

import baarda.adjustment.schur as schur
from baarda.adjustment import schur_kernels as kernels
from baarda.block.camera import with_calibration
from baarda.block.rotation import rotation_and_derivatives, rotation_matrix
from baarda.bundle.collinearity import camera_depth, camera_projection
from baarda.bundle.projection_kernel import all_in_front
from baarda.io.bal import bal_to_block
from baarda.pipeline import prepare
from baarda.simulate.aerial import FlightPlan, simulate_block


@pytest.fixture(scope="module")
def problems():
    aerial, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=6, seed=4))
    return {"aerial": prepare(aerial),
            "self-calibration (border)": prepare(with_calibration(aerial, "brown", "all")),
            "BAL (9 unknowns per photo)": prepare(bal_to_block(_synthetic(seed=2)))}


@pytest.mark.parametrize("name", ["aerial", "self-calibration (border)",
                                  "BAL (9 unknowns per photo)"])
def test_parallel_assembly_is_the_serial_one_bit_for_bit(problems, name):
    pb = problems[name]
    s = pb.system
    lin = pb.linearize(pb.approximations)
    out = []
    for parallel in (False, True):
        hff, gf = np.zeros((s.nf, s.b, s.b)), np.zeros((s.nf, s.b))
        hpp, gp = np.zeros((s.np, s.d, s.d)), np.zeros((s.np, s.d))
        hfp = np.zeros((len(s.order), s.b, s.d))
        if parallel:
            kernels.assemble_parallel(s.order, s.ptr, s.frame_ptr, s.frame_obs, lin.jf, lin.jp,
                                      lin.w, lin.e, hfp, hff, gf, hpp, gp)
        else:
            kernels.assemble(s.order, s.frame, s.point_sorted, lin.jf, lin.jp, lin.w, lin.e,
                             hfp, hff, gf, hpp, gp)
        out.append((hff, gf, hpp, gp, hfp))
    assert np.abs(out[0][0]).max() > 0 and np.abs(out[0][4]).max() > 0
    for a, b in zip(*out, strict=True):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("name", ["aerial", "self-calibration (border)",
                                  "BAL (9 unknowns per photo)"])
def test_cofactor_blocks_row_by_row_equal_numpys(problems, name, monkeypatch):
    res = problems[name].fit()
    ref = schur.SchurFactor(res.problem.system, res.lin).adjusted_cofactors()
    monkeypatch.setattr(schur, "ROW_BY_ROW", 0)  # the kernel, whatever the size
    new = schur.SchurFactor(res.problem.system, res.lin).adjusted_cofactors()
    for a, b in zip(ref, new, strict=True):
        assert a.shape == b.shape
        assert np.allclose(a, b, rtol=1e-12, atol=1e-14 * np.abs(a).max(initial=0.0))
    assert not np.array_equal(ref[0], np.zeros_like(ref[0]))


def test_the_step_check_is_camera_depth(problems):
    pb = problems["aerial"]
    eo, xyz = pb.approximations[0][:, :6], pb.approximations[1].copy()
    rot = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
    args = (rot, np.ascontiguousarray(eo[:, :3]), pb.obs_photo, pb.obs_point)
    assert all_in_front(*args, xyz) and pb.admissible(pb.approximations)
    j = pb.obs_point[17]
    xyz[j] = 2 * eo[pb.obs_photo[17], :3] - xyz[j]  # mirrored through the camera: behind
    depth = camera_depth(eo, xyz[pb.obs_point], pb.obs_photo)
    assert (depth <= 0).any() and not all_in_front(*args, xyz)
    assert not pb.admissible((pb.approximations[0], xyz))


def test_brown_forward_kernel_is_the_model_code(problems):
    pb = problems["BAL (9 unknowns per photo)"]
    eo, xyz, params, _ = pb._split(pb.approximations)
    rot = rotation_and_derivatives(eo[:, 3], eo[:, 4], eo[:, 5])
    points = xyz[pb.obs_point]
    f, je, jp, jpar = pb.image_rows.evaluate(eo, points, params, rot)
    model, cams, sel, photo, observed, which, k = pb.image_rows.groups[0]
    assert model.name == "brown_forward" and len(sel) == len(f)
    p = np.array([params[i] for i in cams], float)[which]
    ref = camera_projection(eo, points, photo, p, model, k, observed, rot)
    # the same numbers to the last bit (NumPy's 2 x 2 products are OpenBLAS's fused
    # multiply-adds on this machine: the kernel rounds them as they do)
    assert np.array_equal(f, ref[0])
    assert np.array_equal(je[:, :, :6], ref[1]) and np.array_equal(jp, ref[2])
    # the free c, k1, k2 of each photo's own camera in its columns 6, 7, 8
    cal = pb.calibration
    idx = cal.free_index[0]
    assert list(idx) == [0, 3, 4]
    assert np.array_equal(je[:, :, 6:], ref[3][:, :, idx])
    assert jpar.shape[0] == 0  # no border: d f / d(camera parameters) not formed
