"""PhotoModeler export reader: counts, conventions checked by reprojecting PhotoModeler's own
solution (its report: overall marking RMS 1.097 px for SXB), malformed files."""

from pathlib import Path

import numpy as np
import pytest

from baarda.block.camera import ideal_image_coordinates
from baarda.bundle.collinearity import project
from baarda.errors import ProjectError
from baarda.io.photomodeler import read_photomodeler

DATA = Path(__file__).resolve().parents[1] / "data"
SXB = DATA / "dbat_sxb_aerial" / "photomodeler_export" / "wsmart-no-orient-pmexport.txt"
CAMCAL = DATA / "dbat_camcal_closerange" / "photomodeler_export" / "camcal-pmexport.txt"


def _residuals_px(block, pixel_mm):
    im = block.image
    cam = block.photos.camera[im.photo]
    p = project(block.photos.eo[im.photo], block.points.xyz[im.point],
                block.cameras.focal_mm[cam], block.cameras.principal_point_mm[cam])
    return (p - ideal_image_coordinates(block)) / pixel_mm


def test_sxb_counts_and_reprojection():
    b = read_photomodeler(SXB)
    assert (len(b.photos), len(b.image), len(b.points)) == (5, 1196, 381)
    assert np.sum(b.points.role == "control") == 16
    assert b.photos.ids == ["8811", "8936", "8937", "8938", "9111"]
    # marks 1 px, SmartPoints 0 -> default 1 px (line 3), in mm
    assert np.allclose(b.image.sigma_mm, 0.006)
    r = _residuals_px(b, 0.006)
    length = np.hypot(r[:, 0], r[:, 1])
    # PhotoModeler's report: overall RMS 1.097 px, maximum 3.124 px at point 410 on photo 5;
    # the export rounds positions to mm and angles to 0.001 deg
    assert abs(np.sqrt(np.mean(length**2)) - 1.097) < 0.02
    worst = int(np.argmax(length))
    assert b.points.ids[b.image.point[worst]] == "410"
    assert b.photos.ids[b.image.photo[worst]] == "9111"
    assert abs(length[worst] - 3.124) < 0.15


def test_camcal_distortion_sign_from_photomodeler_solution():
    b = read_photomodeler(CAMCAL)
    assert (len(b.photos), len(b.image), len(b.points)) == (21, 2074, 100)
    assert b.cameras.model[0] == "brown_backward"
    py = 5.43764 / 1704
    rms = np.sqrt(np.mean(_residuals_px(b, py) ** 2))
    b.cameras.coefficients = -b.cameras.coefficients
    rms_flipped = np.sqrt(np.mean(_residuals_px(b, py) ** 2))
    assert rms < 0.5 and rms_flipped > 10


HEADER = ("Bundle Soln test\n 0.0005 20 100 80\n 1.0 0.1 10 10 10 10 20 20 20\n"
          "10.0 2.5 2.0 5.0 4.0 0 0 0 0 0\n 0 0 0 0 0 0 0 0 0 0\n")
PHOTO = ("   0 a.jpg\n   0 1 2 30 0.5 0.1 0.2\n   0 0 0 0 0 0 0\n\n"
         "   0 10.0 2.5 2.0 5.0 4.0 0 0 0 0 0\n   0 0 0 0 0 0 0 0 0 0\n")
GOOD = HEADER + PHOTO + "\n 1 0 0 0 0.1 0.1 0.1\n\n 1 0 0 0 0.1 0.1 0.1\n\n 0 1 50 40 1 1\n\n"


def test_minimal_export(tmp_path):
    p = tmp_path / "x.txt"
    p.write_text(GOOD)
    b = read_photomodeler(p)
    assert np.allclose(b.image.xy_mm[0], [0, 0]) and np.allclose(b.cameras.principal_point_mm[0],
                                                                  [0, 0])
    assert np.allclose(np.degrees(b.photos.eo[0, 3:]), [0.2, 0.1, 0.5])


@pytest.mark.parametrize("text, line", [
    (GOOD.replace(" 0.0005 20 100 80", " 0.0005 20"), 2),
    (GOOD.replace("   0 1 2 30 0.5 0.1 0.2", "   0 1 2 x 0.5 0.1 0.2"), 7),
    (GOOD.replace(" 0 1 50 40 1 1", " 3 1 50 40 1 1"), 17),
    (GOOD.replace(" 0 1 50 40 1 1", " 9.3e18 1 50 40 1 1"), 17),  # cast overflowed (fuzz)
    (GOOD.replace(" 0 1 50 40 1 1", " 0 1 50 40 1"), 17),
    (GOOD.replace("   0 a.jpg", "   1 a.jpg"), 6),
    ("Something else\n" + GOOD[15:], 1),
    (HEADER + PHOTO, 11),  # no marked points: named the line after the end (fuzz, issue 15)
    (GOOD.replace(" 20 20 20\n", " 20 20 20\x0c\n").replace(" 0 1 50 40 1 1", " 0 1 50 40 1"),
     17),  # a form feed is no line end
])
def test_malformed(tmp_path, text, line):
    p = tmp_path / "x.txt"
    p.write_text(text)
    with pytest.raises(ProjectError) as e:
        read_photomodeler(p)
    assert e.value.line == line and e.value.path == str(p)


