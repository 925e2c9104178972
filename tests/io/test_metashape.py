"""Agisoft Metashape / PhotoScan: the project (.psz, .psx) and cameras XML readers, the
metashape writer, DBAT's sxb.psz reproduced (issue 38)."""

from __future__ import annotations

import io
import json
import re
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
from pyproj import CRS

import baarda
from baarda.block.camera_models import MODELS, apply_forward
from baarda.bundle.collinearity import project
from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.formats import detect, read_any
from baarda.output.metashape_files import write_metashape

DATA = Path(__file__).resolve().parents[1] / "data" / "metashape_sxb"
PSZ = DATA / "sxb.psz"
CONTROL = DATA / "ctrlpts-weighted-raw.txt"


def dbat_report() -> tuple[float, int]:
    text = (DATA / "sxb-dbatreport.txt").read_text()
    return (float(re.search(r"Sigma0:\s+([\d.]+)", text).group(1)),  # type: ignore[union-attr]
            int(re.search(r"Redundancy\s+(\d+)", text).group(1)))  # type: ignore[union-attr]


def summary(folder: Path) -> dict:
    return json.loads((folder / "summary.json").read_text())


def test_sxb_psz_is_read_as_dbat_reads_it():
    b = baarda.read(PSZ)
    assert detect(PSZ) == "metashape"
    assert (len(b.photos), len(b.image), len(b.points)) == (5, 4066, 1182)  # 8132 / 2 IP
    assert list(b.points.role).count("control") == 16
    assert list(b.points.role).count("tie") == 1166
    # fx 20656.5 px of 0.006 mm; cx, cy absolute (PhotoScan 1.2): 4430 - 8858/2, 6468 - 12996/2
    assert b.cameras.focal_mm[0] == pytest.approx(123.939)
    assert b.cameras.principal_point_mm[0] == pytest.approx([0.006, 0.18])
    assert b.settings.calibration_free == ((),)  # the sensor is fixed
    marks = b.points.role[b.image.point] == "control"
    assert marks.sum() == 47
    assert np.allclose(b.image.sigma_mm[marks], 0.1 * 0.006)  # accuracy_projections
    assert np.allclose(b.image.sigma_mm[~marks], 1.0 * 0.006)  # accuracy_tiepoints
    k = b.point_index["216"]
    assert b.points.xyz[k] == pytest.approx([999604.58, 112344.443, 139.453])
    assert b.points.sigma[k] == pytest.approx([0.02, 0.02, 0.04])
    # the chunk's own orientations fit its tie points: the image residuals are pixels
    cam = b.photos.camera[b.image.photo]
    xy = project(b.photos.eo, b.points.xyz[b.image.point], b.cameras.focal_mm[cam],
                 b.cameras.principal_point_mm[cam], b.image.photo)
    rms_px = np.sqrt(np.mean((xy - b.image.xy_mm)[~marks] ** 2)) / 0.006
    assert rms_px < 1.0


@pytest.mark.slow
def test_sxb_psz_reproduces_dbats_report(tmp_path):
    """The acceptance: `baarda adjust sxb.psz` gives DBAT's sigma0 0.710294 and redundancy
    4604.  With DBAT's control file the same once its 410 is the project's 413 (B4.13);
    the file as published has 15 matching points (README.txt: DBAT kept 413 as control)."""
    sigma0, r = dbat_report()
    assert (sigma0, r) == (0.710294, 4604)
    assert main(["adjust", str(PSZ), "-o", str(tmp_path / "plain"), "-q"]) == 0
    s = summary(tmp_path / "plain")
    assert s["redundancy"] == r
    assert s["sigma0"] == pytest.approx(sigma0, abs=5e-7)
    fixed = tmp_path / "ctrl.txt"
    fixed.write_text(CONTROL.read_text().replace("410, B4.13", "413, B4.13"))
    assert main(["adjust", str(PSZ), "--control", str(fixed), "-o", str(tmp_path / "c"),
                 "-q"]) == 0
    s = summary(tmp_path / "c")
    assert s["redundancy"] == r
    assert s["sigma0"] == pytest.approx(sigma0, abs=5e-7)
    assert main(["adjust", str(PSZ), "--control", str(CONTROL), "-o", str(tmp_path / "raw"),
                 "-q"]) == 0
    assert summary(tmp_path / "raw")["redundancy"] == r - 3  # 413 a tie point, 410 unused


