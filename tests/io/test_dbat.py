"""DBAT script reader, checked against DBAT's own results (tests/data, DBAT licence).

* SXB aerial block: baarda's adjustment with DBAT's set-up reproduces sigma0, redundancy,
  v^T P v and every exterior orientation value and standard deviation of
  dbat_script/result/report.txt (the numbers are parsed from DBAT's report here).
* camcal: with DBAT's calibrated camera and camera stations, the image residuals of DBAT's
  top-residual listing are reproduced (lens model, aspect and principal point convention).
"""

import re
from pathlib import Path

import numpy as np
import pytest

from baarda.block.camera import ideal_image_coordinates
from baarda.bundle.collinearity import project, project_with_jacobians
from baarda.errors import ProjectError
from baarda.io.dbat import read_dbat
from baarda.pipeline import adjust

DATA = Path(__file__).resolve().parents[1] / "data"
SXB = DATA / "dbat_sxb_aerial" / "dbat_script"
CAMCAL = DATA / "dbat_camcal_closerange" / "dbat_script"


def _decimals(s: str) -> int:
    return len(s.split(".")[1]) if "." in s else 0


def parse_report(path: Path) -> dict:
    """Sigma0, redundancy, last error and per-photo EO (value, std as printed strings)."""
    text = path.read_text()
    out = {"sigma0": re.search(r"Sigma0:\s+(\S+)", text).group(1),
           "redundancy": int(re.search(r"Redundancy\s+(\d+)", text).group(1)),
           "last_error": re.search(r"Last error:\s+(\S+)", text).group(1),
           "n_params": int(re.search(r"Number of params:\s+(\d+)", text).group(1)),
           "n_obs": int(re.search(r"Number of observations:\s+(\d+)", text).group(1))}
    photos = {}
    for block in re.split(r"\n\s+Photo \d+: ", text)[1:]:
        name = block.split("\n")[0].strip().rsplit(".", 1)[0]
        vals = {}
        for key in ("Omega", "Phi", "Kappa", "Xc", "Yc", "Zc"):
            m = re.search(key + r":\s+Value:\s+(\S+).*?\n\s+Deviation:\s+(\S+)", block, re.S)
            vals[key] = (m.group(1), m.group(2))
        photos[name] = vals
    out["photos"] = photos
    for kind in ("Ctrl", "Check"):
        sec = text.split(f"{kind} measurements")[1].split("Posterior")[1].split("Diff")[0]
        rows = [r.split(",") for r in sec.strip().split("\n")[1:]]
        out[kind] = {r[0].strip(): [s.strip() for s in r[1:7]] for r in rows}
    return out


@pytest.fixture(scope="module")
def sxb():
    block = read_dbat(SXB / "sxb.xml")
    return block, adjust(block)


def test_sxb_counts(sxb):
    block, res = sxb
    ref = parse_report(SXB / "result" / "report.txt")
    assert len(block.photos) == 5 and len(block.image) == 1196 and len(block.points) == 381
    assert np.sum(block.points.role == "control") == 14
    assert sorted(np.asarray(block.points.ids)[block.points.role == "check"]) == ["351", "410"]
    assert res.n_observations == ref["n_obs"] == 2434
    assert res.n_unknowns == ref["n_params"] == 1173
    assert res.redundancy == ref["redundancy"] == 1261


def test_sxb_sigma0_and_vtpv(sxb):
    _, res = sxb
    ref = parse_report(SXB / "result" / "report.txt")
    assert res.converged
    assert f"{res.sigma0:.4f}" == ref["sigma0"]
    # DBAT's 'error' is the norm of the weighted residual vector
    assert f"{np.sqrt(res.vtpv):.4f}" == ref["last_error"]


