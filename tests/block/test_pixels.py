"""One pixel grid per camera (Cameras.pixel_frame, image_size_px; block/pixels.py): the
conversion of --gcp-list and that of review's chips are one, and the per-camera tables
follow cameras when they are appended or split per strip."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from baarda.block.camera import cameras_per_strip, with_camera
from baarda.block.photo_block import Cameras
from baarda.block.pixels import centred, frame_to_mm, known_grid, mm_to_pixels, pixels_to_mm
from baarda.review.chips import to_pixel
from baarda.simulate.aerial import FlightPlan, simulate_block


def _cams():
    """Camera 0: origin at the centre, non-square pixels (COLMAP fx != fy); camera 1:
    origin at a principal point off the centre (MicMac), its image size unknown."""
    return Cameras(["a", "b"], np.array([2.4, 3.0]), np.zeros((2, 2)),
                   pixel_frame=np.array([[np.nan, np.nan, 0.002, 0.0025],
                                         [101.25, 70.75, 0.004, 0.005]]),
                   image_size_px=np.array([[400.0, 300.0], [np.nan, np.nan]]))


def test_gcp_pixels_and_chip_pixels_are_one_convention():
    """A gcp_list pixel u (first centre at 0) is the chip's column u + 0.5 (corner at 0), on
    both cameras, by hand: camera 0's pixel (0, 0) is x = (0.5 - 200) 0.002 mm, y = (150 -
    0.5) 0.0025 mm; camera 1's (101.25 - 0.5, 70.75 - 0.5) is its origin."""
    cams = _cams()
    xy = pixels_to_mm(cams, np.array([0, 1]), np.array([[0.0, 0.0], [100.75, 70.25]]))
    np.testing.assert_allclose(xy, [[-0.399, 0.37375], [0.0, 0.0]], atol=1e-15)
    uv = np.array([[17.0, 250.0], [3.0, 9.0]])
    cam = np.array([0, 1])
    xy = pixels_to_mm(cams, cam, uv)
    for k in range(2):
        frame = tuple(cams.pixel_frame[cam[k]])
        col, row = to_pixel(frame, 400, 300, *xy[k])
        assert (col, row) == pytest.approx((uv[k, 0] + 0.5, uv[k, 1] + 0.5), abs=1e-9)
    np.testing.assert_allclose(mm_to_pixels(cams, cam, xy), uv, atol=1e-9)
    np.testing.assert_allclose(frame_to_mm(cams.pixel_frame, [[400, 300]] * 2, uv + 0.5), xy,
                               atol=1e-12)
    # the GCP code needs the size (to check a pixel is on the image): camera 1 has none
    assert known_grid(cams).tolist() == [True, False]
    assert known_grid(Cameras(["c"], np.ones(1), np.zeros((1, 2)),
                              pixel_frame=centred(1, 0.001))).tolist() == [False]


def test_per_camera_tables_follow_their_cameras():
    """with_camera stacks the frame and the size (NaN where a camera has none);
    cameras_per_strip takes each copy's from its camera."""
    cams = _cams()
    bare = Cameras(["z"], np.array([5.0]), np.zeros((1, 2)))
    c = with_camera(bare, cams, 1)
    np.testing.assert_array_equal(c.pixel_frame, [[np.nan] * 4, [101.25, 70.75, 0.004, 0.005]])
    np.testing.assert_array_equal(c.image_size_px, [[np.nan, np.nan], [np.nan, np.nan]])
    c = with_camera(cams, cams, 0)
    np.testing.assert_array_equal(c.pixel_frame[2], cams.pixel_frame[0])
    np.testing.assert_array_equal(c.image_size_px[2], [400.0, 300.0])
    assert with_camera(bare, bare, 0).pixel_frame is None

    block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=3, pattern=5, seed=1))
    one = replace(cams, ids=["a"], focal_mm=block.cameras.focal_mm[:1],
                  principal_point_mm=np.zeros((1, 2)), pixel_frame=cams.pixel_frame[1:],
                  image_size_px=cams.image_size_px[:1])
    per = cameras_per_strip(replace(block, cameras=one,
                                    photos=replace(block.photos,
                                                   camera=np.zeros(len(block.photos),
                                                                   np.int64)))).cameras
    assert len(per) == 2 and per.ids[0].startswith("a/")
    np.testing.assert_array_equal(per.pixel_frame, cams.pixel_frame[[1, 1]])
    np.testing.assert_array_equal(per.image_size_px, cams.image_size_px[[0, 0]])


MICMAC = Path("/work/shared/data/micmac_ign_ultracam_aerial")


@pytest.mark.skipif(not MICMAC.is_dir(), reason="the shared MicMac data set is not here")
def test_a_gcp_on_micmacs_pixel_lands_on_its_measurement(tmp_path):
    """MicMac's image coordinates start at the principal point, not the image's centre: a
    GCP measured at the pixel of a tie measurement in the .mes file (its column, row less
    half a pixel: gcp_list's first centre at 0) gets that measurement's mm to 1e-9 (the
    image's centre would put it (W/2 - c0, H/2 - r0) pixels off)."""
    from baarda.block.gcp import add_gcps
    from baarda.io.gcp_list import read_gcp_list
    from baarda.pipeline import read_configured

    block, _ = read_configured(MICMAC)
    first = (MICMAC / "Filtered_all_liaisons.mes").read_text().split("\n", 1)[0].split()
    point, photo, col, row = first[0], first[1], float(first[2]), float(first[3])
    i, j = block.photos.ids.index(photo), block.point_index[point]
    k = np.flatnonzero((block.image.photo == i) & (block.image.point == j))[0]
    gcp = tmp_path / "gcp_list.txt"
    gcp.write_text(f"EPSG:32631\n500000 5000000 100 {col - 0.5!r} {row - 0.5!r} {photo} G1\n")
    sized = replace(block, cameras=replace(block.cameras,
                                           image_size_px=np.array([[26500.0, 17100.0]])))
    with_gcp = add_gcps(sized, read_gcp_list(gcp))
    g = with_gcp.point_index["G1"] if "G1" in with_gcp.point_index else \
        with_gcp.point_index["gcp G1"]
    row_g = np.flatnonzero(with_gcp.image.point == g)
    np.testing.assert_allclose(with_gcp.image.xy_mm[row_g], block.image.xy_mm[[k]],
                               atol=1e-9)
    c0, r0 = block.cameras.pixel_frame[0, :2]
    assert (26500 / 2 - c0, 17100 / 2 - r0) == pytest.approx((20, 48))  # not the centre