# ---- a cameras XML written from the format's description, with Metashape's camera model

SENSOR = dict(w=6000, h=4000, pixel=0.0039, f=4100.0, cx=12.5, cy=-7.25, b1=3.5,
              k1=-0.12, k2=0.05, k3=-0.01, p1=4e-4, p2=-2e-4)


def metashape_uv(xc: np.ndarray, s=SENSOR) -> np.ndarray:
    """Metashape's projection (its manual's "frame camera" model) of camera-frame points."""
    x, y = xc[:, 0] / xc[:, 2], xc[:, 1] / xc[:, 2]
    r2 = x * x + y * y
    rad = 1 + s["k1"] * r2 + s["k2"] * r2 ** 2 + s["k3"] * r2 ** 3
    xd = x * rad + s["p1"] * (r2 + 2 * x * x) + 2 * s["p2"] * x * y
    yd = y * rad + s["p2"] * (r2 + 2 * y * y) + 2 * s["p1"] * x * y
    return np.column_stack([s["w"] / 2 + s["cx"] + xd * (s["f"] + s["b1"]),
                            s["h"] / 2 + s["cy"] + yd * s["f"]])


def rot(a, b, c) -> np.ndarray:
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    return (np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
            @ np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
            @ np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]]))


def spec_xml(folder: Path, *, transform=True, bad_rotation=False, unknown_camera=False) -> Path:
    """A cameras XML as Metashape's File > Export > Cameras writes it (Metashape 1.5+: one
    <chunk>, sensors with an adjusted calibration f/cx/cy/b1/k/p, camera transforms in the
    chunk frame, the chunk <transform>, markers with reference and accuracies, projections
    in <frames><frame><markers>), its projections computed with Metashape's model."""
    from pyproj import Transformer

    rng = np.random.default_rng(7)
    s = SENSOR
    # Metashape: with a CRS the chunk transform maps to earth-centred coordinates (WGS 84);
    # the chunk's local frame here: east-north-up at 48 N, 9 E, turned about up and scaled
    lon, lat = np.radians(9.0), np.radians(48.0)
    enu = np.array([[-np.sin(lon), np.cos(lon), 0.0],
                    [-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)],
                    [np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)]])
    t_chunk = np.array(Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
                       .transform(9.0, 48.0, 300.0))
    r_chunk, scale = enu.T @ rot(0.0, 0.0, 1.3), 40.0
    to_utm = Transformer.from_crs("EPSG:4978", CRS("EPSG:32632").to_3d(), always_xy=True)
    centres = np.array([[-1.0, -0.5, 2.0], [0.0, -0.5, 2.0], [1.0, -0.5, 2.0],
                        [-1.0, 0.5, 2.0], [0.0, 0.5, 2.0], [1.0, 0.5, 2.0]])
    # cameras look down the chunk's -z: camera z forward = chunk -z (x right, y down)
    r_cams = [np.diag([1.0, -1.0, -1.0]) @ rot(*rng.normal(0, 0.02, 3)) for _ in centres]
    local = np.column_stack([rng.uniform(-1.2, 1.2, 10), rng.uniform(-0.8, 0.8, 10),
                             rng.uniform(-0.1, 0.1, 10)])
    world = np.column_stack(to_utm.transform(*(t_chunk + scale * local @ r_chunk.T).T))
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', '<document version="1.5.0">',
             '  <chunk label="spec" enabled="true">', '    <sensors next_id="1">',
             '      <sensor id="0" label="cam" type="frame">',
             f'        <resolution width="{s["w"]}" height="{s["h"]}"/>',
             f'        <property name="pixel_width" value="{s["pixel"]}"/>',
             f'        <property name="pixel_height" value="{s["pixel"]}"/>',
             '        <property name="focal_length" value="16"/>',
             '        <property name="layer_index" value="0"/>',
             '        <calibration type="frame" class="initial">',
             f'          <resolution width="{s["w"]}" height="{s["h"]}"/>',
             '          <f>4000</f>', '          <date>2024-05-01T10:00:00Z</date>',
             '        </calibration>',
             '        <calibration type="frame" class="adjusted">',
             f'          <resolution width="{s["w"]}" height="{s["h"]}"/>']
    lines += [f"          <{k}>{s[k]!r}</{k}>" for k in ("f", "cx", "cy", "b1", "k1", "k2",
                                                       "k3", "p1", "p2")]
    lines += ['        </calibration>', '      </sensor>', '    </sensors>',
              '    <cameras next_id="7" next_group_id="0">']
    for k, (c, r) in enumerate(zip(centres, r_cams, strict=True)):
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = r, c
        if bad_rotation and k == 2:
            m[0, 0] *= 1.5
        lines += [f'      <camera id="{k}" sensor_id="0" label="IMG_{k:04d}.JPG">',
                  "        <transform>" + " ".join(repr(float(v)) for v in m.ravel())
                  + "</transform>", "      </camera>"]
    lines += ['      <camera id="6" sensor_id="0" label="IMG_0006.JPG" enabled="false"/>',
              "    </cameras>", '    <markers next_id="10">']
    for j, xyz in enumerate(world):
        enabled = "false" if j in (3, 7) else "true"
        lines += [f'      <marker id="{j}" label="gcp{j}">',
                  '        <reference ' + " ".join(f'{a}="{float(v)!r}"' for a, v in
                                                  zip("xyz", xyz, strict=True))
                  + f' sxy="0.02" sz="0.05" enabled="{enabled}"/>', "      </marker>"]
    lines += ["    </markers>", '    <frames next_id="1">', '      <frame id="0">',
              "        <markers>"]
    for j, x in enumerate(local):
        lines.append(f'          <marker marker_id="{j}">')
        for k, (c, r) in enumerate(zip(centres, r_cams, strict=True)):
            xc = (x - c) @ r
            uv = metashape_uv(xc[None])[0]
            if xc[2] > 0 and 0 < uv[0] < s["w"] and 0 < uv[1] < s["h"]:
                lines.append(f'            <location camera_id="{k}" pinned="true" '
                             f'x="{float(uv[0])!r}" y="{float(uv[1])!r}"/>')
        lines.append("          </marker>")
    if unknown_camera:
        lines += ['          <marker marker_id="0">',
                  '            <location camera_id="17" pinned="true" x="1" y="2"/>',
                  "          </marker>"]
    lines += ["        </markers>", "      </frame>", "    </frames>"]
    if transform:
        lines += ["    <transform>", "      <rotation locked=\"false\">"
                  + " ".join(repr(float(v)) for v in r_chunk.ravel()) + "</rotation>",
                  "      <translation>" + " ".join(repr(float(v)) for v in t_chunk)
                  + "</translation>", f"      <scale>{scale!r}</scale>", "    </transform>"]
    lines += ['    <reference>PROJCS["WGS 84 / UTM zone 32N",GEOGCS["WGS 84",'
              'AUTHORITY["EPSG","4326"]],AUTHORITY["EPSG","32632"]]</reference>',
              "    <settings>", '      <property name="accuracy_tiepoints" value="1"/>',
              '      <property name="accuracy_markers" value="0.005"/>',
              '      <property name="accuracy_projections" value="0.5"/>',
              "    </settings>", "  </chunk>", "</document>"]
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "cameras.xml"
    path.write_text("\n".join(lines) + "\n")
    return path