def test_sxb_exterior_orientation_matches_dbat(sxb):
    """Every EO value and std of DBAT's report, to the printed digits.

    Values may differ by at most one unit of the last printed digit (DBAT stops at a
    relative change of 1e-6; one value, Yc of 8938, differs by 0.7e-6 m from the converged
    solution), standard deviations by half a unit (rounding).
    """
    block, res = sxb
    ref = parse_report(SXB / "result" / "report.txt")
    assert set(ref["photos"]) == set(block.photos.ids)
    deg = 180 / np.pi
    std = res.eo_std
    worst = 0.0
    for i, pid in enumerate(block.photos.ids):
        r = ref["photos"][pid]
        ours = dict(zip(("Xc", "Yc", "Zc", "Omega", "Phi", "Kappa"),
                        zip(np.r_[res.eo[i, :3], res.eo[i, 3:] * deg],
                            np.r_[std[i, :3], std[i, 3:] * deg], strict=True), strict=True))
        for key, (val, sd) in ours.items():
            v_ref, s_ref = r[key]
            unit = 10.0 ** -_decimals(v_ref)
            worst = max(worst, abs(val - float(v_ref)) / unit)
            assert abs(val - float(v_ref)) <= 1.0 * unit, (pid, key, val, v_ref)
            sunit = 10.0 ** -_decimals(s_ref)
            assert abs(sd - float(s_ref)) <= 0.5 * sunit + 1e-12, (pid, key, sd, s_ref)
    assert worst < 1.0


def test_sxb_control_and_check_points_match_dbat(sxb):
    block, res = sxb
    ref = parse_report(SXB / "result" / "report.txt")
    xyz, std = res.points_xyz(), np.full((len(block.points), 3), np.nan)
    std[res.problem.point_ids] = res.xyz_std
    index = block.point_index
    for kind in ("Ctrl", "Check"):
        for pid, vals in ref[kind].items():
            j = index[pid]
            for k in range(3):
                unit = 10.0 ** -_decimals(vals[k])
                assert abs(xyz[j, k] - float(vals[k])) <= 0.5 * unit + 1e-9, (pid, k)
                s = float(vals[3 + k])
                assert abs(std[j, k] - s) <= 0.5 * 10.0 ** -_decimals(vals[3 + k]) + 1e-12, \
                    (pid, k, std[j, k], s)


def test_sxb_pixel_conversion():
    """x_mm - pp = 0.006 x_px - 26.577, y_mm - pp = 38.811 - 0.006 y_px (DBAT's rule)."""
    block = read_dbat(SXB / "sxb.xml")
    rel = block.image.xy_mm - block.cameras.principal_point_mm[0]
    j = block.point_index["317"]
    row = np.flatnonzero((block.image.point == j) & (block.image.photo == 0))[0]
    assert np.allclose(rel[row], [0.006 * 5007.6667 - 26.577, 38.811 - 0.006 * 7275.6667])
    assert np.allclose(block.image.sigma_mm[row], 0.5 * 0.006)