# ------------------------------------------------------- as DBAT reads an export (issue 28)
def test_default_camera_of_line_4(tmp_path):
    """Every photo takes the export's default camera (line 4); the photo lines repeat it
    rounded to 3 decimals (rounded, they cost 0.6 % in sigma0 for SXB's export)."""
    p = tmp_path / "x.txt"
    p.write_text(GOOD.replace("10.0 2.5 2.0 5.0 4.0 0 0 0 0 0\n 0 0", "10.0004 2.5 2.0 5.0 4.0 "
                              "0 0 0 0 0\n 0 0"))
    b = read_photomodeler(p)
    assert b.cameras.focal_mm[0] == 10.0004 and not any("differ" in n for n in b.notes)
    p.write_text(GOOD.replace("   0 10.0 2.5", "   0 11.0 2.5"))
    b = read_photomodeler(p)
    assert b.cameras.focal_mm[0] == 10.0
    assert any("photo 0" in n and "default camera" in n for n in b.notes)


def test_negative_control_precision_is_fixed(tmp_path):
    p = tmp_path / "x.txt"
    p.write_text(GOOD.replace("\n 1 0 0 0 0.1 0.1 0.1\n\n", "\n 1 0 0 0 -0.7876 -0.7876 "
                              "-0.7876\n\n", 1))
    b = read_photomodeler(p)
    assert b.points.role[0] == "control" and np.all(b.points.sigma[0] == 0)
    assert any("fixed" in n for n in b.notes)


def test_marks_of_unknown_points_are_dropped(tmp_path):
    p = tmp_path / "x.txt"
    p.write_text(GOOD.replace(" 0 1 50 40 1 1\n", " 0 1 50 40 1 1\n 0 7 60 40 1 1\n"))
    b = read_photomodeler(p)
    assert len(b.image) == 1 and b.points.ids == ["1"]
    assert any("dropped" in n and ": 7" in n for n in b.notes)
    p.write_text(GOOD.replace(" 0 1 50 40 1 1\n", " 0 7 60 40 1 1\n"))
    with pytest.raises(ProjectError, match="no marked point") as e:
        read_photomodeler(p)
    assert e.value.line == 17


def test_cp1252_export(tmp_path):
    p = tmp_path / "x.txt"
    p.write_bytes(GOOD.replace("Bundle Soln test", "Bundle Soln Façade").encode("cp1252"))
    b = read_photomodeler(p)
    assert b.settings.name == "Façade"
    assert any("cp1252" in n and "line 1" in n for n in b.notes)
    b = read_photomodeler(p, encoding="latin-1")  # named: no guess, no note
    assert not any("cp1252" in n for n in b.notes)


def test_export_without_image_size(tmp_path):
    """Line 2 without the image size: an error that says what to add, or the pixel size
    given (the image size is then the format / pixel size)."""
    p = tmp_path / "x.txt"
    p.write_text(GOOD.replace(" 0.0005 20 100 80", " 0.0005 20"))
    with pytest.raises(ProjectError, match="WIDTH HEIGHT.*--pixel-mm") as e:
        read_photomodeler(p)
    assert e.value.line == 2
    b = read_photomodeler(p, pixel_mm=0.05)  # format 5 x 4 mm -> 100 x 80 px
    assert np.allclose(b.image.xy_mm[0], [0, 0])
    p.write_text(GOOD)
    with pytest.raises(ProjectError, match="--pixel-mm does not apply") as e:
        read_photomodeler(p, pixel_mm=0.05)
    assert e.value.path == "command line"


def test_sxb_export_with_its_own_control_and_default_camera():
    """Without --control the export's own (PhotoModeler's adjusted) control is used; the
    default camera c = 123.9390 of line 4 (the photo lines print 123.939)."""
    b = read_photomodeler(SXB)
    assert b.cameras.focal_mm[0] == 123.939 and len(b.cameras) == 1
    assert any("--control FILE replaces them" in n for n in b.notes)


def test_negative_sy_is_named_at_its_own_line_and_column(tmp_path):
    """A negative sy on line 614 of the SXB export (a mark with sx 0, a SmartPoint) was
    reported at 'line 436, column sx' (the first mark with the smallest sx)."""
    lines = SXB.read_text().split("\n")
    fields = lines[613].split()
    assert fields[:2] == ["1", "65740"] and fields[4] == "0.00000"
    lines[613] = "   " + "   ".join(fields[:5] + ["-1.00000"])
    p = tmp_path / "x.txt"
    p.write_text("\n".join(lines))
    with pytest.raises(ProjectError, match="-1 px is negative") as e:
        read_photomodeler(p)
    assert (e.value.line, e.value.column) == (614, "sy")
    lines[613] = "   " + "   ".join(fields[:4] + ["-0.5", "1.0"])
    p.write_text("\n".join(lines))
    with pytest.raises(ProjectError, match="-0.5 px") as e:
        read_photomodeler(p)
    assert (e.value.line, e.value.column) == (614, "sx")
