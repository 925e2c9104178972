"""Errors that blame the right file (issue 28; each from a 223-case fault run): every one
names the file, line and field where the fault is, and what to do."""

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from pyproj import Transformer

from baarda.cli import main
from baarda.errors import GeometryError, ProjectError
from baarda.pipeline import adjust, read

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
DEMO = ROOT / "examples" / "demo"
COLMAP = DATA / "colmap_maupertuis" / "sparse"
BERLIN = DATA / "opensfm_berlin"


def _demo(tmp_path: Path) -> Path:
    d = tmp_path / "demo"
    shutil.copytree(DEMO, d)
    return d


# ---------------------------------------------------------------- COLMAP
def test_truncated_colmap_images_txt_is_blamed(tmp_path):
    """images.txt cut after its first images: was 'points3D.txt: point 708: track element
    (2, 4561) does not point back to this point' without a line."""
    d = tmp_path / "sparse"
    shutil.copytree(COLMAP, d)
    lines = (COLMAP / "images.txt").read_text().splitlines()
    (d / "images.txt").write_text("\n".join(lines[:8]) + "\n")
    with pytest.raises(ProjectError, match="holds 2 of the 4 images that its header names "
                       r"\(line 4\): the file is cut short") as e:
        read(d)
    assert (e.value.path, e.value.line) == (str(d / "images.txt"), 8)
    # cut before the POINTS2D line of its last image (issue 41)
    (d / "images.txt").write_text("\n".join(lines[:7]) + "\n")
    with pytest.raises(ProjectError, match="the last image has no POINTS2D line") as e:
        read(d)
    assert (e.value.path, e.value.line) == (str(d / "images.txt"), 7)
    # without COLMAP's header comment: the track names the file that lacks the image
    (d / "images.txt").write_text("\n".join(lines[4:8]) + "\n")
    with pytest.raises(ProjectError, match="seen in image 2, which images.txt does not hold "
                       r"\(it holds 2 image\(s\): is images.txt cut short\?\)") as e:
        read(d)
    assert (e.value.path, e.value.line, e.value.column) == (str(d / "points3D.txt"), 4, "TRACK")


# ---------------------------------------------------------------- ODM
def _odm(tmp_path: Path, header: str, lonlat: bool = False) -> Path:
    """An ODM project: opensfm/ of OpenSfM's berlin example and a gcp_list.txt."""
    proj = tmp_path / "odm"
    (proj / "opensfm").mkdir(parents=True)
    shutil.copy(BERLIN / "reconstruction_example.json", proj / "opensfm" / "reconstruction.json")
    shutil.copy(BERLIN / "tracks_example.csv", proj / "opensfm" / "tracks.csv")
    g = json.loads((BERLIN / "ground_control_points.json").read_text())
    tr = Transformer.from_crs("EPSG:4979", "EPSG:32633", always_xy=True)
    rows = [header]
    for p in g["points"]:
        if "position" not in p:
            continue
        q = p["position"]
        e, n, h = (q["longitude"], q["latitude"], q["altitude"]) if lonlat else \
            tr.transform(q["longitude"], q["latitude"], q["altitude"])
        for o in p["observations"]:
            px = o["projection"][0] * 3264 + 3264 / 2 - 0.5
            py = o["projection"][1] * 3264 + 2448 / 2 - 0.5
            rows.append(f"{e!r} {n!r} {h!r} {px!r} {py!r} {o['shot_id']} {p['id']}")
    (proj / "gcp_list.txt").write_text("\n".join(rows) + "\n")
    return proj


def test_odm_gcp_list_with_a_bad_crs_header_is_blamed(tmp_path):
    """Was blamed on reconstruction.json."""
    proj = _odm(tmp_path, "WGS84 UTMX 33N")
    with pytest.raises(ProjectError, match="CRS 'WGS84 UTMX 33N'") as e:
        read(proj)
    assert (e.value.path, e.value.line, e.value.column) == \
        (str(proj / "gcp_list.txt"), 1, "crs")


def test_odm_gcps_in_lon_lat_under_a_utm_header(tmp_path):
    """Were accepted and then 'not measured on any photo'."""
    proj = _odm(tmp_path, "WGS84 UTM 33N", lonlat=True)
    with pytest.raises(ProjectError, match=r"lies \d+ km from the reconstruction's reference "
                       ".*look like longitude and latitude: name EPSG:4326") as e:
        read(proj)
    assert (e.value.path, e.value.line, e.value.column) == (str(proj / "gcp_list.txt"), 2, "X")
    text = (proj / "gcp_list.txt").read_text().replace("WGS84 UTM 33N", "EPSG:4326", 1)
    (proj / "gcp_list.txt").write_text(text)
    assert (read(proj).points.role == "control").sum() == 2