def forward_xy(b) -> np.ndarray:
    """baarda's projection of the block's points (brown_forward camera) [mm]."""
    cam = b.photos.camera[b.image.photo]
    c, pp = b.cameras.focal_mm[cam], b.cameras.principal_point_mm[cam]
    ideal = project(b.photos.eo, b.points.xyz[b.image.point], c, pp, b.image.photo)
    n, _ = apply_forward(MODELS["brown_forward"], (ideal - pp) / c[:, None],
                         b.cameras.coefficients[cam])
    return pp + c[:, None] * n


def test_cameras_xml_is_metashapes_camera_model(tmp_path):
    b = read_any(spec_xml(tmp_path))
    assert detect(tmp_path / "cameras.xml") == "metashape-xml"
    assert b.photos.ids == [f"IMG_{k:04d}" for k in range(6)]  # the disabled one left out
    assert b.settings.crs == "EPSG:32632"
    assert list(b.points.role).count("check") == 2
    assert b.points.sigma[0] == pytest.approx([0.02, 0.02, 0.05])
    assert np.allclose(b.image.sigma_mm, 0.5 * SENSOR["pixel"])
    assert b.settings.calibration_free == (("c", "x0", "y0", "k1", "k2", "k3", "p1", "p2", "a"),)
    # the observations are Metashape's projections; baarda's model reproduces them
    assert np.abs(forward_xy(b) - b.image.xy_mm).max() / SENSOR["pixel"] < 1e-6


