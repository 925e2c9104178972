"""CRS handling: local frame round trips, checks against pyproj's own geocentric
transformation and meridian convergence, and an adjustment in a projected CRS that equals
the adjustment of the same block in the local frame."""

from dataclasses import replace

import numpy as np
import pytest
from pyproj import CRS, Proj, Transformer

from baarda.block.crs import LocalFrame, localize
from baarda.block.photo_block import Photos
from baarda.errors import ProjectError
from baarda.output.bundle_results import tables_in_crs
from baarda.pipeline import adjust
from baarda.simulate.aerial import FlightPlan, simulate_block

rng = np.random.default_rng(11)
CASES = [("EPSG:32632", np.array([520000.0, 5300000.0, 300.0]), [2000, 2000, 100]),
         ("EPSG:4979", np.array([7.5, 48.6, 300.0]), [0.02, 0.02, 100]),
         ("EPSG:4326", np.array([7.5, 48.6, 300.0]), [0.02, 0.02, 100]),
         ("EPSG:27561", np.array([999604.58, 112344.44, 139.45]), [2000, 2000, 100])]


@pytest.mark.parametrize("crs, origin, spread", CASES)
def test_round_trip(crs, origin, spread):
    f = LocalFrame(crs, origin)
    pts = origin + rng.normal(0, 1, (20, 3)) * spread
    assert np.allclose(f.from_local(f.to_local(pts)), pts, rtol=0, atol=1e-7)
    assert np.allclose(f.to_local(origin[None]), 0, atol=1e-6)
    eo = np.column_stack([pts[:5], rng.normal(0, 0.1, (5, 3))])
    back = f.eo_from_local(f.eo_to_local(eo))
    assert np.allclose(back[:, :3], eo[:, :3], atol=1e-7)
    assert np.allclose(back[:, 3:], eo[:, 3:], atol=1e-9)


def test_local_frame_against_pyproj_geocentric():
    """Distances in the local frame equal distances of pyproj's geocentric coordinates;
    'up' is the ellipsoid normal (a point 100 m above the origin is at (0, 0, 100))."""
    origin = np.array([520000.0, 5300000.0, 300.0])
    f = LocalFrame("EPSG:32632", origin)
    pts = origin + rng.normal(0, 1, (30, 3)) * [3000, 3000, 200]
    loc = f.to_local(pts)
    t = Transformer.from_crs(CRS("EPSG:32632").to_3d(), "EPSG:4978", always_xy=True)
    ecef = np.column_stack(t.transform(*pts.T))
    d_loc = np.linalg.norm(loc[:, None] - loc[None], axis=2)
    d_ecef = np.linalg.norm(ecef[:, None] - ecef[None], axis=2)
    assert np.allclose(d_loc, d_ecef, atol=1e-6)
    assert np.allclose(f.to_local(origin + [0, 0, 100.0]), [[0, 0, 100]], atol=1e-6)


def test_grid_axes_rotation_is_meridian_convergence():
    """Away from the central meridian the grid axes turn by the meridian convergence:
    pyproj's value for UTM, the closed form n (lon - lon0) for Lambert I Nord."""
    origin = np.array([300000.0, 5380000.0, 200.0])  # UTM 32N, 3 degrees west of 9 E
    f = LocalFrame("EPSG:32632", origin)
    q = f.axes(np.zeros((1, 3)))[0]
    lon, lat = Transformer.from_crs("EPSG:32632", "EPSG:4326", always_xy=True).transform(
        *origin[:2])
    gamma = Proj("EPSG:32632").get_factors(lon, lat).meridian_convergence
    turn = np.degrees(np.arctan2(q[1, 0], q[0, 0]))  # local east seen in grid axes
    assert abs(gamma) > 2 and np.isclose(turn, gamma, atol=1e-6)
    origin = np.array([999604.58, 112344.44, 139.45])  # Lambert I Nord, Strasbourg
    q = LocalFrame("EPSG:27561", origin).axes(np.zeros((1, 3)))[0]
    lon, lat = Transformer.from_crs("EPSG:27561", "EPSG:4807", always_xy=True).transform(
        *origin[:2])  # NTF (Paris), grads from the Paris meridian
    n = np.sin(np.radians(55 * 0.9))  # standard parallel 55 gon
    assert np.isclose(np.degrees(np.arctan2(q[1, 0], q[0, 0])), n * lon * 0.9, atol=1e-6)


