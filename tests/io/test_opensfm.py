"""OpenSfM datasets and ODM projects (issue 20): OpenSfM's berlin example (BSD-2, copied into
tests/data with its notice), an ODM project folder with gcp_list.txt made from it, and a
simulated block written as an OpenSfM dataset."""

import json
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from pyproj import Transformer

import baarda
from baarda.block.camera import constants, model_of, parameters
from baarda.block.rotation import rodrigues, rotation_vector
from baarda.bundle.collinearity import camera_projection
from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.formats import detect
from baarda.io.opensfm import read_opensfm
from baarda.io.opensfm_files import parse_crs_line, utm_crs
from baarda.output.format_files import write_opensfm
from baarda.output.project_files import write_project
from baarda.pipeline import with_tie_coordinates
from baarda.simulate.aerial import FlightPlan, simulate_block

DATA = Path(__file__).resolve().parents[1] / "data" / "opensfm_berlin"
SIZE = 3264.0  # max(width, height) of the example's camera


@pytest.fixture(scope="module")
def block():
    return read_opensfm(DATA)


@pytest.fixture(scope="module")
def recon():
    return json.loads((DATA / "reconstruction_example.json").read_text())[0]


def opensfm_projection(recon, shot: str, xyz) -> np.ndarray:
    """OpenSfM's perspective camera, written out here: x_cam = R(r) X + t, then
    focal * (1 + k1 r^2 + k2 r^4) * (x/z, y/z), normalised by max(width, height)."""
    s, cam = recon["shots"][shot], next(iter(recon["cameras"].values()))
    p = rodrigues(s["rotation"]) @ np.asarray(xyz, float) + np.asarray(s["translation"])
    n = p[:2] / p[2]
    r2 = n @ n
    return cam["focal"] * (1 + cam["k1"] * r2 + cam["k2"] * r2 * r2) * n


def test_read(block):
    assert detect(DATA) == "opensfm"
    assert block.photos.ids == ["03.jpg", "01.jpg", "02.jpg"]
    assert len(block.image) == 3087 and len(block.points) == 1433
    assert (block.points.role == "control").sum() == 2 and len(block.gnss) == 3
    assert np.allclose(block.gnss.sigma, 5.0)
    assert block.settings.crs == "EPSG:32633" and block.frame is not None
    assert block.settings.datum == "inner"  # 1 GCP on two shots; GPS almost on a line
    assert block.cameras.model[0] == "brown_forward" and \
        block.settings.calibration_free == (("c", "k1", "k2"),)
    c = block.cameras.focal_mm[0]
    assert c == pytest.approx(0.8696658484855359 * SIZE * 0.001, rel=1e-15)
    assert "137 row(s) of shots or tracks not in the reconstruction" in block.notes[-1]


def test_frame_is_the_topocentric_frame(block):
    """reference_lla maps to the local origin; a GCP's latitude, longitude and altitude
    come back through the frame and pyproj."""
    origin = block.frame.from_local(np.zeros((1, 3)))[0]
    lon, lat, h = Transformer.from_crs("EPSG:32633", "EPSG:4979", always_xy=True).transform(
        *origin)
    assert (lat, lon, h) == pytest.approx((52.51896296296295, 13.400376851851851, 0.0),
                                          abs=1e-9)
    gcp = block.points.xyz[block.points.ids.index("gcp 0")]
    lon, lat, h = Transformer.from_crs("EPSG:32633", "EPSG:4979", always_xy=True).transform(
        *block.frame.from_local(gcp[None])[0])
    assert (lat, lon, h) == pytest.approx((52.51926834404209, 13.400703631118825,
                                           14.946108041331172), abs=1e-8)