def test_round_trip_of_the_project_through_the_writer(tmp_path):
    a = baarda.read(PSZ)
    write_metashape(a, tmp_path / "ms")
    b = baarda.read(tmp_path / "ms" / "cameras.xml")  # bundle.out beside it joins
    assert b.photos.ids == a.photos.ids and b.points.ids[:16] == a.points.ids[:16]
    assert np.allclose(b.photos.eo, a.photos.eo, rtol=1e-9, atol=0)
    assert np.array_equal(b.points.xyz, a.points.xyz)
    assert np.array_equal(b.points.role, a.points.role)
    assert np.array_equal(b.points.sigma, a.points.sigma, equal_nan=True)

    def rows(x):
        o = np.lexsort((x.image.photo, x.image.point))
        return x.image.photo[o], x.image.point[o], x.image.xy_mm[o], x.image.sigma_mm[o]

    for u, v in zip(rows(a), rows(b), strict=True):
        assert np.allclose(u, v, rtol=0, atol=1e-12)
    for attr in ("focal_mm", "principal_point_mm", "coefficients", "pixel_mm"):
        assert np.allclose(getattr(b.cameras, attr), getattr(a.cameras, attr), rtol=1e-12)
    # an explicit --tie-points file of another name, through the command
    other = tmp_path / "elsewhere"
    other.mkdir()
    shutil.copy(tmp_path / "ms" / "cameras.xml", other / "cameras.xml")
    shutil.copy(tmp_path / "ms" / "bundle.out", other / "ties.out")
    assert len(baarda.read(other / "cameras.xml").image) == 47  # the markers' block
    c = read_any(other / "cameras.xml", tie_points=other / "ties.out")
    assert len(c.image) == len(a.image)


def test_round_trip_with_distortion(tmp_path):
    a = read_any(spec_xml(tmp_path / "in"))
    notes = write_metashape(a, tmp_path / "out")
    assert any("image size" in n for n in notes)
    b = read_any(tmp_path / "out" / "cameras.xml")
    assert b.settings.crs == "EPSG:32632" and b.frame is not None and a.frame is not None
    assert np.allclose(b.frame.origin_ecef, a.frame.origin_ecef, rtol=0, atol=1e-6)
    assert np.allclose(b.frame.from_local(b.points.xyz), a.frame.from_local(a.points.xyz),
                       rtol=0, atol=1e-6)
    assert np.allclose(b.photos.eo, a.photos.eo, rtol=1e-9, atol=1e-6)
    assert np.allclose(b.image.xy_mm, a.image.xy_mm, rtol=0, atol=1e-12)
    assert np.array_equal(b.image.point, a.image.point)
    assert np.allclose(b.cameras.coefficients, a.cameras.coefficients, rtol=1e-12)
    assert np.allclose(b.cameras.focal_mm, a.cameras.focal_mm, rtol=1e-12)
    assert b.settings.calibration_free == a.settings.calibration_free


def test_convert_writes_metashape(tmp_path):
    assert main(["convert", str(PSZ), "--to", "metashape", "-o", str(tmp_path / "o"),
                 "-q"]) == 0
    assert {p.name for p in (tmp_path / "o").iterdir()} >= {"cameras.xml", "bundle.out",
                                                            "list.txt"}


