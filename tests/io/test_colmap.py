"""COLMAP reader/writer on the Maupertuis model (tests/data, BSD-3 notice).

* the stored per-point mean reprojection errors (ERROR column, computed by COLMAP) are
  reproduced by baarda's projection of the converted block;
* text and binary round trips are exact; pycolmap reads what we write and projects every
  observation where baarda does;
* an adjusted model written back and read again carries the adjusted poses and points.
"""

from pathlib import Path

import numpy as np
import pytest

from baarda.bundle.collinearity import project
from baarda.bundle.free_network import adjust_free
from baarda.errors import ProjectError
from baarda.io.colmap import matrix_to_qvec, qvec_to_matrix, read_colmap
from baarda.io.colmap_block import colmap_to_block, colmap_with_block, eo_to_pose, pose_to_eo
from baarda.output.format_files import write_colmap

SPARSE = Path(__file__).resolve().parents[1] / "data" / "colmap_maupertuis" / "sparse"


def _errors(block):
    im = block.image
    cam = block.photos.camera[im.photo]
    p = project(block.photos.eo[im.photo], block.points.xyz[im.point],
                block.cameras.focal_mm[cam], block.cameras.principal_point_mm[cam])
    e = np.hypot(*((p - im.xy_mm) / 0.001).T)
    per = np.bincount(im.point, e, len(block.points)) / np.bincount(im.point,
                                                                    minlength=len(block.points))
    return e, per


def _same(a, b):
    assert list(a.cameras) == list(b.cameras) and list(a.images) == list(b.images)
    assert list(a.points3D) == list(b.points3D)
    for k, c in a.cameras.items():
        d = b.cameras[k]
        assert (c.model, c.width, c.height) == (d.model, d.width, d.height)
        assert np.array_equal(c.params, d.params)
    for k, i in a.images.items():
        j = b.images[k]
        assert (i.name, i.camera_id) == (j.name, j.camera_id)
        for f in ("qvec", "tvec", "xys", "point3D_ids"):
            assert np.array_equal(getattr(i, f), getattr(j, f)), (k, f)
    for k, p in a.points3D.items():
        q = b.points3D[k]
        assert p.error == q.error
        for f in ("xyz", "rgb", "image_ids", "point2D_idxs"):
            assert np.array_equal(getattr(p, f), getattr(q, f)), (k, f)


def test_maupertuis_counts_and_stored_errors():
    model = read_colmap(SPARSE)
    assert (len(model.cameras), len(model.images), len(model.points3D)) == (1, 4, 1039)
    assert sum(int(np.sum(i.point3D_ids >= 0)) for i in model.images.values()) == 3355
    assert sum(len(i.xys) for i in model.images.values()) == 24010
    block = colmap_to_block(model)
    # 3355 track elements, 5 repeated keypoints of 4 points in one image are left out
    assert len(block.image) == 3350 and "repeated" in block.notes[-1]
    e, per = _errors(block)
    stored = np.array([model.points3D[int(p)].error for p in block.points.ids])
    dup = np.isin(block.points.ids, ["1014", "943", "952", "1042"])
    # the file rounds poses and points to 6 digits: agreement to 0.005 px per point
    assert np.abs(per - stored)[~dup].max() < 0.005
    assert abs(per[~dup].mean() - stored[~dup].mean()) < 1e-3
    assert f"{e.mean():.3f}" == "0.346"  # README's recomputation over all observations


def test_text_and_binary_round_trips(tmp_path):
    model = read_colmap(SPARSE)
    write_colmap(model, tmp_path / "txt")
    again = read_colmap(tmp_path / "txt")
    _same(model, again)
    write_colmap(again, tmp_path / "bin", binary=True)
    assert not (tmp_path / "bin" / "cameras.txt").exists()
    _same(model, read_colmap(tmp_path / "bin"))


def test_pycolmap_reads_what_we_write(tmp_path):
    pycolmap = pytest.importorskip("pycolmap")
    model = read_colmap(SPARSE)
    for im in model.images.values():  # pycolmap does not normalise quaternions
        im.qvec = im.qvec / np.linalg.norm(im.qvec)
    write_colmap(model, tmp_path, binary=True)
    rec = pycolmap.Reconstruction(str(tmp_path))
    assert rec.num_points3D() == 1039 and rec.num_images() == 4
    block = colmap_to_block(model)
    im = block.image
    cam = block.photos.camera[im.photo]
    p = project(block.photos.eo[im.photo], block.points.xyz[im.point],
                block.cameras.focal_mm[cam], block.cameras.principal_point_mm[cam])
    img_ids = list(model.images)
    c = rec.cameras[1]
    worst = 0.0
    for k in range(0, len(im), 7):
        image = rec.images[img_ids[im.photo[k]]]
        xyz = rec.points3D[int(block.points.ids[im.point[k]])].xyz
        pix = c.img_from_cam((image.cam_from_world() * xyz).reshape(1, 3))[0]
        ours = np.array([p[k, 0] / 0.001 + 1919 / 2, 1079 / 2 - p[k, 1] / 0.001])
        worst = max(worst, np.abs(ours - pix).max())
    assert worst < 1e-8