def test_adjustment_in_projected_crs_equals_local_adjustment():
    # full XYZ control with isotropic sigmas: the weights do not depend on the frame axes
    plan = FlightPlan(strips=2, photos_per_strip=4, relief_m=30.0, seed=4, height_chains=0,
                      sigma_control_m=(0.05, 0.05, 0.05), check_points=3)
    local, truth = simulate_block(plan)
    origin = np.array([520000.0, 5300000.0, 0.0])
    frame = LocalFrame("EPSG:32632", origin)
    # the same block expressed in UTM: points and EO mapped with the frame
    pts = replace(local.points, xyz=frame.from_local(local.points.xyz))
    eo = frame.eo_from_local(local.photos.eo)
    in_crs = replace(local, points=pts, photos=Photos(local.photos.ids, local.photos.camera,
                                                      local.photos.strip, eo),
                     settings=replace(local.settings, crs="EPSG:32632"))
    loc2 = localize(in_crs)
    assert loc2.frame is not None and loc2.settings.crs == "EPSG:32632"
    res = adjust(loc2)
    ref = adjust(local)
    # a different origin makes a rigidly moved frame: same observations, same statistics
    assert np.isclose(res.sigma0, ref.sigma0, rtol=1e-7)
    assert np.allclose(res.image_residuals, ref.image_residuals, atol=1e-9)
    ph, pt = tables_in_crs(res)
    xyz_ref = frame.from_local(ref.xyz)
    assert np.allclose(pt[["X", "Y", "Z"]].to_numpy(), xyz_ref, atol=1e-5)
    # standard deviations do not depend on the local frame used: those of the reference
    # adjustment (frame at `origin`) propagated to the CRS equal the tables (frame2)
    cov = ref.factor.point_covariance() * ref.sigma0**2
    s_ref = np.sqrt(np.diagonal(frame.covariance_from_local(ref.xyz, cov), axis1=1, axis2=2))
    assert np.allclose(pt[["sigma_X", "sigma_Y", "sigma_Z"]].to_numpy(), s_ref, rtol=1e-6)
    # the Jacobian is conformal with pyproj's point scale factor k: singular values (1, k, k)
    lon, lat = Transformer.from_crs("EPSG:32632", "EPSG:4326", always_xy=True).transform(
        xyz_ref[:, 0], xyz_ref[:, 1])
    k = Proj("EPSG:32632").get_factors(lon, lat).meridional_scale
    # (k on the ellipsoid, times R / (R + h) at ellipsoidal height h; R the Gaussian radius)
    a, e2 = 6378137.0, 0.00669437999014
    phi = np.radians(lat)
    w = 1 - e2 * np.sin(phi) ** 2
    rg = a * np.sqrt(1 - e2) / w
    kh = k * rg / (rg + xyz_ref[:, 2])
    sv = np.linalg.svd(frame.jacobian(ref.xyz), compute_uv=False)
    assert np.allclose(sv[:, 0], 1, atol=1e-7)
    assert np.allclose(sv[:, 1:], kh[:, None], rtol=2e-8)
    assert not np.allclose(k, 1.0, atol=1e-5)
    eo_ref = frame.eo_from_local(ref.eo)
    assert np.allclose(ph[["X0", "Y0", "Z0"]].to_numpy(), eo_ref[:, :3], atol=1e-5)
    unit = {"gon": np.pi / 200, "deg": np.pi / 180, "rad": 1.0}[local.settings.angle_unit]
    assert np.allclose(ph[["omega", "phi", "kappa"]].to_numpy() * unit, eo_ref[:, 3:],
                       atol=1e-9)
    # check points: differences in the CRS are the local ones turned and scaled by J
    sel = (pt["role"] == "check").to_numpy()
    assert sel.sum() == 3
    d_loc = (ref.xyz - local.points.xyz[ref.problem.point_ids])[sel]
    j = frame.jacobian(ref.xyz[sel])
    assert np.allclose(pt.loc[sel, ["dX", "dY", "dZ"]].to_numpy(),
                       np.einsum("nij,nj->ni", j, d_loc), atol=1e-6)
    del truth


def test_refusals():
    with pytest.raises(ProjectError, match="not a coordinate"):
        LocalFrame("EPSG:999999", [0, 0, 0])
    with pytest.raises(ProjectError, match="ellipsoidal"):
        LocalFrame("EPSG:2154+5720", [700000, 6600000, 100])
