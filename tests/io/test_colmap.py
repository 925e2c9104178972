"""COLMAP reader/writer on the Maupertuis model (tests/data, BSD-3 notice).

* the stored per-point mean reprojection errors (ERROR column, computed by COLMAP) are
  reproduced by baarda's projection of the converted block;
* text and binary round trips are exact; pycolmap reads what we write and projects every
  observation where baarda does;
* an adjusted model written back and read again carries the adjusted poses and points.
"""

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from baarda.bundle.collinearity import project
from baarda.bundle.free_network import adjust_free
from baarda.errors import ProjectError
from baarda.io.colmap import (
    ColmapCamera,
    ColmapImages,
    ColmapModel,
    ColmapPoints,
    matrix_to_qvec,
    qvec_to_matrix,
    read_colmap,
)
from baarda.io.colmap_block import colmap_to_block, colmap_with_block, eo_to_pose, pose_to_eo
from baarda.output.format_files import write_colmap
from baarda.pipeline import read

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
    assert list(a.cameras) == list(b.cameras)
    for k, c in a.cameras.items():
        d = b.cameras[k]
        assert (c.model, c.width, c.height) == (d.model, d.width, d.height)
        assert np.array_equal(c.params, d.params)
    assert a.images.names == b.images.names
    for f in ("ids", "qvec", "tvec", "camera_id", "offsets", "xys", "point3D_ids"):
        x, y = getattr(a.images, f), getattr(b.images, f)
        assert x.dtype == y.dtype and np.array_equal(x, y), f
    for f in ("ids", "xyz", "rgb", "error", "offsets", "image_ids", "point2D_idxs"):
        x, y = getattr(a.points, f), getattr(b.points, f)
        assert x.dtype == y.dtype and np.array_equal(x, y), f


def test_maupertuis_counts_and_stored_errors():
    model = read_colmap(SPARSE)
    assert (len(model.cameras), len(model.images), len(model.points)) == (1, 4, 1039)
    assert int(np.sum(model.images.point3D_ids >= 0)) == 3355
    assert len(model.images.xys) == model.images.offsets[-1] == 24010
    assert model.points.offsets[-1] == 3355
    block = colmap_to_block(model)
    # 3355 track elements, 5 repeated keypoints of 4 points in one image are left out
    assert len(block.image) == 3350 and "repeated" in block.notes[-1]
    e, per = _errors(block)
    stored = model.points.error[model.points.rows(np.array(block.points.ids, np.int64))]
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
    q = model.images.qvec  # pycolmap does not normalise quaternions
    model = replace(model, images=replace(model.images,
                                          qvec=q / np.linalg.norm(q, axis=1, keepdims=True)))
    write_colmap(model, tmp_path, binary=True)
    rec = pycolmap.Reconstruction(str(tmp_path))
    assert rec.num_points3D() == 1039 and rec.num_images() == 4
    block = colmap_to_block(model)
    im = block.image
    cam = block.photos.camera[im.photo]
    p = project(block.photos.eo[im.photo], block.points.xyz[im.point],
                block.cameras.focal_mm[cam], block.cameras.principal_point_mm[cam])
    img_ids = model.images.ids.tolist()
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