def test_projections_reproduce_opensfm(block, recon):
    """baarda's collinearity with brown_forward at the stored values gives OpenSfM's own
    projection of every track observation (to 1e-9 px): residual RMS 1.74 px, what
    OpenSfM's bundle adjustment left."""
    pts = block.points
    rows = np.flatnonzero((pts.role[block.image.point] == "tie")
                          & np.isfinite(pts.xyz[block.image.point]).all(axis=1))
    f, _, _, _ = camera_projection(block.photos.eo, pts.xyz[block.image.point[rows]],
                                   block.image.photo[rows], parameters(block.cameras, 0),
                                   model_of("brown_forward"), constants(block.cameras, 0),
                                   block.image.xy_mm[rows])
    ours = (f - block.image.xy_mm[rows]) / 0.001  # px
    theirs = np.array([opensfm_projection(recon, block.photos.ids[block.image.photo[k]],
                                          pts.xyz[block.image.point[k]])
                       for k in rows]) * np.array([1.0, -1.0]) * SIZE \
        - block.image.xy_mm[rows] / 0.001
    assert len(rows) == 3082
    assert np.max(np.abs(ours - theirs)) < 1e-9
    assert np.sqrt(np.mean(ours**2)) == pytest.approx(1.7428507, abs=1e-6)


def test_one_point_by_hand(recon):
    """Track 773 on 02.jpg: the tracks file's coordinates against OpenSfM's projection of
    the stored point, and baarda's image coordinate in mm (y up)."""
    row = next(r.split("\t") for r in (DATA / "tracks_example.csv").read_text().splitlines()
               if r.startswith("02.jpg\t773\t"))
    xy = np.array([float(row[3]), float(row[4])])
    pred = opensfm_projection(recon, "02.jpg", recon["points"]["773"]["coordinates"])
    assert np.abs(pred - xy).max() * SIZE < 5  # px
    blk = read_opensfm(DATA)
    k = np.flatnonzero((np.array(blk.photos.ids)[blk.image.photo] == "02.jpg")
                       & (np.array(blk.points.ids)[blk.image.point] == "773"))[0]
    assert blk.image.xy_mm[k] == pytest.approx([xy[0] * SIZE * 1e-3, -xy[1] * SIZE * 1e-3])
    # the projection centre and rotation: X0 = -R^T t, R_b = R^T diag(1, -1, -1)
    s = recon["shots"]["02.jpg"]
    r = rodrigues(s["rotation"])
    assert blk.photos.eo[2, :3] == pytest.approx(-r.T @ np.array(s["translation"]))
    assert np.allclose(rotation_vector(r), s["rotation"])


def test_adjust_converges_from_the_stored_reconstruction(block):
    res = baarda.adjust(block)
    # the GPS rows left out (they fix the roll only weakly; issue 41): 1871 with them
    assert res.converged and res.redundancy == 1862
    assert res.sigma0 == pytest.approx(2.6037, abs=1e-4)  # image sigma 1 px (2.5980 with GPS)
    start = baarda.pipeline.prepare(block)
    cost0 = start.linearize(start.approximations).cost
    assert res.lin.cost <= cost0  # started there, the cost did not increase
    qc = baarda.assess(res)
    t = qc.table()
    assert not (t["kind"] == "gnss").any()  # the GPS positions are not observations here
    cal = {r["parameter"]: r for r in res.camera_table() if r["estimated"]}
    assert set(cal) == {"c", "k1", "k2"} and all(r["sigma"] > 0 for r in cal.values())
    corr = res.camera_correlations()[0]
    m = np.array(corr["matrix"])
    assert corr["parameters"] == ["c", "k1", "k2"] and np.allclose(np.diag(m), 1.0)
    assert -0.9 < m[1, 2] < -0.8  # k1 and k2


def test_control_datum_on_request():
    b = baarda.read(DATA, datum="control")
    assert b.settings.datum == "control" and (b.points.role == "control").sum() == 2


