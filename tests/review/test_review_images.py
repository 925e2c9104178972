"""Image chips where each reader's images are and as each reader made its image
coordinates: a dot drawn at a known pixel of a synthetic image, the mark found on it in the
PNG; the pixel of a measurement in the MicMac and DBAT files found again from the block."""

import io
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from baarda.io.bundler import read_bundler
from baarda.io.nvm import read_nvm
from baarda.review.chips import HALF, ZOOM, chip_png, image_folders, pixel_frame, to_pixel

W, H = 240, 160  # the synthetic images (pixels)
DOT = (150, 50)  # the dot's pixel (column, row): its centre is at (150.5, 50.5)
BLUE = (0, 0, 255)


def image_with_dot(path: Path) -> None:
    from PIL import Image

    im = Image.new("RGB", (W, H), (128, 128, 128))
    c, r = DOT
    for dc in (-1, 0, 1):
        for dr in (-1, 0, 1):
            im.putpixel((c + dc, r + dr), BLUE)
    path.parent.mkdir(parents=True, exist_ok=True)
    im.save(path)


def centroid(chip, colour) -> np.ndarray:
    a = np.asarray(chip.convert("RGB"))
    rows, cols = np.nonzero((a == colour).all(axis=2))
    assert len(rows)
    return np.array([cols.mean() + 0.5, rows.mean() + 0.5])  # continuous chip pixels


def check_mark_on_dot(block, photo: str, x: float, y: float, folders=()):
    from PIL import Image

    png, meta = chip_png(block, list(folders), photo, {"x": x, "y": y}, None)
    chip = Image.open(io.BytesIO(png))
    # the green cross's centre and the blue dot's (what the cross leaves of it) coincide,
    # and the cross is at the chip pixel chip_png reports
    green = centroid(chip, (0, 255, 0))
    blue = centroid(chip, BLUE)
    assert np.abs(green - blue).max() < 1.0
    assert np.abs(green - [meta["cx"], meta["cy"]]).max() < 1.0
    # back to the image: the dot's centre
    col = meta["cx"] / ZOOM + round(DOT[0] + 0.5) - HALF
    row = meta["cy"] / ZOOM + round(DOT[1] + 0.5) - HALF
    assert (col, row) == pytest.approx((DOT[0] + 0.5, DOT[1] + 0.5), abs=1e-9)


def test_bundler_list_paths_and_the_image_centre(tmp_path):
    """Bundler: list.txt names the images (here in a subfolder), the measurement in pixels
    from the image's centre, y up."""
    image_with_dot(tmp_path / "pics" / "a.png")
    image_with_dot(tmp_path / "pics" / "b.png")
    x_px, y_px = DOT[0] + 0.5 - W / 2, H / 2 - (DOT[1] + 0.5)
    (tmp_path / "list.txt").write_text("pics/a.png 0 1000\npics/b.png 0 1000\n")
    cam = "1000 0 0\n1 0 0\n0 1 0\n0 0 1\n0 0 -10\n"
    (tmp_path / "bundle.out").write_text(
        "# Bundle file v0.3\n2 1\n" + cam + cam.replace("0 0 -10", "1 0 -10")
        + f"0 0 0\n255 255 255\n2 0 0 {x_px} {y_px} 1 0 {x_px} {y_px}\n")
    block = read_bundler(tmp_path / "bundle.out", pixel_mm=0.005)
    assert block.photos.ids == ["a", "b"] and block.photos.image == ["pics/a.png",
                                                                   "pics/b.png"]
    x, y = block.image.xy_mm[0]
    assert (x, y) == pytest.approx((x_px * 0.005, y_px * 0.005))
    check_mark_on_dot(block, "a", x, y)  # found by list.txt's path, no folder given


def test_nvm_file_names(tmp_path):
    """NVM: the file names of the cameras (relative to the .nvm file), measurements from
    the image's centre, y down."""
    image_with_dot(tmp_path / "shots" / "one.jpg.png")
    image_with_dot(tmp_path / "shots" / "two.jpg.png")
    x_px, y_px = DOT[0] + 0.5 - W / 2, DOT[1] + 0.5 - H / 2
    cams = "".join(f"shots/{n}.jpg.png 1000 1 0 0 0 {k} 0 10 0 0\n"
                   for k, n in enumerate(("one", "two")))
    (tmp_path / "m.nvm").write_text(
        f"NVM_V3\n\n2\n{cams}\n1\n0 0 0 255 255 255 2 0 0 {x_px} {y_px} 1 0 {x_px} {y_px}\n"
        "\n0\n")
    block = read_nvm(tmp_path / "m.nvm", pixel_mm=0.002)
    assert block.photos.image == ["shots/one.jpg.png", "shots/two.jpg.png"]
    x, y = block.image.xy_mm[0]
    check_mark_on_dot(block, block.photos.ids[0], x, y)


