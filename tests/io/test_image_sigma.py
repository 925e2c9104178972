"""One image sigma for every input format (io/image_sigma.py): --sigma-image-um (µm) or
--sigma-px (px, with the camera's pixel size or --pixel-mm) replaces the input's for every
observation; an option that does not apply to the input's format is an error naming the
option and the format (exit 2), never silently ignored."""

from pathlib import Path

import numpy as np
import pytest

from baarda.cli import main
from baarda.errors import ProjectError
from baarda.pipeline import read

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
SHARED = ROOT.parent / "shared" / "data"
DEMO = ROOT / "examples" / "demo"
DBAT = DATA / "dbat_sxb_aerial" / "dbat_script" / "sxb.xml"
PM = DATA / "dbat_sxb_aerial" / "photomodeler_export" / "wsmart-no-orient-pmexport.txt"
COLMAP = DATA / "colmap_maupertuis" / "sparse"
OPENSFM = DATA / "opensfm_berlin"


@pytest.fixture(scope="module")
def bal(tmp_path_factory):
    from bal_reference import _synthetic

    from baarda.output.format_files import write_bal

    p = tmp_path_factory.mktemp("bal") / "p.txt"
    write_bal(_synthetic(seed=4), p)
    return p


def _inputs(bal) -> dict[str, Path]:
    out = {"project": DEMO, "dbat": DBAT, "photomodeler": PM, "colmap": COLMAP, "bal": bal,
           "opensfm": OPENSFM}
    if (SHARED / "aicon_jaicov_closerange" / "example.phc").is_file():
        out["aicon"] = SHARED / "aicon_jaicov_closerange"
    if (SHARED / "micmac_ign_ultracam_aerial").is_dir():
        out["micmac"] = SHARED / "micmac_ign_ultracam_aerial"
    return out


def test_sigma_image_um_for_every_format(bal):
    for fmt, path in _inputs(bal).items():
        b = read(path, sigma_image_um=2.5)
        assert np.allclose(b.image.sigma_mm, 0.0025), fmt
        assert b.image.sigma_xy_mm is None and b.settings.sigma_image_um == 2.5, fmt


@pytest.mark.parametrize("path, pixel_mm", [(DBAT, 0.006), (PM, 0.006)])
def test_sigma_px_with_the_cameras_pixel(path, pixel_mm):
    b = read(path, sigma_px=0.25)
    assert np.allclose(b.image.sigma_mm, 0.25 * pixel_mm)


def test_sigma_px_of_the_nominal_pixel_and_of_a_project(bal):
    assert np.allclose(read(COLMAP, sigma_px=2, pixel_mm=0.004).image.sigma_mm, 0.008)
    assert np.allclose(read(bal, sigma_image_um=3, pixel_mm=0.002).image.sigma_mm, 0.003)
    assert np.allclose(read(COLMAP).image.sigma_mm, 0.001)  # 1 px of 1 µm, as before
    assert np.allclose(read(DEMO, sigma_px=0.5, pixel_mm=0.012).image.sigma_mm, 0.006)


@pytest.mark.parametrize("path, options, words", [
    (DBAT, ["--pixel-mm", "0.01"], ("--pixel-mm", "DBAT script")),
    (DEMO, ["--pixel-mm", "0.01"], ("--pixel-mm", "a native project")),
    (DEMO, ["--sigma-px", "0.5"], ("--sigma-px", "--pixel-mm", "a native project")),
    (PM, ["--pixel-mm", "0.01"], ("--pixel-mm", "line 2 gives the image size")),
    (COLMAP, ["--sigma-px", "1", "--sigma-image-um", "2"], ("--sigma-px", "--sigma-image-um")),
    (DEMO, ["--sigma-image-um", "1e-300"], ("--sigma-image-um", "0.001 to 100000 µm")),
    (DEMO, ["--sigma-image-um", "1e308"], ("--sigma-image-um", "0.001 to 100000 µm")),
])
def test_options_that_do_not_apply_are_errors(tmp_path, capsys, path, options, words):
    assert main(["adjust", str(path), *options, "-o", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert all(w in err for w in words), err
    assert not (tmp_path / "o").exists()


def test_image_sigmas_of_a_file_outside_the_range(tmp_path):
    """A sigma_um of 1e-300 (an infinite weight: 'standard deviation 0' with no file or
    line) or 1e308 (overflows, an infinite MDB) in image_points.csv names file, line and
    column; so does project.toml's image_um."""
    import shutil

    for value in ("1e-300", "1e308"):
        d = tmp_path / value
        shutil.copytree(DEMO, d)
        lines = (d / "image_points.csv").read_text().splitlines()
        lines[5] = lines[5].rsplit(",", 1)[0] + "," + value
        (d / "image_points.csv").write_text("\n".join(lines) + "\n")
        with pytest.raises(ProjectError, match="0.001 to 100000 µm") as e:
            read(d)
        assert (e.value.path, e.value.line, e.value.column) == \
            (str(d / "image_points.csv"), 6, "sigma_um")
    d = tmp_path / "toml"
    shutil.copytree(DEMO, d)
    toml = (d / "project.toml").read_text()
    assert "image_um" in toml
    import re

    (d / "project.toml").write_text(re.sub(r"image_um = \S+", "image_um = 1e-300", toml))
    with pytest.raises(ProjectError, match="0.001 to 100000") as e:
        read(d)
    assert e.value.column == "sigma.image_um"