def _psx(tmp_path: Path) -> Path:
    """sxb.psz repacked in Metashape 1.4's nested layout (.psx + .files folder)."""
    src = zipfile.ZipFile(PSZ)
    doc = src.read("doc.xml").decode()
    start, end = doc.index("<chunk "), doc.index("</chunk>") + len("</chunk>")
    chunk = doc[start:end]
    fs, fe = chunk.index("<frames"), chunk.index("</frames>") + len("</frames>")
    frame_block = chunk[fs:fe]
    inner = frame_block[frame_block.index("<frame id"):frame_block.rindex("</frame>") + 8]
    pc_s, pc_e = inner.index("<point_cloud>"), inner.index("</point_cloud>") + 14
    cloud = inner[pc_s:pc_e]

    def zipped(files: dict[str, bytes]) -> bytes:
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w") as z:
            for k, v in files.items():
                z.writestr(k, v)
        return buf.getvalue()

    plys = {n: src.read(n) for n in src.namelist() if n.endswith(".ply")}
    cloud_zip = zipped({"doc.xml": cloud.encode(), **plys})
    frame_doc = (inner[:pc_s] + '<point_cloud path="point_cloud/point_cloud.zip"/>'
                 + inner[pc_e:]).replace("<frame id=\"0\">", "<frame version=\"1.2.0\">")
    frame_zip = zipped({"doc.xml": frame_doc.encode()})
    chunk_doc = chunk[:fs] + '<frames next_id="1"><frame id="0" path="0/frame.zip"/></frames>' \
        + chunk[fe:]
    chunk_zip = zipped({"doc.xml": chunk_doc.encode()})
    proj = zipped({"doc.xml": b'<?xml version="1.0"?><document version="1.4.0"><chunks>'
                   b'<chunk id="0" path="0/chunk.zip"/></chunks></document>'})
    files = tmp_path / "sxb.files"
    (files / "0" / "0" / "point_cloud").mkdir(parents=True)
    (files / "project.zip").write_bytes(proj)
    (files / "0" / "chunk.zip").write_bytes(chunk_zip)
    (files / "0" / "0" / "frame.zip").write_bytes(frame_zip)
    (files / "0" / "0" / "point_cloud" / "point_cloud.zip").write_bytes(cloud_zip)
    psx = tmp_path / "sxb.psx"
    psx.write_text('<?xml version="1.0"?><document version="1.4.0" '
                   'path="{projectname}.files/project.zip"/>\n')
    return psx


def test_psx_nested_layout_reads_the_same_block(tmp_path):
    psx = _psx(tmp_path)
    assert detect(psx) == "metashape"
    a, b = baarda.read(PSZ), baarda.read(psx)
    assert np.array_equal(a.photos.eo, b.photos.eo)
    assert np.array_equal(a.image.xy_mm, b.image.xy_mm)
    assert a.points.ids == b.points.ids
    # Metashape 1.4's .psz: the .files folder zipped, project.zip's doc.xml as its doc.xml
    files = tmp_path / "sxb.files"
    nested = tmp_path / "nested.psz"
    with zipfile.ZipFile(nested, "w") as z:
        z.writestr("doc.xml", zipfile.ZipFile(files / "project.zip").read("doc.xml"))
        for f in files.rglob("*.zip"):
            if f.name != "project.zip":
                z.write(f, f.relative_to(files).as_posix())
    c = baarda.read(nested)
    assert np.array_equal(a.image.xy_mm, c.image.xy_mm) and a.points.ids == c.points.ids
    (files / "0" / "0" / "frame.zip").unlink()
    with pytest.raises(ProjectError, match="frame"):
        baarda.read(psx)


def _exit2(args, capsys, *words):
    assert main(args) == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err, err
    assert "Traceback" not in err


def test_bad_input_is_exit_2_naming_file_and_element(tmp_path, capsys):
    out = str(tmp_path / "o")
    cut = tmp_path / "cut.psz"
    cut.write_bytes(PSZ.read_bytes()[:100000])
    _exit2(["convert", str(cut), "--format", "metashape", "-o", out], capsys, "cut.psz")
    x = spec_xml(tmp_path / "u", unknown_camera=True)
    _exit2(["convert", str(x), "-o", out], capsys, str(x), "camera 17", "camera_id")
    x = spec_xml(tmp_path / "t", transform=False)
    _exit2(["convert", str(x), "-o", out], capsys, str(x), "no <transform>")
    x = spec_xml(tmp_path / "r", bad_rotation=True)
    _exit2(["convert", str(x), "-o", out], capsys, str(x), "camera 2", "not a rotation",
           "column 'transform'")
    x = spec_xml(tmp_path / "v")
    x.write_text(x.read_text().replace('<marker id="5" label="gcp5">', ""))
    _exit2(["convert", str(x), "-o", out], capsys, str(x), "line")
    # a projection of a marker the chunk does not define
    x = spec_xml(tmp_path / "w")
    x.write_text(x.read_text().replace('<marker marker_id="4">', '<marker marker_id="44">'))
    _exit2(["convert", str(x), "-o", out], capsys, str(x), "marker 44")
    # tie points of another chunk
    y = spec_xml(tmp_path / "y")
    write_metashape(baarda.read(PSZ), tmp_path / "sxb")
    _exit2(["convert", str(y), "--tie-points", str(tmp_path / "sxb" / "bundle.out"), "-o",
            out], capsys, "bundle.out")
    _exit2(["convert", str(PSZ), "--tie-points", str(tmp_path / "sxb" / "bundle.out"), "-o",
            out], capsys, "--tie-points")