def test_camcal_residuals_match_dbat_listing():
    """Backward Brown model, aspect and pp convention against DBAT's top residuals.

    With DBAT's calibrated camera and stations fixed, each object point is estimated by
    least squares from its rays (control points fixed at their coordinates); the residuals
    (projection - corrected observation, in pixels of height py, as DBAT prints them) then
    equal DBAT's listing.
    """
    block = read_dbat(CAMCAL / "camcaldemo.xml", camera=CAMCAL / "result" / "c4040z.xml",
                      stations=CAMCAL / "result" / "camera_stations.txt")
    cam = block.cameras
    ideal = ideal_image_coordinates(block)
    im = block.image
    eo = block.photos.eo[im.photo]
    c = np.full(len(im), cam.focal_mm[0])
    pp = np.tile(cam.principal_point_mm[0], (len(im), 1))
    res = np.zeros_like(ideal)
    for j in range(len(block.points)):
        rows = np.flatnonzero(im.point == j)
        x = block.points.xyz[j].copy()
        if not np.isfinite(x).all():
            x = np.array([0.5, 0.5, 0.0])
            for _ in range(30):
                p, _, jp = project_with_jacobians(eo[rows], np.tile(x, (len(rows), 1)),
                                                  c[rows], pp[rows])
                dx = np.linalg.lstsq(jp.reshape(-1, 3), (ideal[rows] - p).ravel(),
                                     rcond=None)[0]
                x += dx
                if np.abs(dx).max() < 1e-14:
                    break
        res[rows] = project(eo[rows], np.tile(x, (len(rows), 1)), c[rows], pp[rows]) \
            - ideal[rows]
    py = 5.43764 / 1704
    res_px = res / py
    # overall RMS as DBAT reports it (0.216 px)
    assert f"{np.sqrt(np.mean(np.sum(res_px**2, axis=1))):.3f}" == "0.216"
    photo = {p: i for i, p in enumerate(block.photos.ids)}
    names = [f"P82500{20 + int(k)}" for k in range(1, 22)]
    assert all(n in photo for n in names)
    listing = np.genfromtxt(CAMCAL / "result" / "top_residuals.txt", delimiter=",",
                            comments="#")
    for pid, img, _, _, rx, ry, _ in listing:
        i = photo[names[int(img) - 1]]
        row = np.flatnonzero((im.point == block.point_index[str(int(pid))]) &
                             (im.photo == i))[0]
        assert np.allclose(res_px[row], [rx, ry], atol=2e-5), (pid, img, res_px[row], rx, ry)


