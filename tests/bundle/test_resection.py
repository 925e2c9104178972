"""Approximate orientations by space resection (bundle/resection.py)."""

from pathlib import Path

import numpy as np
import pytest

from baarda.bundle.collinearity import project
from baarda.bundle.resection import orient_block, resect
from baarda.errors import GeometryError
from baarda.io.dbat import read_dbat, read_dbat_stations
from baarda.pipeline import adjust, with_approximations
from baarda.simulate.aerial import FlightPlan, simulate_block

CAMCAL = Path(__file__).resolve().parents[1] / "data" / "dbat_camcal_closerange" / "dbat_script"
rng = np.random.default_rng(2)


@pytest.mark.parametrize("spread_z", [0.0, 40.0, 400.0])
def test_resect_recovers_exact_orientation(spread_z):
    """Noise-free: planar (homography), mildly and strongly non-planar (DLT) point sets."""
    eo = np.array([100.0, 200.0, 1500.0, 0.05, -0.03, 1.2])
    xyz = np.column_stack([rng.uniform(-600, 800, 12), rng.uniform(-500, 900, 12),
                           rng.uniform(0, 1, 12) * spread_z])
    c = 153.0
    xy = project(np.tile(eo, (12, 1)), xyz, np.full(12, c), np.zeros((12, 2)))
    got, rms = resect(xy, xyz, c)
    assert rms < 1e-9
    assert np.allclose(got[:3], eo[:3], atol=1e-6) and np.allclose(got[3:], eo[3:], atol=1e-9)


def test_orient_block_from_control_and_ties():
    b, truth = simulate_block(FlightPlan(strips=2, photos_per_strip=4, seed=6, noise=False))
    b.photos.eo = np.full_like(b.photos.eo, np.nan)
    eo = orient_block(b)
    true = np.array([[truth["photos"][p][k] for k in ("X0", "Y0", "Z0", "omega", "phi",
                                                      "kappa")] for p in b.photos.ids])
    assert np.allclose(eo[:, :3], true[:, :3], atol=1e-3)
    assert np.allclose(eo[:, 3:], true[:, 3:], atol=1e-6)


def test_camcal_convergent_photos_from_four_coplanar_control_points():
    """DBAT's calibration network: 21 convergent photos, 4 control points on a plane.  The
    resection (nominal camera) lands near DBAT's final stations, and from it (with DBAT's
    calibrated camera) the adjustment reaches the solution it reaches from the stations."""
    b = with_approximations(read_dbat(CAMCAL / "camcaldemo.xml"))
    st = read_dbat_stations(CAMCAL / "result" / "camera_stations.txt")
    ref = np.array([st[str(i + 1)] for i in range(len(b.photos))])
    assert np.abs(b.photos.eo[:, :3] - ref[:, :3]).max() < 0.1  # m, at 1.5-2 m distance
    d = (b.photos.eo[:, 3:] - ref[:, 3:] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(d).max() < np.radians(3)
    cam = CAMCAL / "result" / "c4040z.xml"
    r1 = adjust(read_dbat(CAMCAL / "camcaldemo.xml", camera=cam))
    r2 = adjust(read_dbat(CAMCAL / "camcaldemo.xml", camera=cam,
                          stations=CAMCAL / "result" / "camera_stations.txt"))
    da = (r1.eo[:, 3:] - r2.eo[:, 3:] + np.pi) % (2 * np.pi) - np.pi  # kappa may wrap
    assert r1.converged and np.allclose(r1.eo[:, :3], r2.eo[:, :3], atol=1e-8)
    assert np.allclose(da, 0, atol=1e-9)
    assert np.isclose(r1.sigma0, r2.sigma0, rtol=1e-10)


def test_too_few_points():
    with pytest.raises(GeometryError, match="at least 3"):
        resect(np.zeros((2, 2)), np.zeros((2, 3)), 100.0)