def test_command_line(tmp_path):
    out = tmp_path / "out"
    assert main(["adjust", str(DATA), "-o", str(out), "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["redundancy"] == 1862 and s["sigma0"] == pytest.approx(2.6037, abs=1e-4)
    assert s["camera_correlations"][0]["parameters"] == ["c", "k1", "k2"]
    pts = (out / "points.csv").read_text().splitlines()
    gcp = next(r for r in pts if r.startswith("gcp 0,check"))
    d = [float(v) for v in gcp.split(",")[-3:]]
    assert d == pytest.approx([-11.35, -15.11, 25.45], abs=0.05)  # 31 m from the rays
    assert main(["convert", str(DATA), "-o", str(tmp_path / "p"), "-q"]) == 0
    assert (tmp_path / "p" / "gnss.csv").is_file()
    # the native project is in the CRS (UTM 33N), with the camera id's ',' as ';'
    assert "v2 apple iphone4;1 3264 2448" in (tmp_path / "p" / "cameras.csv").read_text()
    native = baarda.read(tmp_path / "p")
    assert native.settings.crs == "EPSG:32633" and native.settings.datum == "inner"
    assert 391400 < native.gnss.xyz[0, 0] < 391500
    r = baarda.adjust(native)
    assert r.redundancy == 1862 and r.sigma0 == pytest.approx(s["sigma0"], rel=1e-9)


def odm_project(tmp_path: Path, header: str = "WGS84 UTM 33N") -> Path:
    """An ODM project folder: opensfm/ with the example's files and gcp_list.txt in UTM
    zone 33N with pixel coordinates (OpenSfM's x_n = (px + 0.5 - w/2) / max(w, h))."""
    proj = tmp_path / "odm"
    (proj / "opensfm").mkdir(parents=True)
    shutil.copy(DATA / "reconstruction_example.json", proj / "opensfm" / "reconstruction.json")
    shutil.copy(DATA / "tracks_example.csv", proj / "opensfm" / "tracks.csv")
    g = json.loads((DATA / "ground_control_points.json").read_text())
    tr = Transformer.from_crs("EPSG:4979", "EPSG:32633", always_xy=True)
    rows = [header]
    for p in g["points"]:
        if "position" not in p:
            continue
        q = p["position"]
        e, n, h = tr.transform(q["longitude"], q["latitude"], q["altitude"])
        for o in p["observations"]:
            px = o["projection"][0] * SIZE + 3264 / 2 - 0.5
            py = o["projection"][1] * SIZE + 2448 / 2 - 0.5
            rows.append(f"{e!r} {n!r} {h!r} {px!r} {py!r} {o['shot_id']} {p['id']}")
    (proj / "gcp_list.txt").write_text("\n".join(rows) + "\n")
    return proj


def test_odm_project_with_gcp_list(tmp_path, block):
    proj = odm_project(tmp_path)
    assert detect(proj) == "opensfm"
    b = baarda.read(proj)
    assert b.settings.crs == "EPSG:32633"
    for pid in ("gcp 0", "gcp 3"):
        j, k = b.points.ids.index(pid), block.points.ids.index(pid)
        assert b.points.xyz[j] == pytest.approx(block.points.xyz[k], abs=1e-6)
        assert b.image.xy_mm[b.image.point == j] == pytest.approx(
            block.image.xy_mm[block.image.point == k], abs=1e-9)
    assert len(b.image) == len(block.image) - 2  # GCP 1 has no coordinates: not in the list
    assert parse_crs_line("WGS84 UTM 32S") == "EPSG:32732"
    assert parse_crs_line("EPSG:25833") == "EPSG:25833"
    assert utm_crs(13.4, 52.5) == "EPSG:32633" and utm_crs(-70.0, -33.0) == "EPSG:32719"


def test_check_gcp(tmp_path):
    b = baarda.read(DATA, check_gcp="0")
    assert b.points.role[b.points.ids.index("gcp 0")] == "check"
    assert b.points.role[b.points.ids.index("gcp 3")] == "control"
    b = baarda.read(DATA, check_gcp="alternate")
    assert list(b.points.role[[b.points.ids.index("gcp 0"), b.points.ids.index("gcp 3")]]) \
        == ["control", "check"]
    with pytest.raises(ProjectError, match="--check-gcp: 7 is not a control point"):
        baarda.read(DATA, check_gcp=["7"])
    assert main(["adjust", str(DATA), "-o", str(tmp_path / "o"), "-q", "--check-gcp",
                 "nope"]) == 2


def copy_dataset(tmp_path: Path) -> Path:
    d = tmp_path / "ds"
    shutil.copytree(DATA, d)
    return d


@pytest.mark.parametrize("edit, message, line, column", [
    (lambda d: (d / "reconstruction_example.json").write_text("[{\"cameras\": }]"),
     "not valid JSON", 1, "character 14"),
    (lambda d: (d / "tracks_example.csv").write_text(
        (d / "tracks_example.csv").read_text().replace("0.0379803", "0.03x9803", 1)),
     "'0.03x9803' is not a number", 2, "x"),
    (lambda d: (d / "reconstruction_example.json").write_text(
        (d / "reconstruction_example.json").read_text().replace('"perspective"', '"fisheye62"')),
     "projection type fisheye62 is not supported", 5, "projection_type"),
    (lambda d: (d / "reconstruction_example.json").write_text(
        (d / "reconstruction_example.json").read_text().replace(
            '"focal": 0.8696658484855359', '"focal": -1')),
     "must be positive", 8, "focal"),
    (lambda d: (d / "reconstruction_example.json").write_text(
        (d / "reconstruction_example.json").read_text().replace(
            "1.003762767932739,", '"x",', 1)),
     "is not a number", 15, "rotation"),
])
def test_errors_name_file_line_and_field(tmp_path, edit, message, line, column):
    d = copy_dataset(tmp_path)
    edit(d)
    with pytest.raises(ProjectError, match=message) as e:
        read_opensfm(d)
    assert e.value.line == line and e.value.column == column
    assert main(["adjust", str(d), "-o", str(tmp_path / "out"), "-q"]) == 2


def test_simulated_block_reads_back_to_the_native_adjustment(tmp_path):
    """A simulated block with GNSS and check points, written as a native project and as an
    OpenSfM dataset: the same adjustment (sigma0, redundancy numbers and w to 1e-9)."""
    b, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=5, relief_m=40.0,
                                     check_points=3, height_chains=0, gnss_sigma_m=0.1,
                                     seed=11))
    write_project(b, tmp_path / "native")
    write_opensfm(with_tie_coordinates(b), tmp_path / "osfm")
    checks = [p for p, r in zip(b.points.ids, b.points.role, strict=True) if r == "check"]
    native = baarda.read(tmp_path / "native")
    osfm = baarda.read(tmp_path / "osfm", calibrate="none", sigma_px=5.0,
                       check_gcp=",".join(checks))
    assert osfm.settings.datum == "control"
    r1, r2 = baarda.adjust(native), baarda.adjust(osfm)
    assert r1.redundancy == r2.redundancy == 106
    assert r2.sigma0 == pytest.approx(r1.sigma0, rel=1e-9, abs=0)
    key = ["kind", "photo", "point", "component"]
    t1 = baarda.assess(r1).table().set_index(key).sort_index()
    t2 = baarda.assess(r2).table().set_index(key).sort_index()
    assert list(t1.index) == list(t2.index)
    assert np.abs(t1["redundancy"].to_numpy() - t2["redundancy"].to_numpy()).max() < 1e-9
    w1, w2 = t1["w"].to_numpy(float), t2["w"].to_numpy(float)
    assert np.allclose(w1, w2, rtol=0, atol=1e-6, equal_nan=True)
    m1, m2 = t1["mdb"].to_numpy(float), t2["mdb"].to_numpy(float)
    assert np.allclose(m1, m2, rtol=0, atol=1e-9, equal_nan=True)