# ------------------------------------------------------------- arrays, fast paths, checks
def _synthetic(n_images=4, n_points=6, track=3, seed=0) -> ColmapModel:
    """A consistent model: every point seen in `track` consecutive images (mod n_images),
    keypoints of an image in point order, then 2 keypoints without a point."""
    rng = np.random.default_rng(seed)
    point = np.repeat(np.arange(n_points), track)
    image = ((rng.integers(n_images, size=n_points)[:, None] + np.arange(track)) %
             n_images).ravel()
    order = np.lexsort((point, image))
    per = np.bincount(image, minlength=n_images) + 2
    offsets = np.concatenate([[0], np.cumsum(per)])
    slot = np.arange(len(order)) - np.concatenate([[0], np.cumsum(per - 2)])[image[order]]
    idx = np.empty(len(point), np.int64)
    idx[order] = slot
    pids = np.full(offsets[-1], -1, np.int64)
    pids[offsets[image[order]] + slot] = point[order] + 1
    images = ColmapImages(np.arange(1, n_images + 1), np.tile([1.0, 0, 0, 0], (n_images, 1)),
                          rng.normal(size=(n_images, 3)), np.ones(n_images, np.int64),
                          [f"img{i}.jpg" for i in range(n_images)], offsets,
                          rng.uniform(0, 1000, (offsets[-1], 2)), pids)
    points = ColmapPoints(np.arange(1, n_points + 1), rng.normal(size=(n_points, 3)),
                          rng.integers(0, 256, (n_points, 3)).astype(np.uint8),
                          rng.uniform(0, 2, n_points), track * np.arange(n_points + 1),
                          image + 1, idx)
    cams = {1: ColmapCamera("PINHOLE", 1000, 800, np.array([900.0, 900, 500, 400]))}
    return ColmapModel(cams, images, points)


def test_arrays_and_helpers(tmp_path):
    model = _synthetic()
    for binary in (False, True):
        write_colmap(model, tmp_path / str(binary), binary=binary)
        _same(model, read_colmap(tmp_path / str(binary)))
    im, pt = model.images, model.points
    xys, ids = im.keypoints(2)
    assert np.array_equal(xys, im.xys[im.offsets[2]:im.offsets[3]]) and len(ids) == len(xys)
    assert np.array_equal(im.image_of_keypoint(), np.repeat(np.arange(4), im.keypoint_counts))
    assert np.array_equal(im.rows([3, 9, 1]), [2, -1, 0])
    images, idxs = pt.track(5)
    assert len(images) == pt.track_lengths[5] == 3
    # every track element points back to its point
    rows = im.rows(pt.image_ids)
    assert np.array_equal(im.point3D_ids[im.offsets[rows] + pt.point2D_idxs],
                          pt.ids[pt.point_of_element()])


def _broken(tmp_path, binary, images=None, points=None):
    model = _synthetic()
    model = replace(model, images=replace(model.images, **(images or {})),
                    points=replace(model.points, **(points or {})))
    folder = tmp_path / ("bin" if binary else "txt")
    write_colmap(model, folder, binary=binary)
    with pytest.raises(ProjectError) as e:
        read_colmap(folder)
    return e.value


@pytest.mark.parametrize("binary", [False, True])
def test_model_checks(tmp_path, binary):
    m = _synthetic()
    im, pt = m.images, m.points
    ext = ".bin" if binary else ".txt"
    pid = im.point3D_ids.copy()
    k = im.offsets[2]  # the first keypoint of image 3
    pid[k] = 99
    err = _broken(tmp_path, binary, images={"point3D_ids": pid})
    assert err.detail == "image 3 refers to unknown 3D point 99"
    assert Path(err.path).name == f"images{ext}"
    cam = im.camera_id.copy()
    cam[3] = 5  # a later image with an unknown camera: the first problem is named
    err = _broken(tmp_path, binary, images={"point3D_ids": pid, "camera_id": cam})
    assert err.detail == "image 3 refers to unknown 3D point 99"
    cam[1] = 5
    err = _broken(tmp_path, binary, images={"point3D_ids": pid, "camera_id": cam})
    assert err.detail == "image 2 uses unknown camera 5"
    # track elements: a keypoint of another point, beyond the image's keypoints, of an
    # unknown image
    for field, value in (("point2D_idxs", 1), ("point2D_idxs", 50), ("image_ids", 9)):
        arr = getattr(pt, field).copy()
        e = pt.offsets[4] + 1  # the second element of point 5
        arr[e] = value if field == "image_ids" else (pt.point2D_idxs[e] + 1
                                                     if value == 1 else value)
        iid = arr[e] if field == "image_ids" else pt.image_ids[e]
        idx = arr[e] if field == "point2D_idxs" else pt.point2D_idxs[e]
        err = _broken(tmp_path, binary, points={field: arr})
        if field == "image_ids":  # issue 28: the file that lacks the image is named
            assert err.detail == (f"point 5 is seen in image 9, which images{ext} does not "
                                  "hold (it holds 4 image(s): is images" + ext + " cut short?)")
        else:
            assert err.detail == (f"point 5: track element ({iid}, {idx}) does not point "
                                  "back to this point")
        assert Path(err.path).name == f"points3D{ext}"
        assert err.line == (None if binary else 8)  # the fifth record, after 3 comments