def _write(tmp: Path, xml: str, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (tmp / name).write_text(text)
    p = tmp / "p.xml"
    p.write_text(xml)
    return p


XML = """<?xml version="1.0"?>
<document dbat_script_version="1.0">
  <input>
    <ctrl_pts><file format="id,label,x,y,z,sx,sy,sz">ctrl.txt</file></ctrl_pts>
    <images><file format="id,path">img.txt</file></images>
    <image_pts><file format="id,im,x,y" sxy="0.5">pts.txt</file></image_pts>
    <cameras><camera><unit>mm</unit><sensor>53.148,77.976</sensor><image>8858,12996</image>
      <cc>123.9</cc><pp>26.5,38.8</pp>{extra}</camera></cameras>
  </input>
</document>
"""
FILES = {"ctrl.txt": "# id, name, X, Y, Z, sx, sy, sz\n1, a, 0, 0, 0, 0.02, 0.02, 0.04\n",
         "img.txt": "1, a.jpg\n2, b.jpg\n",
         "pts.txt": "# id, image, x, y\n1, 1, 100.5, 200.25\n1, 2, 300, 400\n"}


def test_minimal_script_reads(tmp_path):
    b = read_dbat(_write(tmp_path, XML.format(extra=""), FILES))
    assert b.photos.ids == ["a", "b"] and len(b.image) == 2


def test_unreadable_file_names(tmp_path):
    """Fuzz find (issue 15): a file name too long for the file system escaped as OSError."""
    name = "1" * 400 + ".txt"
    p = _write(tmp_path, XML.format(extra="").replace("pts.txt", name), FILES)
    with pytest.raises(ProjectError, match="cannot be read") as e:
        read_dbat(p)
    assert Path(e.value.path).name == name


def test_no_image_measurements(tmp_path):
    """Fuzz find (issue 15): empty image point files gave a block with a NaN image sigma
    (the median of nothing, with numpy's RuntimeWarning)."""
    p = _write(tmp_path, XML.format(extra=""), dict(FILES, **{"pts.txt": "# id, im, x, y\n"}))
    with pytest.raises(ProjectError, match="no image measurements") as e:
        read_dbat(p)
    assert e.value.path == str(p) and e.value.line == 6


@pytest.mark.parametrize("change, where", [
    ({"pts.txt": "1, 1, 100.5, abc\n"}, ("pts.txt", 1, "y")),
    ({"pts.txt": "1, 1, 100.5\n"}, ("pts.txt", 1, None)),
    ({"pts.txt": "1, 1, 1, 2\n1, 9, 3, 4\n"}, ("pts.txt", 2, "im")),
    ({"pts.txt": "1, 1, 1, 2\n1, 1, 3, 4\n"}, ("pts.txt", 2, "id")),  # both lines named
    ({"ctrl.txt": "1, a, 0, 0, 0, 1, 1, 1\n2, b, 1, 1, 1, 1, 1, 1\n1, a, 0, 0, 0, 1, 1, 1\n"},
     ("ctrl.txt", 3, "id")),
    ({"ctrl.txt": "1, a, 0, 0, 0, 0.02, -1, 0.04\n"}, ("ctrl.txt", 1, None)),
    ({"ctrl.txt": "1, a, 0, 0, nan, 0.02, 0.02, 0.04\n"}, ("ctrl.txt", 1, "z")),
])
def test_malformed_files_name_file_line_field(tmp_path, change, where):
    files = dict(FILES, **change)
    with pytest.raises(ProjectError) as e:
        read_dbat(_write(tmp_path, XML.format(extra=""), files))
    name, line, col = where
    assert Path(e.value.path).name == name
    assert e.value.line == line
    if col:
        assert e.value.column == col


@pytest.mark.parametrize("extra, text", [
    ("<skew>0.1</skew>", "skew"), ("<unit>px</unit>", "unit"), ("<model>0</model>", "model"),
    ("<K>1,2,3,4</K>", "K"),
])
def test_malformed_camera(tmp_path, extra, text):
    xml = XML.format(extra=extra).replace("<unit>mm</unit>", "") if "unit" in extra else \
        XML.format(extra=extra)
    with pytest.raises(ProjectError, match=text):
        read_dbat(_write(tmp_path, xml, FILES))


def test_broken_xml_names_line(tmp_path):
    p = _write(tmp_path, XML.format(extra="").replace("</cameras>", "</camera>"), FILES)
    with pytest.raises(ProjectError) as e:
        read_dbat(p)
    assert e.value.line == 8 and "XML" in str(e.value)


@pytest.mark.parametrize("encoding", ["nan", "shift_jis", "rot13", "idna"])
def test_xml_declaration_naming_an_unreadable_encoding(tmp_path, encoding):
    """Fuzz find (issue 15): expat's LookupError / ValueError escaped (unknown encodings,
    codecs that are not text encodings, multi-byte encodings)."""
    xml = XML.format(extra="").replace('"1.0"?>', f'"1.0" encoding="{encoding}"?>', 1)
    p = _write(tmp_path, xml, FILES)
    with pytest.raises(ProjectError, match="encoding") as e:
        read_dbat(p)
    assert e.value.path == str(p) and e.value.line == 1


# ---------------------------------------------------------------- operations (issue 28)
OPS_XML = """<?xml version="1.0"?>
<document dbat_script_version="1.0">
  <input>
    <ctrl_pts><file format="id,label,x,y,z,sx,sy,sz">ctrl.txt</file></ctrl_pts>
    <images><file format="id,path">img.txt</file></images>
    {prior}
    <image_pts><file format="id,im,x,y" sxy="0.5">pts.txt</file></image_pts>
    <cameras>{camera}</cameras>
  </input>
  <operations>
{ops}
  </operations>
</document>
"""
CAMERA = ("<camera><unit>mm</unit><sensor>53.148,77.976</sensor><image>8858,12996</image>"
          "<focal>120</focal><cc>123.9</cc><pp>26.5,38.8</pp><K>1e-5,0,0</K></camera>")


def _script(tmp, ops="", prior="", camera=CAMERA, files=None):
    return _write(tmp, OPS_XML.format(ops=ops, prior=prior, camera=camera), files or FILES)


def _estimate(io: str) -> str:
    return f"<operation><set_bundle_estimate_params><io>{io}</io>" \
           "</set_bundle_estimate_params></operation>"


@pytest.mark.parametrize("io, free", [
    ("<all>true</all><skew>false</skew>",
     ("c", "x0", "y0", "b1", "k1", "k2", "k3", "p1", "p2")),
    # DBAT's romabundledemo: 5 parameters, not the 8 that lowercase-only flags gave
    ("<all>true</all><aspect>false</aspect><skew>false</skew><P>false</P><K3>false</K3>",
     ("c", "x0", "y0", "k1", "k2")),
    ("<K2>true</K2>", ("k1", "k2")),  # Kn true: K1..Kn
    ("<K>true</K><K2>false</K2>", ("k1",)),  # Kn false: Kn..K3
    ("<P1>true</P1>", ("p1", "p2")),  # P1 and P2 go together
    ("<all>true</all><P2>false</P2>", ("c", "x0", "y0", "b1", "b2", "k1", "k2", "k3")),
    ("<cc>true</cc><px>true</px>", ("c", "x0")),
    ("<c>a comment</c><pp>true</pp>", ("x0", "y0")),
    ("true", ("c", "x0", "y0", "b1", "b2", "k1", "k2", "k3", "p1", "p2")),
    ("false", None),
])
def test_estimation_flags_as_dbat_applies_them(tmp_path, io, free):
    b = read_dbat(_script(tmp_path, _estimate(io)))
    if free is None:
        assert b.settings.calibration_free is None and b.cameras.model[0] == "brown_backward"
    else:
        assert b.settings.calibration_free == (free,) and b.cameras.model[0] == "dbat3"


@pytest.mark.parametrize("io, field", [
    ("<all>true</all><p>false</p>", "p"),  # DBAT's tags are case sensitive
    ("<K4>true</K4>", "K4"), ("<cc>yes</cc>", "cc"), ("<focal>true</focal>", "focal"),
])
def test_bad_estimation_flags_name_the_line(tmp_path, io, field):
    p = _script(tmp_path, _estimate(io))
    with pytest.raises(ProjectError) as e:
        read_dbat(p)
    assert e.value.path == str(p) and e.value.line == 11 and e.value.column == field


def test_initial_values(tmp_path):
    """set_initial_values: 'default' puts the camera constant to the focal length and
    removes the distortion (it matters for what is not estimated); numbers are taken."""
    def initial(io):
        ops = f"<operation><set_initial_values><io>{io}</io></set_initial_values></operation>"
        return read_dbat(_script(tmp_path, ops)).cameras

    assert initial("<all>loaded</all>").focal_mm[0] == 123.9
    cam = initial("<all>default</all>")
    assert cam.focal_mm[0] == 120 and cam.model[0] == "none"
    assert np.allclose(cam.principal_point_mm[0], 0)  # the sensor centre
    assert initial("<cc>125.5</cc>").focal_mm[0] == 125.5
    with pytest.raises(ProjectError, match="expected 2 numbers"):
        initial("<pp>1</pp>")


def test_camera_file_and_command_line_camera(tmp_path):
    """<cameras><file>: the camera of a DBAT camera file (was: 'no <cameras><camera> in
    <input>', also with --camera)."""
    (tmp_path / "cam.xml").write_text(
        '<?xml version="1.0"?><document dbat_camera_version="1.0"><cameras>'
        + CAMERA + "</cameras></document>")
    b = read_dbat(_script(tmp_path, camera="<file>cam.xml</file>"))
    assert b.cameras.focal_mm[0] == 123.9
    other = tmp_path / "other.xml"
    other.write_text((tmp_path / "cam.xml").read_text().replace("123.9", "150"))
    (tmp_path / "cam.xml").unlink()  # the script's camera file is not needed then
    b = read_dbat(tmp_path / "p.xml", camera=other)
    assert b.cameras.focal_mm[0] == 150
    with pytest.raises(ProjectError, match="not found") as e:
        read_dbat(tmp_path / "p.xml")
    assert Path(e.value.path).name == "cam.xml"
    p = _script(tmp_path, camera="<c>none</c>")
    with pytest.raises(ProjectError, match="neither a <camera> nor a camera <file>"):
        read_dbat(p)


PRIOR = '<prior_eo><file format="id,x,y,z,omega,phi,kappa" units="{u}">eo.txt</file></prior_eo>'


def test_prior_orientations(tmp_path):
    files = dict(FILES, **{"eo.txt": "# id, x, y, z, o, p, k\n2, 10, 20, 1000, 1, 2, 90\n"})
    b = read_dbat(_script(tmp_path, prior=PRIOR.format(u="degrees"), files=files))
    assert np.isnan(b.photos.eo[0]).all()  # image 1 is not listed: resected
    assert np.allclose(b.photos.eo[1], [10, 20, 1000, *np.radians([1, 2, 90])])
    assert any("prior orientations of 1 image(s)" in n for n in b.notes)
    b = read_dbat(_script(tmp_path, prior=PRIOR.format(u="gon"), files=files))
    assert np.isclose(b.photos.eo[1, 5], np.pi / 2 * 90 / 100)


@pytest.mark.parametrize("units, eo, where", [
    ("", "2, 10, 20, 1000, 1, 2, 90\n", ("p.xml", 6, "units")),
    ("deg", "2, 10, 20, 1000, 1, 2, 90\n", ("p.xml", 6, "units")),
    ("degrees", "7, 10, 20, 1000, 1, 2, 90\n", ("eo.txt", 1, "id")),
    ("degrees", "2, 10, 20, 1000, 1, 2\n", ("eo.txt", 1, None)),
])
def test_bad_prior_orientations(tmp_path, units, eo, where):
    files = dict(FILES, **{"eo.txt": eo})
    p = _script(tmp_path, prior=PRIOR.format(u=units), files=files)
    with pytest.raises(ProjectError) as e:
        read_dbat(p)
    assert (Path(e.value.path).name, e.value.line, e.value.column) == where


def test_datum_setting(tmp_path):
    ops = ('<operation><set_datum ref_cam="2" ref_base="z">depend</set_datum></operation>')
    b = read_dbat(_script(tmp_path, ops))
    assert b.settings.datum == "free" and b.settings.free_datum == ("b", "z")
    for bad, field in (('ref_cam="3"', "ref_cam"), ('ref_base="up"', "ref_base")):
        p = _script(tmp_path, f"<operation><set_datum {bad}>depend</set_datum></operation>")
        with pytest.raises(ProjectError) as e:
            read_dbat(p)
        assert e.value.column == field and e.value.line == 11


def test_dbat_datum_rule_chooses_the_largest_signed_offset():
    """DBAT's 'depend' holds the coordinate with the largest signed offset from the
    reference image, baarda's own choice the largest absolute one."""
    from dataclasses import replace

    from baarda.bundle.free_network import choose_datum
    from baarda.simulate.aerial import FlightPlan, simulate_block

    b = simulate_block(FlightPlan(strips=2, photos_per_strip=3, seed=1))[0]
    eo = b.photos.eo.copy()
    eo[:, :3] = [[0, 0, 0], [5, 0, 0], [-9, 0, 0], [0, 2, 0], [0, 0, 1], [0, 0, 3]]
    b = replace(b, photos=replace(b.photos, eo=eo))
    assert choose_datum(b) == (0, 2, 0)
    ids = b.photos.ids
    for base, expect in (("longest", (0, 1, 0)), ("y", (0, 3, 1)), ("z", (0, 5, 2))):
        s = replace(b.settings, datum="free", free_datum=(ids[0], base))
        assert choose_datum(replace(b, settings=s)) == expect
    s = replace(b.settings, datum="free", free_datum=(ids[2], "x"))
    assert choose_datum(replace(b, settings=s)) == (2, 1, 0)