def test_writer_refuses_what_opensfm_cannot_hold(tmp_path):
    b, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=4, seed=3))
    with pytest.raises(ValueError, match="need a horizontal position"):
        write_opensfm(with_tie_coordinates(b), tmp_path / "x")  # height-only control points
    with pytest.raises(ValueError, match="tie point.*without coordinates"):
        write_opensfm(b, tmp_path / "z")
    b2 = replace(b, imu=replace(b.imu, photo=np.array([0]), angles=np.zeros((1, 3)),
                                sigma=np.ones((1, 3))))
    with pytest.raises(ValueError, match="IMU"):
        write_opensfm(b2, tmp_path / "y")


def _written_and_read_back(tmp_path, coef, pp, model):
    """A simulated block (no noise) on one camera of `model` with coefficients `coef` and
    principal point `pp`, its image points baarda's projections of its points, written as
    an OpenSfM dataset and read back: (the cameras written, the block read, the per
    coordinate RMS of the reader's note on the stored reprojection errors [px])."""
    from baarda.block.photo_block import Cameras
    from baarda.bundle.geometry import intersect

    b, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=4, height_chains=0,
                                     noise=False, seed=4))
    cams = Cameras(b.cameras.ids, b.cameras.focal_mm, np.array([pp]),
                   np.array([model], dtype=object), np.array([coef]))
    b = replace(b, cameras=cams)
    tie = np.flatnonzero(b.points.role == "tie")
    xyz = b.points.xyz.copy()
    xyz[tie] = intersect(b, b.photos.eo, tie)
    b = replace(b, points=replace(b.points, xyz=xyz))
    f, _, _, _ = camera_projection(b.photos.eo, xyz[b.image.point], b.image.photo,
                                   parameters(cams, 0), model_of(model),
                                   constants(cams, 0), b.image.xy_mm)
    b = replace(b, image=replace(b.image, xy_mm=f))
    write_opensfm(b, tmp_path / "ds")
    cam = json.loads((tmp_path / "ds" / "reconstruction.json").read_text())[0]["cameras"]
    back = read_opensfm(tmp_path / "ds")
    note = next(n for n in back.notes if n.startswith("reprojection errors"))
    return cams, cam, back, float(re.search(r"per coordinate ([0-9.]+) px", note).group(1))