@pytest.mark.parametrize("binary", [False, True])
def test_numbers_that_are_not_finite(tmp_path, binary):
    """Fuzz find (issue 15): the binary reader took NaN and inf (the text reader refuses
    them), which reached the geometry as numpy's LinAlgError."""
    m = _synthetic()
    im, pt = m.images, m.points
    qvec, xys, xyz = im.qvec.copy(), im.xys.copy(), pt.xyz.copy()
    qvec[1, 2] = np.nan
    err = _broken(tmp_path, binary, images={"qvec": qvec})
    assert ("image 2: QW QX QY QZ TX TY TZ: not a finite number" if binary else
            "'nan' is not a finite number") in err.detail
    xys[im.offsets[2] + 1, 1] = np.inf
    err = _broken(tmp_path, binary, images={"xys": xys})
    assert ("image 3: keypoint 1 is not a finite number" if binary else
            "'inf' is not a finite number") in err.detail
    xyz[3, 0] = -np.inf
    err = _broken(tmp_path, binary, points={"xyz": xyz})
    assert ("point 4: X Y Z ERROR: not a finite number" if binary else
            "'-inf' is not a finite number") in err.detail
    model = replace(m, cameras={1: ColmapCamera("PINHOLE", 1000, 800,
                                                np.array([900.0, np.inf, 500, 400]))})
    write_colmap(model, tmp_path / "cam", binary=binary)
    with pytest.raises(ProjectError, match="not a finite number") as e:
        read_colmap(tmp_path / "cam")
    assert Path(e.value.path).name == f"cameras{'.bin' if binary else '.txt'}"
    empty = ColmapModel(m.cameras)  # no images, no points: read, refused by the conversion
    write_colmap(empty, tmp_path / "empty", binary=binary)
    assert len(read_colmap(tmp_path / "empty").images) == 0
    with pytest.raises(ProjectError, match="no images or no 3D points"):
        read(tmp_path / "empty")


@pytest.mark.parametrize("binary", [False, True])
def test_zero_and_huge_quaternions(tmp_path, binary):
    """Fuzz finds (issue 15): a zero quaternion gave NaN orientations, a huge one overflowed
    in its norm (numpy's RuntimeWarnings); zero is refused, any other is normalised."""
    m = _synthetic()
    qvec = m.images.qvec.copy()
    qvec[2] = 0.0
    write_colmap(replace(m, images=replace(m.images, qvec=qvec)), tmp_path / "z", binary=binary)
    with pytest.raises(ProjectError, match="image 3: the quaternion QW QX QY QZ is zero") as e:
        read(tmp_path / "z")
    assert Path(e.value.path).name == f"images{'.bin' if binary else '.txt'}"
    qvec[2] = [1e300, 0, 0, 1e300]
    write_colmap(replace(m, images=replace(m.images, qvec=qvec)), tmp_path / "h", binary=binary)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        block = read(tmp_path / "h")
    assert np.allclose(qvec_to_matrix(qvec[2]), qvec_to_matrix([1, 0, 0, 1]))
    assert np.isfinite(block.photos.eo).all()


@pytest.mark.parametrize("binary", [False, True])
def test_conversion_errors_name_the_file(tmp_path, binary):
    """Fuzz find (issue 15): errors of the conversion named '<folder>: camera 1', no file."""
    m = _synthetic()
    model = replace(m, cameras={1: ColmapCamera("PINHOLE", 1000, 800,
                                                np.array([0.0, 900, 500, 400]))})
    write_colmap(model, tmp_path, binary=binary)
    with pytest.raises(ProjectError) as e:
        read(tmp_path)
    assert e.value.path == str(tmp_path / f"cameras{'.bin' if binary else '.txt'}")
    assert e.value.detail == "camera 1: focal length must be positive"