@pytest.mark.slow
def test_metashape_xml_with_markers_and_bundler_adjusts(tmp_path):
    """A Metashape XML with control and check markers plus its Bundler file adjusts; the
    markers are control and check points with their given accuracies; the result folder
    written back as Metashape and re-adjusted gives the same sigma0 (1e-6)."""
    from dataclasses import replace

    import pandas as pd

    a = baarda.read(PSZ)
    role = a.points.role.copy()
    sigma = a.points.sigma.copy()
    for pid in ("305", "511"):
        k = a.point_index[pid]
        role[k], sigma[k] = "check", np.nan
    a = replace(a, points=replace(a.points, role=role, sigma=sigma))
    write_metashape(a, tmp_path / "xml")
    out = tmp_path / "adj"
    assert main(["adjust", str(tmp_path / "xml" / "cameras.xml"), "-o", str(out), "-q"]) == 0
    pts = pd.read_csv(out / "points.csv", dtype={"point": str})
    assert sorted(pts.point[pts.role == "check"]) == ["305", "511"]
    assert (pts.role == "control").sum() == 14
    obs = pd.read_csv(out / "observations.csv", dtype={"point": str})
    ctrl = obs[obs.kind == "control"]
    assert len(ctrl) == 42
    assert np.allclose(ctrl.sigma[ctrl.component != "Z"], 0.02)
    assert np.allclose(ctrl.sigma[ctrl.component == "Z"], 0.04)
    s = summary(out)
    assert s["n_check_points"] == 2 and s["redundancy"] == 4604 - 6
    # the result folder goes back out as Metashape and re-adjusts to the same sigma0
    assert main(["convert", str(out), "--to", "metashape", "-o", str(tmp_path / "back"),
                 "-q"]) == 0
    assert main(["adjust", str(tmp_path / "back" / "cameras.xml"), "-o",
                 str(tmp_path / "again"), "-q"]) == 0
    again = summary(tmp_path / "again")
    assert again["redundancy"] == s["redundancy"]
    assert again["sigma0"] == pytest.approx(s["sigma0"], rel=1e-6)


def test_ply_tables():
    from baarda.io.ply import read_ply

    head = b"ply\nformat %s 1.0\nelement vertex 2\nproperty float x\nproperty int id\nend_header\n"
    rows = np.array([(1.5, 7), (-2.25, 9)], dtype=[("x", "<f4"), ("id", "<i4")])
    t = read_ply(head % b"binary_little_endian" + rows.tobytes(), "a.ply")
    assert t["x"].tolist() == [1.5, -2.25] and t["id"].tolist() == [7, 9]
    big = rows.astype([("x", ">f4"), ("id", ">i4")])
    assert read_ply(head % b"binary_big_endian" + big.tobytes(), "b.ply")["id"].tolist() == [7, 9]
    assert read_ply(head % b"ascii" + b"1.5 7\n-2.25 9\n", "c.ply")["x"].tolist() == [1.5, -2.25]
    with pytest.raises(ProjectError, match="c.ply: the file ends early: 2 rows"):
        read_ply(head % b"ascii" + b"1.5 7\n", "c.ply")
    with pytest.raises(ProjectError, match="a.ply: the file ends early: 2 rows of 8 bytes"):
        read_ply(head % b"binary_little_endian" + rows.tobytes()[:12], "a.ply")
    with pytest.raises(ProjectError, match="not a PLY file"):
        read_ply(b"PK\x03\x04", "d.ply")


