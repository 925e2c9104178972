"""The IGN UltraCam block of MicMac's use case (issue 14): read where it lies in
../shared/data (IGN data, not copied), adjusted with its GNSS/IMU orientations."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.micmac import read_micmac, read_sensor
from baarda.pipeline import adjust, assess, read

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / \
    "micmac_ign_ultracam_aerial"
pytestmark = pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/"
                                "micmac_ign_ultracam_aerial is not beside this checkout")


@pytest.fixture(scope="module")
def block():
    return read(DATA)


def test_read(block):
    assert len(block.photos) == 20 and len(block.image) == 18137
    roles = block.points.role
    assert (roles == "tie").sum() == 6462 and (roles == "control").sum() == 1
    assert "2075 point(s) measured on one image left out" in block.notes[1]
    assert np.isclose(block.cameras.focal_mm[0], 123.9)
    assert sorted(set(block.photos.strip)) == ["00015", "00016", "00017"]
    assert len(block.gnss) == len(block.imu) == 20 and block.settings.crs == "EPSG:2154"
    s = read_sensor(DATA / "s07_UC_Eagle_M3_120.xml")
    assert (s["width"], s["height"], s["ppx"], s["ppy"], s["focal"]) == \
        (26460, 17004, 13230, 8502, 30975) and np.isclose(s["pixel_mm"], 0.004)


def test_adjusts_with_the_files_conventions(block):
    """With R = Rx Ry Rz (degrees) and x = (x_px - ppx) p, y = (ppy - y_px) p the block
    converges to image residuals of 0.15 px (0.6 µm) from the GNSS/IMU orientations."""
    r = adjust(block)
    assert r.converged and r.iterations <= 5
    im = r.image_residuals * 1e3
    assert np.sqrt(np.mean(im**2)) < 0.7  # µm: 4 µm pixels
    assert 0.40 < r.sigma0 < 0.47 and r.redundancy == 16888


def test_strip_shifts_of_the_gnss(block):
    """Strip 16, flown the other way, has GNSS Y residuals of 0.7-0.8 m: with a shift per
    strip every strip's shift is significant and snooping rejects one image coordinate."""
    b = replace(block, settings=replace(block.settings, gnss_offsets="strip"))
    tests = {h.name: h for h in assess(adjust(b)).hypotheses}
    for s in ("00015", "00016", "00017"):
        assert tests[f"GNSS shift of strip {s}"].rejected
    assert tests["GNSS shift of strip 00016"].nabla[1] > 0.4 > -0.4 > \
        tests["GNSS shift of strip 00015"].nabla[1]


def test_command_line(tmp_path):
    out = tmp_path / "out"
    assert main(["adjust", str(DATA), "-o", str(out), "-q"]) == 0
    doc = json.loads((out / "summary.json").read_text())
    assert doc["redundancy"] == 16888
    assert main(["convert", str(DATA), "-o", str(tmp_path / "p")]) == 0
    assert (tmp_path / "p" / "gnss.csv").is_file() and (tmp_path / "p" / "imu.csv").is_file()


def test_errors_name_the_file_and_line(tmp_path):
    folder = tmp_path / "mm"
    folder.mkdir()
    for f in DATA.iterdir():
        if f.name != "21FD2447_alt.OPK":
            (folder / f.name).write_bytes(f.read_bytes())
    lines = (folder / "trajectograhie.opk").read_text().splitlines()
    lines[3] = lines[3].replace(lines[3].split()[2], "6518x", 1)
    (folder / "trajectograhie.opk").write_text("\n".join(lines) + "\n")
    with pytest.raises(ProjectError) as e:
        read_micmac(folder)
    assert e.value.line == 4 and "trajectograhie.opk" in str(e.value)


def _copy(tmp_path: Path) -> Path:
    folder = tmp_path / "mm"
    folder.mkdir()
    for f in DATA.iterdir():
        if f.name != "21FD2447_alt.OPK":
            (folder / f.name).write_bytes(f.read_bytes())
    return folder


def test_tie_point_errors_name_the_line_an_editor_shows(tmp_path):
    """Filtered_all_liaisons.mes ends its lines ' \\r \\n': one line end, not two (the third
    line was reported as line 5, every line N as 2N - 1)."""
    folder = _copy(tmp_path)
    tie = folder / "Filtered_all_liaisons.mes"
    lines = tie.read_bytes().split(b"\n")
    assert lines[0].endswith(b" \r ")
    lines[2] = lines[2].replace(b".", b"x", 1)
    tie.write_bytes(b"\n".join(lines))
    with pytest.raises(ProjectError) as e:
        read_micmac(folder)
    assert e.value.line == 3 and e.value.column == "x" and "liaisons" in str(e.value)


def test_camera_descriptions_are_parsed_not_sniffed(tmp_path, block):
    """A comment longer than 200 bytes before <sensor> in both camera files: the folder is
    still MicMac's and each photo gets the camera its orientations name (s07, 123.9 mm)."""
    folder = _copy(tmp_path)
    for name in ("s07_UC_Eagle_M3_120.xml", "s08_UC_Eagle_M3_120.xml"):
        p = folder / name
        p.write_bytes(b"<!-- " + b"x" * 300 + b" -->\n" + p.read_bytes())
    commented = read(folder)
    assert commented.cameras.ids == block.cameras.ids == ["UCE-M3-f120-s07"]
    assert np.array_equal(commented.cameras.focal_mm, block.cameras.focal_mm)
