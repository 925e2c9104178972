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
    ({"pts.txt": "1, 1, 1, 2\n1, 1, 3, 4\n"}, ("p.xml", None, None)),
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
