"""Unusable approximations named by their cause before adjusting (issue 15): wrong angle
unit, kappa off by 200 gon on a strip, an image coordinate of 1e6 mm, pixels as mm, a
header-only image_points.csv, coordinates beyond the Earth."""

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from baarda.bundle.diagnostics import _photo_medians, diagnose
from baarda.cli import main
from baarda.errors import GeometryError, ProjectError
from baarda.io.project import read_project
from baarda.pipeline import adjust, read

DEMO = Path(__file__).parents[2] / "examples" / "demo"


@pytest.fixture
def demo(tmp_path):
    dst = tmp_path / "demo"
    shutil.copytree(DEMO, dst)
    return dst


def edit(folder: Path, name: str, change) -> None:
    t = pd.read_csv(folder / name, dtype=str, keep_default_na=False)
    change(t)
    t.to_csv(folder / name, index=False)


def adjust_error(folder: Path, capsys) -> str:
    assert main(["adjust", str(folder), "-o", str(folder.parent / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and not (folder.parent / "out").exists()
    return err


def test_the_demo_has_no_findings():
    assert diagnose(read(DEMO)) == []


def test_angles_in_gon_read_as_radians(demo, capsys):
    toml = (demo / "project.toml").read_text().replace('"gon"', '"rad"')
    (demo / "project.toml").write_text(toml)
    err = adjust_error(demo, capsys)
    assert 'with angle_unit = "gon" the misclosure would be 0.705 mm' in err


def test_angles_beyond_two_pi_in_radians(demo, capsys):
    toml = (demo / "project.toml").read_text().replace('"gon"', '"rad"')
    (demo / "project.toml").write_text(toml)
    edit(demo, "photos.csv", lambda t: t.__setitem__("kappa", "399.5"))
    err = adjust_error(demo, capsys)
    assert "kappa = 399.5 with angle_unit = rad (32 photo(s) like it)" in err


def test_kappa_off_by_200_gon_on_one_strip(demo, capsys):
    def turn(t):
        s = t["strip"] == "1"
        t.loc[s, "kappa"] = (t.loc[s, "kappa"].astype(float) + 200).astype(str)

    edit(demo, "photos.csv", turn)
    findings = diagnose(read(demo))
    assert len(findings) == 1
    f = findings[0]
    assert "8 photo(s) (all of strip 1)" in f and "kappa is off by half a turn" in f
    err = adjust_error(demo, capsys)
    assert "Likely cause: approximations: the rays of 8 photo(s) (all of strip 1)" in err


def test_one_image_coordinate_of_a_million_mm(demo, capsys):
    edit(demo, "image_points.csv", lambda t: t.loc.__setitem__((10, "x_mm"), "1000000"))
    err = adjust_error(demo, capsys)
    assert "1 image point(s) lie outside any image format" in err
    assert "photo 01002, point 002002: (1e+06, 2.36354) mm, 6536 c" in err


def test_image_coordinates_in_pixels(demo, capsys):
    def pixels(t):
        for c in ("x_mm", "y_mm"):
            t[c] = (t[c].astype(float) / 0.009 + 12800).astype(str)

    edit(demo, "image_points.csv", pixels)
    assert "Are they in pixels?" in adjust_error(demo, capsys)


def test_header_only_image_points(demo, capsys):
    (demo / "image_points.csv").write_text("photo,point,x_mm,y_mm,sigma_um\n")
    with pytest.raises(ProjectError, match="image_points.csv: no image points"):
        read_project(demo)
    assert "no image points (the file holds only its header)" in adjust_error(demo, capsys)


def test_coordinates_beyond_the_earth_are_a_note(demo, capsys):
    def shift(t, cols):
        for c in cols:
            t[c] = (t[c].astype(float) + 1e12).astype(str)

    edit(demo, "photos.csv", lambda t: shift(t, ("X0", "Y0")))
    edit(demo, "ground_points.csv", lambda t: shift(t, ("X", "Y")))
    assert main(["adjust", str(demo), "-o", str(demo.parent / "out")]) == 0
    out = capsys.readouterr().out
    assert "note: coordinates up to 1e+12 m: larger than any map" in out


def test_no_image_observations_at_all():
    block = read(DEMO)
    empty = block.select_image(np.zeros(len(block.image), bool))
    with pytest.raises(GeometryError, match="no image observations"):
        diagnose(empty)


def test_photo_medians_equal_numpy_medians():
    block = read(DEMO)
    d = np.random.default_rng(1).normal(size=len(block.image))
    d[::5] = np.nan
    ref = [np.median(d[(block.image.photo == i) & np.isfinite(d)])
           for i in range(len(block.photos))]
    assert np.allclose(_photo_medians(block, d), ref, rtol=0, atol=0)


def test_intersection_of_rays_that_are_not_finite(small_block):
    """Fuzz find (issue 15): a NaN or inf ray (an orientation or image coordinate that
    overflows) made numpy's eigvalsh raise LinAlgError; such points are not intersected."""
    from baarda.bundle.geometry import intersect

    block, _ = small_block
    eo = block.photos.eo.copy()
    eo[0, 3] = np.inf
    points = np.unique(block.image.point)
    xyz = intersect(block, eo, points)
    on_first = np.isin(points, block.image.point[block.image.photo == 0])
    assert np.isnan(xyz[on_first]).all() and np.isfinite(xyz[~on_first]).all()


def test_height_control_without_x_and_y(demo, capsys):
    """Fuzz find (issue 15): a height control point with empty X and Y (docs/format.md
    allows it) made the test whether the height control lies on one line a numpy
    LinAlgError (SVD of NaN)."""
    def height_only(t):
        t.loc[t.point == "002005", ["X", "Y"]] = ""

    edit(demo, "ground_points.csv", height_only)
    block = read(demo)
    assert np.isnan(block.points.xyz[block.points.ids.index("002005"), :2]).all()
    assert main(["adjust", str(demo), "-o", str(demo.parent / "out"), "-q"]) == 0
    assert "Traceback" not in capsys.readouterr().err


def test_sigma_so_small_that_its_weight_overflows(demo, capsys):
    """Fuzz find (issue 15): sigma_um = 5e-324 gave an infinite weight (numpy's divide by
    zero warning) and then 'the residuals at the approximate values are not finite'; issue
    28: the reader names file, line and column (it was 'standard deviation 0' with neither)."""
    def tiny(t):
        t.loc[0, "sigma_um"] = "5e-324"

    edit(demo, "image_points.csv", tiny)
    with pytest.raises(ProjectError, match="image standard deviation 5e-324 µm: expected "
                       "0.001 to 100000 µm") as e:
        adjust(read(demo))
    assert (Path(e.value.path).name, e.value.line, e.value.column) == \
        ("image_points.csv", 2, "sigma_um")


def test_a_huge_coordinate_is_printed_in_three_digits(tmp_path, capsys):
    """A projection centre at X0 = 1e300 m: the weak-control note said '(0 m of 1000000...
    (301 digits) m between the outer projection centres)'; now 1e+300, and no message of
    the run holds a number of 20 digits."""
    import re

    from baarda.errors import figure

    assert (figure(1234.5), figure(-2.5e9), figure(1e308), figure(0.123, 2)) == \
        ("1234", "-2.5e+09", "1e+308", "0.12")
    shutil.copytree(DEMO, tmp_path / "big")
    photos = pd.read_csv(tmp_path / "big" / "photos.csv", dtype=str)
    photos.loc[0, "X0"] = "1e300"
    photos.to_csv(tmp_path / "big" / "photos.csv", index=False)
    assert main(["adjust", str(tmp_path / "big"), "-o", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "(0 m of 1e+300 m between the outer projection centres)" in err
    assert not re.search(r"\d{20}", err), err