def test_brown_camera_conventions(tmp_path):
    """A brown_forward camera with every coefficient (principal point, k1-k3, p1, p2,
    aspect), written as OpenSfM's `brown`: OpenSfM's projection (OpenCV's Brown on x/z, y/z,
    y down, normalised by max(w, h)), as the reader evaluates it for its note, reproduces
    baarda's projections exactly, and the camera reads back unchanged."""
    coef = np.array([[2e-5, -3e-9, 1e-13, 4e-6, -7e-6, 2e-4]]) * np.array(
        [[153.0**2, 153.0**4, 153.0**6, 153.0, 153.0, 1.0]])  # normalised units
    cams, cam, back, rms = _written_and_read_back(tmp_path, coef[0], [0.12, -0.08],
                                                  "brown_forward")
    assert next(iter(cam.values()))["projection_type"] == "brown"
    assert rms == 0.0  # printed to 0.001 px; exactly:
    assert back.cameras.focal_mm[0] == pytest.approx(cams.focal_mm[0], rel=1e-12)
    assert back.cameras.principal_point_mm[0] == pytest.approx([0.12, -0.08], rel=1e-12)
    assert back.cameras.coefficients[0] == pytest.approx(coef[0], rel=1e-12)
    assert back.settings.calibration_free == (("c", "x0", "y0", "k1", "k2", "k3", "p1", "p2", "a"),)


@pytest.mark.parametrize("coef, pp, kind", [
    ([0.03, -0.01, 0.0, 0.0, 0.0], [0.0, 0.0], "fisheye"),
    ([0.03, -0.01, 0.004, -0.001, 2e-4], [0.12, -0.08], "fisheye_opencv"),
])
def test_fisheye_cameras(tmp_path, coef, pp, kind):
    """fisheye_forward cameras written as OpenSfM's fisheye / fisheye_opencv: OpenSfM's
    equidistant projection (as the reader evaluates it for its note) reproduces baarda's
    projections, the camera reads back unchanged and the block adjusts to zero residuals."""
    _, cam, back, rms = _written_and_read_back(tmp_path, coef, pp, "fisheye_forward")
    assert next(iter(cam.values()))["projection_type"] == kind
    assert rms == 0.0
    assert back.cameras.model[0] == "fisheye_forward"
    assert back.cameras.principal_point_mm[0] == pytest.approx(pp, abs=1e-12)
    assert back.cameras.coefficients[0, :5] == pytest.approx(coef, abs=1e-12)
    res = baarda.adjust(baarda.read(tmp_path / "ds", calibrate="none"))
    assert res.converged and np.abs(res.image_residuals).max() < 1e-6  # mm


