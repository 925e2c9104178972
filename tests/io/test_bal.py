"""BAL reader/writer.  The three BAL problems have no stated licence and are not copied:
the tests read them from ../shared/data/bal and skip, saying so, when absent.  Their
adjustment is compared with pycolmap/Ceres in benchmarks/bench_bal.py (not a test)."""

import bz2
from pathlib import Path

import numpy as np
import pytest
from bal_reference import _synthetic, bal_residuals

from baarda.bundle.collinearity import camera_depth
from baarda.bundle.free_network import adjust_free
from baarda.bundle.geometry import predicted_observations
from baarda.errors import ProjectError
from baarda.io.bal import (
    BalProblem,
    bal_to_block,
    bal_with_block,
    read_bal,
    rodrigues,
    rotation_vector,
)
from baarda.output.format_files import write_bal

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "bal"
# README of the data set: counts and the initial reprojection errors (median, mean, 99th
# percentile, max [px]) and share of observations behind the camera, computed there
CASES = [("problem-49-7776-pre.txt.bz2", 49, 7776, 31843, (1.48, 4.21, 27.3, 53), 0.001),
         ("problem-16-22106-pre.txt.bz2", 16, 22106, 83718, (4.42, 6.72, 36.3, 76), 0.0),
         ("problem-21-11315-pre.txt.bz2", 21, 11315, 36455, (2.98, 8.07, 71.4, 103), 0.0)]


@pytest.mark.parametrize("name, ncam, npt, nobs, errors, behind", CASES)
def test_read_real_problems(name, ncam, npt, nobs, errors, behind):
    path = SHARED / name
    if not path.is_file():
        pytest.skip(f"BAL file (no licence stated, not in the repository) not found: {path}")
    p = read_bal(path)
    assert p.cameras.shape == (ncam, 9) and p.points.shape == (npt, 3)
    assert len(p.obs_xy) == nobs
    assert np.all(np.bincount(p.obs_camera, minlength=ncam) > 0)
    assert np.all(np.bincount(p.obs_point, minlength=npt) > 0)
    b = bal_to_block(p)
    im = b.image
    xy = predicted_observations(b)
    e = np.hypot(*((xy - im.xy_mm) / 0.001).T)
    assert np.allclose(e, np.hypot(*bal_residuals(p).T), rtol=1e-9, atol=1e-9)
    stats = (np.median(e), np.mean(e), np.percentile(e, 99), np.max(e))
    for got, ref in zip(stats, errors, strict=True):
        digits = len(str(ref).split(".")[1]) if "." in str(ref) else 0
        assert abs(got - ref) <= 0.5 * 10.0**-digits + 1e-9, (got, ref)
    share = np.mean(camera_depth(b.photos.eo[im.photo], b.points.xyz[im.point]) <= 0)
    assert round(share, 3) == behind


def test_synthetic_round_trips(tmp_path):
    p = _synthetic()
    for r in rodrigues(p.cameras[:, :3]):
        assert np.allclose(rodrigues(rotation_vector(r)), r, atol=1e-12)
    write_bal(p, tmp_path / "p.txt.bz2")
    q = read_bal(tmp_path / "p.txt.bz2")
    for f in ("cameras", "points", "obs_camera", "obs_point", "obs_xy"):
        assert np.array_equal(getattr(p, f), getattr(q, f)), f
    b = bal_to_block(q)
    back = bal_with_block(q, b.photos.eo, b.points.xyz)
    assert np.allclose(rodrigues(back.cameras[:, :3]), rodrigues(q.cameras[:, :3]), atol=1e-12)
    assert np.allclose(back.cameras[:, 3:], q.cameras[:, 3:], atol=1e-12)


def test_synthetic_adjustment_minimises_the_bal_cost():
    p = _synthetic(seed=2)
    rng = np.random.default_rng(5)
    start = BalProblem(p.cameras.copy(), p.points + rng.normal(0, 0.02, p.points.shape),
                       p.obs_camera, p.obs_point, p.obs_xy)
    start.cameras[:, 3:6] += rng.normal(0, 0.02, (len(p.cameras), 3))
    res = adjust_free(bal_to_block(start))
    assert res.converged
    out = bal_with_block(start, res.eo, res.points_xyz(), res.cameras)  # f, k1, k2 estimated
    r = bal_residuals(out)  # residuals of the written-back problem, BAL's own formula
    assert np.isclose(np.sum(r**2), res.vtpv, rtol=1e-9)
    # a minimum: the BAL cost grows in every perturbed direction of the points
    for k in range(3):
        for h in (1e-4, -1e-4):
            pert = BalProblem(out.cameras, out.points.copy(), out.obs_camera, out.obs_point,
                              out.obs_xy)
            pert.points[:, k] += h
            assert np.sum(bal_residuals(pert) ** 2) > np.sum(r**2)
    # 0.5 px noise: sigma0 (in px, sigma 1 px) near 0.5
    assert 0.4 < res.sigma0 < 0.6


