"""Bundler and NVM files written from a COLMAP model by a writer other than baarda's: pycolmap
reads the model, and the files are written by the formats' published conventions (Bundler's
documentation; VisualSFM's NVM documentation), the way COLMAP's exporters do
(src/colmap/scene/reconstruction_io.cc) except where COLMAP departs from the format: its NVM
measurements are from the image corner, not the image centre (colmap/colmap issue 946).
pycolmap 4 no longer has export_bundler / export_NVM, so this stands in for them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pycolmap


def _distortion(camera) -> tuple[float, float]:
    name = camera.model.name
    if name in ("SIMPLE_PINHOLE", "PINHOLE"):
        return 0.0, 0.0
    if name == "SIMPLE_RADIAL":
        return float(camera.params[3]), 0.0
    if name == "RADIAL":
        return float(camera.params[3]), float(camera.params[4])
    raise ValueError(f"{name}: Bundler holds SIMPLE_RADIAL, RADIAL and pinhole cameras")


def export_bundler(model: str | Path, folder: Path) -> Path:
    """bundle.out and list.txt of a COLMAP model; the path of bundle.out."""
    r = pycolmap.Reconstruction(str(model))
    ids = sorted(r.reg_image_ids())
    index = {i: k for k, i in enumerate(ids)}
    out = ["# Bundle file v0.3", f"{len(ids)} {r.num_points3D()}"]
    names = []
    for i in ids:
        im = r.images[i]
        cam = r.cameras[im.camera_id]
        k1, k2 = _distortion(cam)
        pose = im.cam_from_world()
        rot = pose.rotation.matrix() * np.array([1.0, -1.0, -1.0])[:, None]  # y up, -z
        t = pose.translation * np.array([1.0, -1.0, -1.0])
        out.append(f"{float(cam.mean_focal_length())!r} {k1!r} {k2!r}")
        out += [" ".join(repr(float(v)) for v in row) for row in rot]
        out.append(" ".join(repr(float(v)) for v in t))
        names.append(im.name)
    for pid in sorted(r.points3D):
        p = r.points3D[pid]
        out.append(" ".join(repr(float(v)) for v in p.xyz))
        out.append(" ".join(str(int(v)) for v in p.color))
        views = []
        for e in p.track.elements:
            views.append(_view(r, index, e, y_up=True))
        out.append(f"{len(views)} " + " ".join(views))
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "bundle.out").write_text("\n".join(out) + "\n")
    (folder / "list.txt").write_text("\n".join(names) + "\n")
    return folder / "bundle.out"


def _view(r, index: dict, e, y_up: bool) -> str:
    """'camera key x y' of a track element, x and y from the principal point (y up: Bundler;
    y down: NVM)."""
    im = r.images[e.image_id]
    cam = r.cameras[im.camera_id]
    x, y = im.points2D[e.point2D_idx].xy
    dy = cam.principal_point_y - y if y_up else y - cam.principal_point_y
    return (f"{index[e.image_id]} {e.point2D_idx} {float(x - cam.principal_point_x)!r} "
            f"{float(dy)!r}")


def export_nvm(model: str | Path, path: Path) -> Path:
    """A VisualSFM NVM_V3 file of a COLMAP model (measurements from the principal point, r =
    -k of a SIMPLE_RADIAL camera, one measurement per image and point: the lowest keypoint
    index, the one COLMAP's reader and baarda's keep)."""
    r = pycolmap.Reconstruction(str(model))
    ids = sorted(r.reg_image_ids())
    index = {i: k for k, i in enumerate(ids)}
    out = ["NVM_V3", "", str(len(ids))]
    for i in ids:
        im = r.images[i]
        cam = r.cameras[im.camera_id]
        k1, k2 = _distortion(cam)
        if k2:
            raise ValueError("NVM holds one radial term")
        x, y, z, w = map(float, im.cam_from_world().rotation.quat)  # pycolmap: x y z w
        c = [float(v) for v in im.projection_center()]
        out.append(f"{im.name} {float(cam.mean_focal_length())!r} {w!r} {x!r} {y!r} {z!r} "
                   f"{c[0]!r} {c[1]!r} {c[2]!r} {-k1!r} 0")
    out += ["", str(r.num_points3D())]
    for pid in sorted(r.points3D):
        p = r.points3D[pid]
        views = []
        lowest: dict[int, int] = {}  # one measurement per image: its lowest keypoint index
        for e in p.track.elements:
            lowest[e.image_id] = min(lowest.get(e.image_id, e.point2D_idx), e.point2D_idx)
        for e in p.track.elements:
            if lowest.get(e.image_id) != e.point2D_idx:
                continue
            del lowest[e.image_id]
            views.append(_view(r, index, e, y_up=False))
        out.append(" ".join(repr(float(v)) for v in p.xyz) + " " +
                   " ".join(str(int(v)) for v in p.color) + f" {len(views)} " + " ".join(views))
    out += ["", "0", ""]
    path.write_text("\n".join(out) + "\n")
    return path