def test_reference_lla_json_and_camera_models_json(tmp_path, block):
    """ODM keeps reference_lla.json beside the reconstruction, and a camera may come from
    camera_models.json (overridden by camera_models_overrides.json)."""
    d = copy_dataset(tmp_path)
    rec = json.loads((d / "reconstruction_example.json").read_text())
    ref = rec[0].pop("reference_lla")
    cams = rec[0].pop("cameras")
    (d / "reconstruction_example.json").write_text(json.dumps(rec))
    (d / "reference_lla.json").write_text(json.dumps(ref))
    cid = next(iter(cams))
    nominal = dict(cams[cid], focal=0.85)
    (d / "camera_models.json").write_text(json.dumps({cid: nominal}))
    b = read_opensfm(d)
    assert b.settings.crs == "EPSG:32633"
    assert np.allclose(b.points.xyz[b.points.ids.index("gcp 0")],
                       block.points.xyz[block.points.ids.index("gcp 0")], atol=1e-9)
    assert b.cameras.focal_mm[0] == pytest.approx(0.85 * SIZE * 1e-3)
    (d / "camera_models_overrides.json").write_text(json.dumps({cid: cams[cid]}))
    assert read_opensfm(d).cameras.focal_mm[0] == block.cameras.focal_mm[0]


def test_calibrate_none_replaces_the_readers_note():
    """Issue 41: with --calibrate none the notes no longer say the cameras' OpenSfM
    parameters are estimated."""
    said = [n for n in baarda.read(DATA).notes if "parameters are estimated (c, k1, k2)" in n]
    assert len(said) == 1
    b = baarda.read(DATA, calibrate="none")
    assert all(f == () for f in b.settings.calibration_free)
    assert not any("are estimated" in n for n in b.notes)


def test_berlins_statistics_do_not_depend_on_the_photo_held(block):
    """Issue 41: berlin's 3 GPS positions (gps_dop 5 m) lie close to a line and fix the roll
    about it only weakly (bundle/datum_share.py); with them as observations 7 constraints
    were more than minimal and v'Pv depended on the photo held (12,628.0373 with photo 0,
    12,628.0386 with photo 2).  The free network now leaves them out (a note says why and
    what to do), holds the 7 datum parameters by minimal constraints, and v'Pv, every w
    and every r are the same whichever photo is held."""
    from baarda.bundle.free_network import FreeBundleProblem, choose_datum
    from baarda.pipeline import assess, prepare

    p = prepare(block)
    assert len(p.block.gnss) == 0 and len(block.gnss) == 3
    note = [n for n in p.block.notes if "GNSS positions left out" in n]
    assert len(note) == 1 and "--datum control" in note[0] and "only weakly" in note[0]
    other = FreeBundleProblem(p.block, datum=choose_datum(p.block, 2), inner=True)
    assert other.datum[0] != p.datum[0]
    a, b = p.fit(), other.fit()
    assert a.converged and b.converged and a.redundancy == b.redundancy
    assert b.vtpv == pytest.approx(a.vtpv, rel=1e-9)
    qa, qb = assess(a).quality, assess(b).quality
    assert np.allclose(qa.w, qb.w, rtol=0, atol=1e-6, equal_nan=True)
    assert np.allclose(qa.redundancy_number, qb.redundancy_number, rtol=0, atol=1e-7)
    assert "statistics do not depend on the datum" in p.datum_text()
    assert a.vtpv == pytest.approx(12623.2272, abs=1e-3)  # was 12,628.037 with the GPS rows
    # carrying the datum alone, the GPS would turn the block by 134 degrees and scale it by
    # 2.1 (the best similarity of the adjusted projection centres onto them)
    from baarda.block.rotation import similarity

    sc, r, _ = similarity(a.eo[block.gnss.photo, :3], block.gnss.xyz)
    angle = np.degrees(np.arccos((np.trace(r) - 1) / 2))
    assert angle == pytest.approx(134, abs=1) and sc == pytest.approx(2.1, abs=0.05)
