"""COLMAP sparse models: cameras, images, points3D in text (.txt) or binary (.bin) form.

`read_colmap(folder)` returns a `ColmapModel` (colmap_model.py: images and points as
arrays) that holds the files faithfully (ids, camera models and parameters, poses, all 2D
keypoints, tracks, colours, errors), so that `write_colmap` writes them back unchanged
(round trip).  The files are read by colmap_text.py and colmap_binary.py; `read_colmap`
then checks that the three files agree.  The conversion to and from a baarda Block
(conventions below) is in colmap_block.py.

Conventions (https://colmap.github.io/format.html) and their conversion:

* pose (q, t) maps world to camera: X_cam = R(q) X + t, camera x right, y down, z forward;
  q = (qw, qx, qy, qz).  baarda: u = R_b^T (X - X0) with y up and z backward, so
  R_b = R^T diag(1, -1, -1) and X0 = -R^T t.
* pixels: origin at the upper-left corner of the image (pixel centres at +0.5), y down.
  baarda mm: x = (col - W/2) p, y = (H/2 - row) p fx/fy with a nominal pixel size p
  (`pixel_mm`, default 0.001 mm: 1 px = 1 µm, so image residuals in µm read as pixels);
  camera constant c = fx p, principal point ((cx - W/2) p, (H/2 - cy) p fx/fy).
* lens: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL (k), RADIAL (k1, k2), OPENCV (k1, k2, p1,
  p2), FULL_OPENCV with k4 = k5 = k6 = 0 (k3) -> ``brown_forward`` with (k1, k2, k3,
  p2, -p1) (COLMAP's y axis points down and its decentring terms are swapped).  Other
  models are read and written but not converted.
* observations: keypoints with a 3D point; a point measured twice in one image keeps the
  first keypoint (a note names the others).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.rotation import quaternion_matrix
from baarda.errors import ProjectError
from baarda.io.colmap_binary import read_cameras_bin, read_images_bin, read_points_bin
from baarda.io.colmap_model import (
    FILES,
    MODEL_ID,
    MODELS,
    ColmapCamera,
    ColmapImages,
    ColmapModel,
    ColmapPoints,
    first_repeated,
    lookup,
)
from baarda.io.colmap_text import (
    check_header_count,
    data_line,
    read_cameras_txt,
    read_images_txt,
    read_points_txt,
)

__all__ = ["FILES", "MODELS", "MODEL_ID", "ColmapCamera", "ColmapImages", "ColmapModel",
           "ColmapPoints", "is_colmap_model", "matrix_to_qvec", "model_files", "qvec_to_matrix",
           "read_colmap"]


# ----------------------------------------------------------------- rotations
def qvec_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion (qw, qx, qy, qz) (normalised first; scaled by
    its largest component before, so that no square overflows)."""
    q = np.asarray(q, float)
    q = q / np.max(np.abs(q))
    return quaternion_matrix(q / np.linalg.norm(q))