@pytest.mark.parametrize("binary", [False, True])
def test_duplicate_ids(tmp_path, binary):
    m = _synthetic()
    ids = m.images.ids.copy()
    ids[2] = ids[0]
    err = _broken(tmp_path, binary, images={"ids": ids})
    assert "duplicate image id 1" in err.detail
    assert err.line == (None if binary else 9)  # the third image's header line
    ids = m.points.ids.copy()
    ids[4] = ids[1]
    err = _broken(tmp_path, binary, points={"ids": ids})
    assert "duplicate point id 2" in err.detail and err.line == (None if binary else 8)


@pytest.mark.slow
def test_bad_number_in_a_big_points_file(tmp_path):
    model = _synthetic(n_images=50, n_points=30_000, track=4)
    write_colmap(model, tmp_path)
    good = read_colmap(tmp_path)
    _same(model, good)
    lines = (tmp_path / "points3D.txt").read_text().splitlines()
    no = 3 + 17_345  # 3 comment lines, then point row 17,344 (1-based line 17,348)
    for tok, col, field in (("1.5e", 2, "Y"), ("x", 6, "B"), ("0x10", 9, "TRACK"),
                            ("inf", 7, "ERROR")):
        p = lines[no - 1].split()
        p[col] = tok
        (tmp_path / "points3D.txt").write_text("\n".join(lines[:no - 1] + [" ".join(p)] +
                                                         lines[no:]) + "\n")
        with pytest.raises(ProjectError) as e:
            read_colmap(tmp_path)
        assert (e.value.line, e.value.column) == (no, field), tok


def test_fast_text_readers_agree_with_the_line_reader(tmp_path, monkeypatch):
    """The tokeniser reads plain files itself (the line reader is not called) and gives
    what the line reader gives (tabs, CRLF, comment lines, signs); a file it does not take
    (underscores in numbers, a no-break space) is read line by line with the same result."""
    from baarda.io import colmap_text

    model = _synthetic(n_images=5, n_points=40)
    write_colmap(model, tmp_path)
    calls = []
    for name in ("_images_lines", "_points_lines"):
        orig = getattr(colmap_text, name)
        monkeypatch.setattr(colmap_text, name,
                            lambda *a, _o=orig, _n=name: calls.append(_n) or _o(*a))
    _same(model, read_colmap(tmp_path))
    (tmp_path / "m").mkdir()
    _same(read_colmap(SPARSE), read_colmap(_copy(tmp_path / "m", "cameras", CAM)))
    assert calls == []
    pts = (tmp_path / "points3D.txt").read_text()
    img = (tmp_path / "images.txt").read_text()
    variants = [
        ("points3D", pts.replace(" ", "\t").replace("\n", "\r\n"), False),
        ("points3D", pts.replace("\n1 ", "\n# a comment\n\n  1 ", 1), False),
        ("images", img.replace("\n", "\r\n"), False),
        ("points3D", pts.replace("\n1 ", "\n+1 ", 1), False),
        ("points3D", pts.replace("\n1 ", "\n0_1 ", 1), True),
        ("images", img.replace(" -1", " -0_1"), True),
        ("images", img.replace(" -1", " -1\u00a0", 1), True),
    ]
    for name, text, slow in variants:
        calls.clear()
        (tmp_path / f"{name}.txt").write_bytes(text.encode())
        _same(model, read_colmap(tmp_path))
        assert bool(calls) == slow, (name, text[:200])
        (tmp_path / "points3D.txt").write_text(pts)
        (tmp_path / "images.txt").write_text(img)