GOOD = "2 1 2\n0 0 1.5 -2.5\n1 0 3.5 4.5\n" + "0\n0\n0\n0\n0\n-5\n500\n0\n0\n" \
       "0\n0.1\n0\n1\n0\n-5\n500\n0\n0\n" + "0.1\n0.2\n0.3\n"


@pytest.mark.parametrize("text, line, field", [
    ("2 1\n" + GOOD[6:], 1, None),
    (GOOD.replace("0 0 1.5 -2.5", "0 0 1.5"), 2, None),
    (GOOD.replace("1 0 3.5 4.5", "2 0 3.5 4.5"), 3, "camera_index"),
    (GOOD.replace("1 0 3.5 4.5", "1 7 3.5 4.5"), 3, "point_index"),
    (GOOD.replace("1 0 3.5 4.5", "1 0 x 4.5"), 3, "observation"),
    (GOOD.replace("\n500\n", "\nabc\n", 1), 10, "camera"),
    (GOOD.replace("\n500\n", "\n-500\n", 1), 10, "f"),
    (GOOD.replace("0\n0\n0\n0\n0\n-5", "1e200\n0\n0\n0\n0\n-5", 1), 4, "r"),  # fuzz
    (GOOD[:-4], 23, None),
    (GOOD + "7\n", 25, None),
])
def test_malformed(tmp_path, text, line, field):
    path = tmp_path / "p.txt"
    path.write_text(text)
    with pytest.raises(ProjectError) as e:
        read_bal(path)
    assert e.value.line == line and e.value.column == field


def test_form_feed_is_no_line_end(tmp_path):
    """Fuzz find (issue 15): a form feed or vertical tab (whitespace inside a line) split
    the line, so later lines were misnumbered or misread."""
    path = tmp_path / "p.txt"
    path.write_text(GOOD.replace("0 0 1.5 -2.5\n", "0 0 1.5 -2.5\x0c\n")
                    .replace("\n500\n", "\n\x0b500\n", 1))
    assert np.allclose(read_bal(path).cameras[0, 6], 500)
    path.write_text(GOOD.replace("0 0 1.5 -2.5\n", "0 0 1.5 -2.5\x0c\n")
                    .replace("\n500\n", "\nabc\n", 1))
    with pytest.raises(ProjectError) as e:
        read_bal(path)
    assert e.value.line == 10 and e.value.column == "camera"


def test_minimal_file_and_bad_bzip2(tmp_path):
    (tmp_path / "p.txt").write_text(GOOD)
    p = read_bal(tmp_path / "p.txt")
    assert p.cameras.shape == (2, 9) and np.allclose(p.points, [[0.1, 0.2, 0.3]])
    (tmp_path / "q.txt.bz2").write_bytes(bz2.compress(GOOD.encode())[:20])
    with pytest.raises(ProjectError, match="bzip2"):
        read_bal(tmp_path / "q.txt.bz2")


def test_calibrate_chosen_for_the_run_is_noted(tmp_path):
    """`--calibrate none` on a BAL file (whose reader notes f, k1, k2 as estimated): the
    notes say what the run does instead of what the reader said."""
    from baarda.pipeline import read

    p = tmp_path / "problem-6-60.txt"
    write_bal(_synthetic(seed=2), p)
    assert any("estimated, as the BAL problems intend" in n for n in read(p).notes)
    b = read(p, calibrate="none")
    assert all(f == () for f in b.settings.calibration_free)
    # issue 41: the reader's "estimated" is replaced, not contradicted
    assert not any("estimated" in n for n in b.notes)
    assert any(n.startswith("calibrate none (every camera's parameters held at the input's "
                            "values): chosen for this run") for n in b.notes)
    b = read(p, calibrate=["c", "k1"])
    assert b.settings.calibration_free[0] == ("c", "k1")
    assert any(n.startswith("calibrate c, k1: chosen for this run") for n in b.notes)