def matrix_to_qvec(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (qw >= 0) of a rotation matrix (Shepperd's method)."""
    r = np.asarray(r, float)
    tr = np.trace(r)
    cand = np.array([tr, r[0, 0], r[1, 1], r[2, 2]])
    k = int(np.argmax(cand))
    if k == 0:
        s = 2 * np.sqrt(1 + tr)
        q = [s / 4, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    elif k == 1:
        s = 2 * np.sqrt(1 + r[0, 0] - r[1, 1] - r[2, 2])
        q = [(r[2, 1] - r[1, 2]) / s, s / 4, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s]
    elif k == 2:
        s = 2 * np.sqrt(1 + r[1, 1] - r[0, 0] - r[2, 2])
        q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, s / 4, (r[1, 2] + r[2, 1]) / s]
    else:
        s = 2 * np.sqrt(1 + r[2, 2] - r[0, 0] - r[1, 1])
        q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4]
    q = np.asarray(q)
    return q if q[0] >= 0 else -q


# ------------------------------------------------------------------ public API
def _present(folder: Path, ext: str) -> list[str]:
    return [f for f in FILES if (folder / f"{f}{ext}").is_file()]


def is_colmap_model(path: str | Path) -> bool:
    """A folder with at least two of COLMAP's three model files (.txt or .bin): one with
    a file missing is recognised, so that reading it names the missing file."""
    p = Path(path)
    return p.is_dir() and any(len(_present(p, ext)) >= 2 for ext in (".txt", ".bin"))


def model_files(folder: str | Path) -> dict[str, Path]:
    """The files of a model folder that read_colmap reads (binary preferred when both
    exist), by name (cameras, images, points3D); ProjectError if there is no model, naming
    the files missing from a model that has some."""
    folder = Path(folder)
    for ext in (".bin", ".txt"):
        if all((folder / f"{f}{ext}").is_file() for f in FILES):
            return {f: folder / f"{f}{ext}" for f in FILES}
    for ext in (".bin", ".txt"):
        have = _present(folder, ext)
        if have:
            lost = [f"{f}{ext}" for f in FILES if f not in have]
            raise ProjectError(str(folder / lost[0]), "not found: a COLMAP model folder "
                               f"holds {', '.join(f + ext for f in FILES)}; this one has "
                               f"{', '.join(f + ext for f in have)} only")
    raise ProjectError(str(folder), "not a COLMAP model folder (cameras, images, points3D "
                       ".txt or .bin)")


def read_colmap(folder: str | Path) -> ColmapModel:
    """Read a COLMAP sparse model folder (binary files preferred when both exist)."""
    files = model_files(folder)
    if files["cameras"].suffix == ".bin":
        model = ColmapModel(read_cameras_bin(files["cameras"]),
                            read_images_bin(files["images"]),
                            read_points_bin(files["points3D"]))
    else:
        # each file's header count checked as it is read: a file cut short is named before
        # the other files' references to what it lost
        cameras = read_cameras_txt(files["cameras"])
        if not cameras:
            raise ProjectError(str(files["cameras"]), "holds no camera: the file is cut short "
                               "(or the model is empty)")
        check_header_count(files["cameras"], len(cameras))
        images = read_images_txt(files["images"])
        check_header_count(files["images"], len(images.ids))
        points = read_points_txt(files["points3D"])
        check_header_count(files["points3D"], len(points.ids))
        model = ColmapModel(cameras, images, points)
    _check(model, files["images"], files["points3D"])
    return model


def _check(model: ColmapModel, ifile: Path, pfile: Path) -> None:
    """The files agree: distinct ids, every image's camera and 3D points exist, every track
    element is a keypoint of its image that refers back to the point.  The first problem
    in file order is named (images before points)."""
    im, pt = model.images, model.points
    k = first_repeated(im.ids)  # the text reader names the line of a repeated id itself
    if k >= 0:
        raise ProjectError(str(ifile), f"duplicate image id {im.ids[k]}")
    k = first_repeated(pt.ids)
    if k >= 0:
        raise ProjectError(str(pfile), f"duplicate point id {pt.ids[k]}")
    bad_cam = lookup(np.fromiter(model.cameras, np.int64, len(model.cameras)),
                     im.camera_id) < 0
    pid = im.point3D_ids
    unknown = (pid != -1) & (pt.rows(pid) < 0)
    seen = np.concatenate([[0], np.cumsum(unknown)])  # unknown points before each keypoint
    bad_img = bad_cam | (seen[im.offsets[1:]] > seen[im.offsets[:-1]])
    if bad_img.any():
        k = int(np.argmax(bad_img))
        if bad_cam[k]:
            raise ProjectError(str(ifile), f"image {im.ids[k]} uses unknown camera "
                               f"{im.camera_id[k]}")
        _, ids = im.keypoints(k)
        bad = ids[(ids != -1) & (pt.rows(ids) < 0)]
        raise ProjectError(str(ifile), f"image {im.ids[k]} refers to unknown 3D point {bad[0]}")
    # track elements: image known, keypoint index inside it, keypoint refers to the point
    wrong = np.ones(len(pt.image_ids), bool)
    row = im.rows(pt.image_ids)
    e = np.flatnonzero(row >= 0)
    row, idx = row[e], pt.point2D_idxs[e]
    inside = (idx >= 0) & (idx < im.keypoint_counts[row])
    e, row, idx = e[inside], row[inside], idx[inside]
    wrong[e] = pid[im.offsets[row] + idx] != np.repeat(pt.ids, pt.track_lengths)[e]
    if wrong.any():
        e = int(np.argmax(wrong))
        j = int(np.searchsorted(pt.offsets, e, side="right")) - 1
        line = data_line(pfile, j) if pfile.suffix == ".txt" else None
        if im.rows(pt.image_ids[e:e + 1])[0] < 0:
            raise ProjectError(str(pfile), f"point {pt.ids[j]} is seen in image "
                               f"{pt.image_ids[e]}, which {ifile.name} does not hold (it holds "
                               f"{len(im)} image(s): is {ifile.name} cut short?)", line,
                               "TRACK")
        raise ProjectError(str(pfile), f"point {pt.ids[j]}: track element ({pt.image_ids[e]}, "
                           f"{pt.point2D_idxs[e]}) does not point back to this point", line,
                           "TRACK")