def _pinhole_fx_fy(folder, fx=1000.0, fy=1300.0, seed=3):
    """A COLMAP text model written by hand: one PINHOLE camera with fx != fy, 5 images
    looking down at 40 points, keypoints = projection + 1 px noise; the truth returned for
    an independent adjustment (rotation vectors, translations, points)."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    w, h, cx, cy = 1600, 1200, 790.0, 610.0
    xyz = np.column_stack([rng.uniform(-4, 4, 40), rng.uniform(-3, 3, 40),
                           rng.uniform(0, 2, 40)])
    centres = np.column_stack([np.linspace(-2, 2, 5), rng.uniform(-0.5, 0.5, 5),
                               np.full(5, -10.0)])
    rot = Rotation.from_rotvec(rng.normal(0, 0.03, (5, 3)))
    t = -np.einsum("kij,kj->ki", rot.as_matrix(), centres)
    uv = []
    for k in range(5):
        xc = rot[k].apply(xyz) + t[k]
        uv.append(np.column_stack([fx * xc[:, 0] / xc[:, 2] + cx,
                                   fy * xc[:, 1] / xc[:, 2] + cy]) + rng.normal(0, 1, (40, 2)))
    folder.mkdir(parents=True)
    (folder / "cameras.txt").write_text(f"1 PINHOLE {w} {h} {fx!r} {fy!r} {cx!r} {cy!r}\n")
    lines = []
    for k in range(5):
        qx, qy, qz, qw = (float(q) for q in rot[k].as_quat())
        tx, ty, tz = (float(v) for v in t[k])
        lines.append(f"{k + 1} {qw!r} {qx!r} {qy!r} {qz!r} {tx!r} {ty!r} {tz!r} 1 im{k}.jpg")
        lines.append(" ".join(f"{float(u)!r} {float(v)!r} {j + 1}"
                              for j, (u, v) in enumerate(uv[k])))
    (folder / "images.txt").write_text("\n".join(lines) + "\n")
    (folder / "points3D.txt").write_text("".join(
        f"{j + 1} {float(x)!r} {float(y)!r} {float(z)!r} 0 0 0 1.0 "
        + " ".join(f"{k + 1} {j}" for k in range(5)) + "\n" for j, (x, y, z) in enumerate(xyz)))
    return (fx, fy, cx, cy), rot.as_rotvec(), t, xyz, np.array(uv)


def test_pinhole_with_fx_ne_fy_minimises_the_pixels(tmp_path):
    """Issue 41: y scaled by fx/fy keeps 1 px as its sigma in its own unit, so v'Pv is the
    sum of squared pixel residuals that an independent bundle adjustment (scipy
    least_squares over poses and points, COLMAP's PINHOLE projection in pixels) minimises
    (with x's sigma for y it was vx^2 + (fx/fy)^2 vy^2)."""
    from scipy.optimize import least_squares
    from scipy.spatial.transform import Rotation

    from baarda.pipeline import adjust

    (fx, fy, cx, cy), rv, t, xyz, uv = _pinhole_fx_fy(tmp_path / "m")

    def residuals(p):
        r = []
        pts = p[30:].reshape(-1, 3)
        for k in range(5):
            xc = Rotation.from_rotvec(p[6 * k:6 * k + 3]).apply(pts) + p[6 * k + 3:6 * k + 6]
            r.append(np.column_stack([fx * xc[:, 0] / xc[:, 2] + cx,
                                      fy * xc[:, 1] / xc[:, 2] + cy]) - uv[k])
        return np.concatenate(r).ravel()

    p0 = np.concatenate([np.column_stack([rv, t]).ravel(), xyz.ravel()])
    sol = least_squares(residuals, p0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    independent = float(np.sum(sol.fun ** 2))
    block = read(tmp_path / "m")
    sxy = block.image.sigma_xy
    assert np.allclose(sxy[:, 0], 0.001) and np.allclose(sxy[:, 1], 0.001 * fx / fy)
    res = adjust(block)
    assert res.converged and res.redundancy == 2 * 5 * 40 - (6 * 5 + 3 * 40 - 7)
    assert res.vtpv == pytest.approx(independent, rel=1e-6)