def test_chunk_rotation_and_dropped_terms(tmp_path, capsys):
    x = spec_xml(tmp_path / "a")
    text = x.read_text()
    rot = re.search(r"<rotation locked=\"false\">([^<]*)</rotation>", text).group(1)  # type: ignore[union-attr]
    x.write_text(text.replace(rot, " ".join(["1"] * 9)))
    _exit2(["convert", str(x), "-o", str(tmp_path / "o")], capsys, str(x),
           "the chunk's <rotation> is not a rotation", "column 'rotation'")
    y = spec_xml(tmp_path / "b")
    y.write_text(y.read_text().replace("<k3>", "<k4>0.002</k4><b2>0.5</b2><k3>", 1).replace(
        '<camera id="1" sensor_id="0" label="IMG_0001.JPG">', '<camera id="1" sensor_id="0" '
        'label="IMG_0001.JPG"><reference x="1" y="2" z="3" enabled="true"/>'))
    b = read_any(y)
    assert any("k4 = 0.002, b2 = 0.5 not held" in n for n in b.notes)
    assert "not read: 1 camera reference position(s) (GNSS)" in b.notes
    w = spec_xml(tmp_path / "d")
    w.write_text(w.read_text().replace('AUTHORITY["EPSG","32632"]]</reference>',
                                       'AUTHORITY["EPSG","9707"]]</reference>'))
    _exit2(["convert", str(w), "-o", str(tmp_path / "o")], capsys, str(w), "EPSG:9707",
           "compound")
    z = spec_xml(tmp_path / "c")
    z.write_text(z.read_text().replace('pinned="true"', 'pinned="false"', 3))
    assert any(n.startswith("3 marker projection(s) not pinned") for n in read_any(z).notes)


def test_component_transform_and_sxyz(tmp_path):
    """Metashape 1.6+ keeps the transform in <components>; accuracies as sxyz."""
    x = spec_xml(tmp_path / "a")
    a = read_any(x)
    text = x.read_text()
    t0 = text.index("\n    <transform>\n") + 1
    t1 = text.index("    </transform>\n", t0) + len("    </transform>\n")
    moved = text[:t0] + text[t1:]
    moved = moved.replace("    <cameras ", '    <components next_id="1" active_id="0">\n'
                          '      <component id="0" label="Component 1">\n' + text[t0:t1]
                          + "      </component>\n    </components>\n    <cameras ", 1)
    moved = moved.replace('sxy="0.02" sz="0.05"', 'sxyz="0.03"')
    y = tmp_path / "b" / "cameras.xml"
    y.parent.mkdir()
    y.write_text(moved)
    b = read_any(y)
    assert np.array_equal(a.photos.eo, b.photos.eo)
    assert b.points.sigma[0] == pytest.approx([0.03, 0.03, 0.03])
    grouped = moved.replace('<camera id="0"', '<group id="0" label="Flight 1" type="folder">'
                            '<camera id="0"', 1).replace("    </cameras>", "</group></cameras>")
    y.write_text(grouped)
    assert read_any(y).photos.ids == a.photos.ids  # cameras in a <group> (a folder)
    two = moved.replace("    </components>", '      <component id="1">' + text[t0:t1]
                        + "      </component>\n    </components>")
    y.write_text(two)
    with pytest.raises(ProjectError, match="2 components with their own <transform>"):
        read_any(y)


def test_bundler_ties_in_the_chunk_frame(tmp_path):
    """A Bundler file in the chunk's own frame (not the reference system) joins as well:
    its camera centres tell which frame it is in."""
    a = baarda.read(PSZ)
    write_metashape(a, tmp_path)
    text = (tmp_path / "cameras.xml").read_text()
    centre = np.array([float(v) for v in re.search(r"<translation>([^<]*)</translation>",
                                                   text).group(1).split()])  # type: ignore[union-attr]
    lines = (tmp_path / "bundle.out").read_text().splitlines()
    nc, npt = (int(v) for v in lines[1].split())
    for k in range(nc):
        r = np.array([[float(v) for v in lines[3 + 5 * k + i].split()] for i in range(3)])
        t = np.array([float(v) for v in lines[6 + 5 * k].split()])
        lines[6 + 5 * k] = " ".join(repr(float(v)) for v in t + r @ centre)
    for j in range(npt):
        i = 2 + 5 * nc + 3 * j
        lines[i] = " ".join(repr(float(v)) for v in
                            np.array([float(v) for v in lines[i].split()]) - centre)
    (tmp_path / "bundle.out").write_text("\n".join(lines) + "\n")
    b = baarda.read(tmp_path / "cameras.xml")
    assert np.allclose(b.points.xyz, a.points.xyz, rtol=0, atol=1e-8)
    assert len(b.image) == len(a.image)
