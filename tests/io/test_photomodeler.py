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
