"""Models formed from image coordinates by relative orientation."""

import shutil
from pathlib import Path

import numpy as np
import pytest

from baarda.errors import GeometryError
from baarda.independent import similarity
from baarda.independent.forming import form_models, model_pairs
from baarda.independent.model_problem import adjust_models
from baarda.pipeline import read_models
from baarda.simulate.aerial import FlightPlan, simulate_block

DEMO = Path(__file__).parents[2] / "examples" / "demo"


def test_noise_free_models_are_similar_to_the_terrain():
    blk, truth = simulate_block(FlightPlan(strips=2, photos_per_strip=4, noise=False,
                                           image_scale=5000))
    mb = form_models(blk)
    assert mb.n_models == 6 and len(model_pairs(blk)) == 6
    for m in range(mb.n_models):
        r = mb.obs_model == m
        x = mb.obs_xyz[r]
        xt = np.array([truth["points"].get(mb.points[j]) or
                       [truth["photos"][mb.points[j][2:]][k] for k in ("X0", "Y0", "Z0")]
                       for j in mb.obs_point[r]])
        s, rot, t = similarity.fit3d(x, xt)
        assert np.abs(xt - (t + s * x @ rot.T)).max() < 1e-8
        assert s == pytest.approx(5.0, rel=0.02)  # model at image scale: 5 m per mm
        pcs = mb.pc[mb.obs_point[r]]
        assert pcs.sum() == 2 and np.allclose(x[pcs][0], 0)


def test_formed_block_adjusts_to_the_truth():
    blk, truth = simulate_block(FlightPlan(strips=2, photos_per_strip=5, image_scale=5000,
                                           control_spacing=1, height_chains=1, seed=3))
    for cov in (False, True):
        mb = form_models(blk, covariance=cov)
        assert (mb.obs_cov is not None) == cov
        if cov:
            assert np.all(np.linalg.eigvalsh(mb.obs_cov)[:, 0] > 0)
        res = adjust_models(mb, "3d")
        assert 0.5 < res.sigma0 < 1.5
        pb = res.problem
        ok = ~mb.pc[pb.point_ids]
        tr = np.array([truth["points"][mb.points[j]] for j in pb.point_ids[ok]])
        err = (res.xyz[ok] - tr) / res.xyz_std[ok]
        assert np.sqrt(np.mean(err**2)) < 2.0


def test_datum_free_removes_the_similarity_part():
    from baarda.independent.forming import datum_free

    rng = np.random.default_rng(2)
    xyz = rng.normal(0, 50, (7, 3))
    c = xyz - xyz.mean(axis=0)
    g = np.zeros((7, 3, 7))
    g[:, [0, 1, 2], [0, 1, 2]] = 1
    g[:, 1, 3], g[:, 2, 3], g[:, 0, 4], g[:, 2, 4] = -c[:, 2], c[:, 1], c[:, 2], -c[:, 0]
    g[:, 0, 5], g[:, 1, 5], g[:, :, 6] = -c[:, 1], c[:, 0], c
    g = g.reshape(21, 7)
    a = rng.normal(size=(7, 7)) * 1e-3
    only_datum = g @ (a @ a.T) @ g.T  # a random similarity of the whole model
    np.testing.assert_allclose(datum_free(only_datum, xyz), 0, atol=1e-8)
    noise = np.eye(21) * 0.01**2
    both = datum_free(noise + only_datum, xyz)
    np.testing.assert_allclose(both, datum_free(noise, xyz), atol=1e-12)
    assert np.all(np.linalg.eigvalsh(both) > -1e-15)
    assert np.all(np.diagonal(both, axis1=1, axis2=2) < 0.01**2)


def test_singular_relative_orientation_is_a_geometry_error(tmp_path):
    """Fuzz find (issue 15): an image coordinate of 3.7e85 mm made the covariance of a
    relative orientation a numpy LinAlgError (singular matrix)."""
    shutil.copytree(DEMO, tmp_path / "demo")
    f = tmp_path / "demo" / "image_points.csv"
    lines = f.read_text().split("\n")
    parts = lines[1].split(",")
    parts[3] = "3.735227700714507e+85"
    lines[1] = ",".join(parts)
    f.write_text("\n".join(lines))
    with pytest.raises(GeometryError, match="relative orientation of photos 01001 and 01002"):
        read_models(tmp_path / "demo")