# ---------------------------------------------------------------- CSV tables
def test_nul_byte_in_an_id(tmp_path):
    """A NUL byte in a photos.csv id surfaced as 'unknown photo' in image_points.csv."""
    d = _demo(tmp_path)
    lines = (d / "photos.csv").read_text().split("\n")
    lines[3] = lines[3].replace("01003", "01\x00003", 1)
    (d / "photos.csv").write_text("\n".join(lines))
    with pytest.raises(ProjectError, match="NUL byte") as e:
        read(d)
    assert (e.value.path, e.value.line, e.value.column) == (str(d / "photos.csv"), 4, "photo")


@pytest.mark.parametrize("name", ["photos.csv", "image_points.csv", "ground_points.csv",
                                  "cameras.csv"])
def test_two_byte_order_marks(tmp_path, name):
    """Two UTF-8 byte-order marks (files joined) crashed the fast CSV reader or turned ids
    like 01001 into integers (1001: 'unknown photo')."""
    d = _demo(tmp_path)
    (d / name).write_bytes(b"\xef\xbb\xbf\xef\xbb\xbf" + (DEMO / name).read_bytes())
    b = read(d)
    assert b.photos.ids[0] == "01001" and b.points.ids[0] == "001003"
    assert main(["adjust", str(d), "-o", str(tmp_path / "o"), "-q"]) == 0


# ---------------------------------------------------------------- CRS and coordinates
def test_geographic_crs_on_metric_coordinates(tmp_path, capsys):
    """crs = "EPSG:4326" on metric coordinates ended in a generic 'the approximations do
    not fit'."""
    d = _demo(tmp_path)
    (d / "project.toml").write_text('crs = "EPSG:4326"\n' + (DEMO / "project.toml").read_text())
    with pytest.raises(ProjectError, match=r"EPSG:4326 \(WGS 84\) is geographic: X and Y are "
                       "longitude and latitude in degrees, but point 001003 has X 920.01597, "
                       r"Y -805\.0434524 \(outside \+-180 and \+-90\)") as e:
        adjust(read(d))
    assert (e.value.path, e.value.column) == (str(d / "project.toml"), "crs")
    assert main(["adjust", str(d), "-o", str(tmp_path / "o"), "-q"]) == 2
    assert "is geographic" in capsys.readouterr().err


def test_ground_x_and_y_swapped(tmp_path, capsys):
    """Was blamed on the photos' approximations ('their approximate orientations or the
    identification of their points are wrong')."""
    d = _demo(tmp_path)
    text = (DEMO / "ground_points.csv").read_text().replace("point,X,Y,Z", "point,Y,X,Z", 1)
    (d / "ground_points.csv").write_text(text)
    with pytest.raises(GeometryError, match=r"the control's X and Y look swapped .* lie "
                       r"\d+ m \(median\) .* with X and Y exchanged: exchange the X and Y "
                       "columns"):
        adjust(read(d))
    assert main(["adjust", str(d), "-o", str(tmp_path / "o"), "-q"]) == 2
    assert "look swapped" in capsys.readouterr().err


# ---------------------------------------------------------------- which format
def test_format_of_the_wrong_kind_of_path(tmp_path, capsys):
    """`--format bal` on a folder said 'file not found'."""
    assert main(["adjust", str(DEMO), "--format", "bal", "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "--format bal reads a BAL file (.txt or .bz2), but this is a folder; it looks like " \
        "project input (leave out --format)" in err
    with pytest.raises(ProjectError, match="--format colmap reads a COLMAP model folder, but "
                       "this is a file; it looks like dbat input"):
        read(DATA / "dbat_sxb_aerial" / "dbat_script" / "sxb.xml", "colmap")


def test_folder_without_project_toml(tmp_path):
    """Said 'format not recognised' without naming project.toml."""
    d = tmp_path / "p"
    d.mkdir()
    for name in ("cameras.csv", "photos.csv", "image_points.csv", "ground_points.csv"):
        shutil.copy(DEMO / name, d / name)
    with pytest.raises(ProjectError, match="not found: the folder has cameras.csv, photos.csv, "
                       "image_points.csv, ground_points.csv but a native project needs "
                       "project.toml") as e:
        read(d)
    assert e.value.path == str(d / "project.toml")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ProjectError, match=re.escape("no project.toml (a native project "
                                                     "folder)")):
        read(tmp_path / "empty")
    assert np.isfinite(read(DEMO).photos.eo).all()