def test_pose_conversion_round_trip():
    rng = np.random.default_rng(1)
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        t = rng.normal(size=3)
        eo = pose_to_eo(q, t)
        q2, t2 = eo_to_pose(eo)
        assert np.allclose(qvec_to_matrix(q2), qvec_to_matrix(q), atol=1e-12)
        assert np.allclose(t2, t, atol=1e-12)
        assert np.allclose(qvec_to_matrix(matrix_to_qvec(qvec_to_matrix(q))),
                           qvec_to_matrix(q), atol=1e-12)


def test_adjusted_model_written_back(tmp_path):
    model = read_colmap(SPARSE)
    block = colmap_to_block(model)
    res = adjust_free(block)
    assert res.converged and res.sigma0 < 1
    _, per = _errors(block)
    new = colmap_with_block(model, res.eo, res.points_xyz())
    write_colmap(new, tmp_path, binary=True)
    back = colmap_to_block(read_colmap(tmp_path))
    assert np.allclose(back.photos.eo, res.eo, atol=1e-10)
    assert np.allclose(back.points.xyz, res.points_xyz(), atol=1e-10)
    # the adjustment lowers the reprojection errors of the stored model
    _, per_adj = _errors(back)
    assert np.mean(per_adj**2) < np.mean(per**2)


def _copy(tmp_path, name, text):
    for f in ("cameras", "images", "points3D"):
        src = (SPARSE / f"{f}.txt").read_text()
        (tmp_path / f"{f}.txt").write_text(text if f == name else src)
    return tmp_path


CAM = (SPARSE / "cameras.txt").read_text()
IMG = (SPARSE / "images.txt").read_text()
PTS = (SPARSE / "points3D.txt").read_text()


@pytest.mark.parametrize("name, text, line, field", [
    ("cameras", CAM.replace("SIMPLE_PINHOLE", "NOT_A_MODEL"), 4, "MODEL"),
    ("cameras", CAM.replace("1847.53 959.5 539.5", "1847.53 959.5"), 4, "PARAMS"),
    ("cameras", CAM.replace("1919", "wide"), 4, "WIDTH"),
    ("images", IMG.replace("-7.96417", "x7.9"), 5, "TX"),
    ("images", IMG.replace("355.968 4.50115 -1", "355.968 4.50115"), 6, "POINTS2D"),
    ("points3D", PTS.replace("708 -2.39675", "708 abc"), 4, "X"),
    ("points3D", PTS.replace("57 57 49", "57 300 49"), 4, "RGB"),
    ("points3D", PTS.replace(" 4 3472\n", " 4\n", 1), 4, None),
])
def test_malformed_text(tmp_path, name, text, line, field):
    with pytest.raises(ProjectError) as e:
        read_colmap(_copy(tmp_path, name, text))
    assert Path(e.value.path).name == f"{name}.txt"
    assert e.value.line == line and e.value.column == field


def test_inconsistent_track(tmp_path):
    with pytest.raises(ProjectError, match="does not point back"):
        read_colmap(_copy(tmp_path, "points3D", PTS.replace("2 4561 3 3389", "2 4562 3 3389")))


def test_truncated_binary(tmp_path):
    write_colmap(read_colmap(SPARSE), tmp_path, binary=True)
    data = (tmp_path / "images.bin").read_bytes()
    (tmp_path / "images.bin").write_bytes(data[:-5])
    with pytest.raises(ProjectError, match="ends inside") as e:
        read_colmap(tmp_path)
    assert Path(e.value.path).name == "images.bin"


def test_unsupported_camera_model_is_not_converted(tmp_path):
    model = read_colmap(_copy(tmp_path, "cameras", CAM.replace(
        "SIMPLE_PINHOLE 1919 1079 1847.53 959.5 539.5",
        "FOV 1919 1079 1847.53 1847.53 959.5 539.5 0.1")))
    with pytest.raises(ProjectError, match="FOV"):
        colmap_to_block(model)
