"""Image chips of the shared COLMAP Maupertuis project (images/ beside sparse/)."""

import io
from pathlib import Path

import numpy as np
import pytest
from review_serving import Served

from baarda.pipeline import read_configured
from baarda.review.chips import HALF, ZOOM, image_folders
from baarda.review.session import ReviewSession

MAUPERTUIS = Path("/work/shared/data/colmap_maupertuis")
pytestmark = [pytest.mark.slow, pytest.mark.skipif(
    not (MAUPERTUIS / "images").is_dir(), reason="the shared COLMAP Maupertuis data set "
    "with its images is not on this machine (/work/shared/data/colmap_maupertuis)")]


def keypoint(photo: str, point: str) -> tuple[float, float]:
    """The pixel (column, row) of a 3D point on an image, read from COLMAP's images.txt."""
    lines = [s for s in (MAUPERTUIS / "sparse" / "images.txt").read_text().splitlines()
             if not s.startswith("#")]
    for head, pts in zip(lines[0::2], lines[1::2], strict=False):
        if Path(head.split()[9]).stem == photo:
            v = pts.split()
            for k in range(0, len(v), 3):
                if v[k + 2] == point:
                    return float(v[k]), float(v[k + 1])
    raise KeyError((photo, point))


@pytest.fixture(scope="module")
def served():
    block, config = read_configured(MAUPERTUIS)
    s = Served(ReviewSession(block, config), folders=image_folders(MAUPERTUIS / "sparse"),
               pixel_mm=0.001)
    yield s
    s.close()


def test_chips_of_maupertuis_are_pngs_marked_where_measured(served):
    from PIL import Image

    status, data, _ = served.request("/api/observations?status=flagged")
    rows = [r for r in data["observations"] if r["kind"] == "image"][:3]
    assert rows and status == 200
    src = {}
    for r in rows:
        status, png, hdr = served.request(f"/api/chip?photo={r['photo']}&point={r['point']}")
        assert status == 200 and hdr["Content-Type"] == "image/png"
        chip = Image.open(io.BytesIO(png)).convert("RGB")
        assert chip.size == (2 * HALF * ZOOM, 2 * HALF * ZOOM)
        cx, cy = map(float, hdr["X-Chip-Centre"].split(","))
        # the green cross is drawn where COLMAP's keypoint is (images.txt, independent)
        col, row = keypoint(r["photo"], r["point"])
        assert cx / ZOOM + round(col) - HALF == pytest.approx(col, abs=1e-6)
        assert cy / ZOOM + round(row) - HALF == pytest.approx(row, abs=1e-6)
        assert chip.getpixel((round(cx) + 6, round(cy))) == (0, 255, 0)
        # away from the marks the chip is the image, magnified ZOOM times
        name = next(p for p in (MAUPERTUIS / "images").iterdir() if p.stem == r["photo"])
        src.setdefault(name, Image.open(name).convert("RGB"))
        c0, r0 = round(col) - HALF, round(row) - HALF
        for u, v in ((2, 2), (2 * HALF - 3, 5), (7, 2 * HALF - 3)):
            assert chip.getpixel((u * ZOOM + 1, v * ZOOM + 1)) == \
                src[name].getpixel((c0 + u, r0 + v))
        assert float(hdr["X-Chip-Mm-Per-Px"]) == pytest.approx(0.001 / ZOOM)
    assert np.isfinite(cx)


def test_a_photo_without_a_readable_image_says_so(tmp_path):
    from baarda.review.chips import NoImage, chip_png

    (tmp_path / "03.jpg").write_bytes(b"not a jpeg")
    block, _ = read_configured(MAUPERTUIS)
    ray = {"x": 0.0, "y": 0.0, "pred_x": None, "pred_y": None}
    with pytest.raises(NoImage, match="cannot be read"):
        chip_png(block, [tmp_path], "03", ray, 0.001)
    with pytest.raises(NoImage, match="no image of photo 02"):
        chip_png(block, [tmp_path], "02", ray, 0.001)
