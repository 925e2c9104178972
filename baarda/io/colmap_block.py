"""COLMAP models <-> baarda blocks: poses, pixels and lens models converted explicitly.

The conventions are stated in colmap.py's docstring: world-to-camera poses with x right,
y down, z forward become baarda's R_b = R^T diag(1, -1, -1), X0 = -R^T t; pixels (origin at
the upper-left corner, y down) become mm with a nominal pixel size.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.block.rotation import angles_from_matrix, rotation_matrix
from baarda.errors import ProjectError
from baarda.io.colmap import (
    ColmapCamera,
    ColmapImage,
    ColmapModel,
    ColmapPoint,
    matrix_to_qvec,
    qvec_to_matrix,
    read_colmap,
)

# camera models with a baarda lens model
CONVERTIBLE = ("SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV", "FULL_OPENCV")

FLIP = np.diag([1.0, -1.0, -1.0])


def pose_to_eo(qvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    """COLMAP world-to-camera pose -> baarda EO (X0, Y0, Z0, omega, phi, kappa)."""
    r = qvec_to_matrix(qvec)
    return np.concatenate([-r.T @ np.asarray(tvec, float), angles_from_matrix(r.T @ FLIP)])


def eo_to_pose(eo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """baarda EO -> COLMAP (qvec, tvec)."""
    rb = rotation_matrix(eo[3], eo[4], eo[5])
    r = FLIP @ rb.T
    return matrix_to_qvec(r), -r @ np.asarray(eo[:3], float)



def _camera_to_baarda(c: ColmapCamera, pm: float, where: str):
    p = c.params
    k = np.zeros(5)
    if c.model in ("SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL"):
        fx = fy = p[0]
        cx, cy = p[1], p[2]
        k[: len(p) - 3] = p[3:]
    elif c.model in ("PINHOLE", "OPENCV", "FULL_OPENCV"):
        fx, fy, cx, cy = p[:4]
        if c.model != "PINHOLE":
            k1, k2, p1, p2 = p[4:8]
            k[:] = [k1, k2, 0.0, p2, -p1]
        if c.model == "FULL_OPENCV":
            if np.any(p[9:12] != 0):
                raise ProjectError(where, "FULL_OPENCV with k4..k6 (rational model) is not "
                                   "supported")
            k[2] = p[8]
    else:
        raise ProjectError(where, f"camera model {c.model} cannot be converted (supported: "
                           f"{', '.join(CONVERTIBLE)})")
    if fx <= 0 or fy <= 0:
        raise ProjectError(where, "focal length must be positive")
    pmy = pm * fx / fy
    pp = ((cx - c.width / 2) * pm, (c.height / 2 - cy) * pmy)
    return fx * pm, pp, pmy, ("brown_forward" if np.any(k) else "none"), k


def colmap_to_block(model: ColmapModel, pixel_mm: float = 0.001, sigma_px: float = 1.0,
                    name: str = "colmap", source: str = "") -> Block:
    """Block of a COLMAP model: photos = images (EO from the poses), tie points = points3D."""
    if not model.images or not model.points3D:
        raise ProjectError(source or name, "the model has no images or no 3D points")
    cam_ids = list(model.cameras)
    cams = [_camera_to_baarda(model.cameras[c], pixel_mm, f"{source or name}: camera {c}")
            for c in cam_ids]
    cam_index = {c: i for i, c in enumerate(cam_ids)}
    img_ids = list(model.images)
    names = [model.images[i].name for i in img_ids]
    photo_ids = ([Path(n).stem for n in names] if len({Path(n).stem for n in names}) ==
                 len(names) else [str(i) for i in img_ids])
    eo = np.array([pose_to_eo(model.images[i].qvec, model.images[i].tvec) for i in img_ids])
    pt_ids = list(model.points3D)
    pt_index = {p: j for j, p in enumerate(pt_ids)}
    photo, point, xy, dropped = [], [], [], []
    for k, iid in enumerate(img_ids):
        im = model.images[iid]
        sel = np.flatnonzero(im.point3D_ids != -1)
        pids = im.point3D_ids[sel]
        _, first = np.unique(pids, return_index=True)
        keep = np.zeros(len(sel), bool)
        keep[first] = True
        dropped += [f"{pid} in {im.name}" for pid in pids[~keep]]
        sel = sel[keep]
        ci = cam_index[im.camera_id]
        c = model.cameras[im.camera_id]
        pmy = cams[ci][2]
        photo.append(np.full(len(sel), k))
        point.append(np.array([pt_index[int(p)] for p in im.point3D_ids[sel]], dtype=np.int64))
        xy.append(np.column_stack([(im.xys[sel, 0] - c.width / 2) * pixel_mm,
                                   (c.height / 2 - im.xys[sel, 1]) * pmy]))
    notes = [f"COLMAP model: nominal pixel size {pixel_mm:g} mm (1 px = {pixel_mm * 1e3:g} µm), "
             "image origin at the image centre, y up; poses converted from world-to-camera"]
    if dropped:
        notes.append(f"{len(dropped)} repeated keypoint(s) of one point in one image left out "
                     f"(first kept): {', '.join(dropped[:10])}")
    cameras = Cameras([str(c) for c in cam_ids], np.array([c[0] for c in cams]),
                      np.array([c[1] for c in cams]),
                      np.array([c[3] for c in cams], dtype=object),
                      np.array([c[4] for c in cams]))
    photos = Photos(photo_ids, np.array([cam_index[model.images[i].camera_id]
                                         for i in img_ids], dtype=np.int64),
                    np.full(len(img_ids), "", dtype=object), eo)
    photo_a = np.concatenate(photo)
    image = ImagePoints(photo_a, np.concatenate(point), np.vstack(xy),
                        np.full(len(photo_a), sigma_px * pixel_mm))
    xyz = np.array([model.points3D[p].xyz for p in pt_ids])
    points = GroundPoints([str(p) for p in pt_ids], xyz, np.full((len(pt_ids), 3), np.nan),
                          np.full(len(pt_ids), "tie", dtype=object))
    settings = Settings(name=name, angle_unit="deg", sigma_image_um=sigma_px * pixel_mm * 1e3,
                        datum="free")
    return Block(settings, cameras, photos, image, points, source=source, notes=notes)


def colmap_with_block(model: ColmapModel, eo: np.ndarray, xyz: np.ndarray,
                      errors: np.ndarray | None = None) -> ColmapModel:
    """A copy of `model` with the poses of `eo` (image order) and coordinates `xyz` (point
    order of the model, NaN = keep) and, if given, new per-point errors [px]."""
    images = {}
    for k, (iid, im) in enumerate(model.images.items()):
        q, t = eo_to_pose(eo[k])
        images[iid] = ColmapImage(q, t, im.camera_id, im.name, im.xys.copy(),
                                  im.point3D_ids.copy())
    points = {}
    for j, (pid, p) in enumerate(model.points3D.items()):
        new = xyz[j] if np.isfinite(xyz[j]).all() else p.xyz
        err = p.error if errors is None or not np.isfinite(errors[j]) else float(errors[j])
        points[pid] = ColmapPoint(np.array(new, float), p.rgb.copy(), err, p.image_ids.copy(),
                                  p.point2D_idxs.copy())
    return ColmapModel(dict(model.cameras), images, points)


def read_colmap_block(folder: str | Path, **kw) -> Block:
    folder = Path(folder)
    return colmap_to_block(read_colmap(folder), name=kw.pop("name", folder.name),
                           source=str(folder), **kw)