def test_origin_at_the_principal_point_and_non_square_pixels(tmp_path, demo_read):
    """A camera whose image coordinates start at its principal point (MicMac) and whose
    pixels are not square (DBAT, COLMAP with fx != fy): the mark on the dot."""
    block, _ = demo_read
    image_with_dot(tmp_path / "images" / "03008.png")
    c0, r0, pw, ph = 100.25, 70.75, 0.004, 0.005
    x, y = (DOT[0] + 0.5 - c0) * pw, (r0 - (DOT[1] + 0.5)) * ph
    n = len(block.cameras)
    frame = np.tile([c0, r0, pw, ph], (n, 1))
    odd = replace(block, cameras=replace(block.cameras, pixel_frame=frame))
    check_mark_on_dot(odd, "03008", x, y, image_folders(tmp_path / "project.toml"))
    # the page's click: a chip pixel right and down is x, y in each pixel's own size
    _, meta = chip_png(odd, [tmp_path / "images"], "03008", {"x": x, "y": y}, None)
    assert (meta["mm_per_px"], meta["mm_per_px_y"]) == (pw / ZOOM, ph / ZOOM)


MICMAC = Path("/work/shared/data/micmac_ign_ultracam_aerial")
DBAT = Path("/work/shared/data/dbat_sxb_aerial/dbat_script")


@pytest.mark.skipif(not MICMAC.is_dir(), reason="the shared MicMac data set is not here")
def test_micmac_measurements_map_back_to_their_pixels():
    """MicMac's image coordinates start at the principal point (not the image's centre):
    the pixel a measurement has in the .mes file, from the block's mm."""
    from baarda.pipeline import read_configured

    block, _ = read_configured(MICMAC)
    frame = pixel_frame(block, 0, None)
    assert np.isfinite(frame[:2]).all()
    first = (MICMAC / "Filtered_all_liaisons.mes").read_text().split("\n", 1)[0].split()
    point, photo, col, row = first[0], first[1], float(first[2]), float(first[3])
    i, j = block.photos.ids.index(photo), block.point_index[point]
    k = np.flatnonzero((block.image.photo == i) & (block.image.point == j))[0]
    x, y = block.image.xy_mm[k]
    assert to_pixel(frame, 1, 1, x, y) == pytest.approx((col, row), abs=1e-6)


@pytest.mark.skipif(not DBAT.is_dir(), reason="the shared DBAT data set is not here")
def test_dbat_measurements_map_back_to_their_pixels():
    """DBAT: pixels from the upper-left corner, the image's centre at W/2, H/2, pixel
    width and height from the sensor; the script's image paths kept."""
    from baarda.pipeline import read_configured

    block, _ = read_configured(DBAT / "sxb.xml")
    assert block.photos.image is not None
    assert block.photos.image[0].endswith("images/8811.jpg")
    frame = pixel_frame(block, 0, None)
    first = [s for s in (DBAT / "measurements" / "markpts.txt").read_text().splitlines()
             if s.strip() and not s.startswith("#")][0]
    pid, im, col, row = (v.strip() for v in first.split(",")[:4])
    assert im == "1"  # images.txt: 1, .../8811.jpg
    i, j = block.photos.ids.index("8811"), block.point_index[pid]
    k = np.flatnonzero((block.image.photo == i) & (block.image.point == j))[0]
    # the camera's image: 8858 x 12996 pixels (sxb.xml)
    assert to_pixel(frame, 8858, 12996, *block.image.xy_mm[k]) == pytest.approx(
        (float(col), float(row)), abs=1e-6)


def test_colmap_image_names_with_folders_under_images(tmp_path):
    """COLMAP: an image named "cam1/a.png" is found at images/cam1/a.png beside the model's
    sparse/0 (measurements in pixels, the first pixel's centre at 0.5); a name that would
    lead out of images/ ("../x.png") is not followed."""
    import baarda
    from baarda.review.chips import find_image, image_of

    for name in ("cam1/a.png", "cam1/b.png"):
        image_with_dot(tmp_path / "images" / name)
    image_with_dot(tmp_path / "outside.png")
    sparse = tmp_path / "sparse" / "0"
    sparse.mkdir(parents=True)
    (sparse / "cameras.txt").write_text(f"1 SIMPLE_PINHOLE {W} {H} 1000 {W / 2} {H / 2}\n")
    u, v = DOT[0] + 0.5, DOT[1] + 0.5
    (sparse / "images.txt").write_text(
        f"1 1 0 0 0 0 0 10 1 cam1/a.png\n{u} {v} 1\n"
        f"2 1 0 0 0 -1 0 10 1 cam1/b.png\n{u} {v} 1\n")
    (sparse / "points3D.txt").write_text("1 0 0 0 255 255 255 0.1 1 0 2 0\n")
    block = baarda.read(str(sparse))
    photo = block.photos.ids[0]
    folders = image_folders(sparse)
    # what the page asks before it shows a chip (server.py) and what the chip reads
    assert image_of(block, folders, photo) == tmp_path.resolve() / "images" / "cam1" / "a.png"
    x, y = block.image.xy_mm[0]
    check_mark_on_dot(block, photo, x, y, folders)
    assert find_image(folders, "../outside.png") is None
    assert find_image(folders, "cam1/../../outside.png") is None
