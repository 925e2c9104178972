"""COLMAP models <-> baarda blocks: poses, pixels and lens models converted explicitly.

The conventions are stated in colmap.py's docstring: world-to-camera poses with x right,
y down, z forward become baarda's R_b = R^T diag(1, -1, -1), X0 = -R^T t; pixels (origin at
the upper-left corner, y down) become mm with a nominal pixel size.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block, Cameras, GroundPoints, ImagePoints, Photos, Settings
from baarda.block.rotation import eo_of_pose, pose_of_eo
from baarda.errors import ProjectError
from baarda.io.colmap import (
    FILES,
    ColmapCamera,
    ColmapModel,
    matrix_to_qvec,
    model_files,
    qvec_to_matrix,
    read_colmap,
)
from baarda.io.colmap_model import lookup
from baarda.io.records import check_pixel_options

# camera models with a baarda lens model
CONVERTIBLE = ("SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV", "FULL_OPENCV")


def pose_to_eo(qvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    """COLMAP world-to-camera pose -> baarda EO (X0, Y0, Z0, omega, phi, kappa)."""
    return eo_of_pose(qvec_to_matrix(qvec), tvec)


def eo_to_pose(eo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """baarda EO -> COLMAP (qvec, tvec)."""
    r, t = pose_of_eo(eo)
    return matrix_to_qvec(r), t


def _camera_to_baarda(c: ColmapCamera, pm: float, where: str, cid: int):
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
                raise ProjectError(where, f"camera {cid}: FULL_OPENCV with k4..k6 (rational "
                                   "model) is not supported")
            k[2] = p[8]
    else:
        raise ProjectError(where, f"camera {cid}: camera model {c.model} cannot be converted "
                           f"(supported: {', '.join(CONVERTIBLE)})")
    if fx <= 0 or fy <= 0:
        raise ProjectError(where, f"camera {cid}: focal length must be positive")
    pmy = pm * fx / fy
    pp = ((cx - c.width / 2) * pm, (c.height / 2 - cy) * pmy)
    return fx * pm, pp, pmy, ("brown_forward" if np.any(k) else "none"), k


def colmap_to_block(model: ColmapModel, pixel_mm: float = 0.001, sigma_px: float = 1.0,
                    name: str = "colmap", source: str = "",
                    files: dict[str, Path] | None = None) -> Block:
    """Block of a COLMAP model: photos = images (EO from the poses), tie points = points3D
    (both in model order); image points = the keypoints with a 3D point, image by image.
    files: the model's files by name (colmap.model_files), named by the errors."""
    from baarda.io import colmap_kernels as ck  # numba, loaded only for COLMAP models

    check_pixel_options(pixel_mm, sigma_px)
    im, pt = model.images, model.points
    where = {f: str(files[f]) if files else source or name for f in FILES}
    if not len(im) or not len(pt):
        raise ProjectError(source or name, "the model has no images or no 3D points")
    cam_ids = list(model.cameras)
    cams = [_camera_to_baarda(model.cameras[c], pixel_mm, where["cameras"], c)
            for c in cam_ids]
    cam_of_image = lookup(np.array(cam_ids, np.int64), im.camera_id)
    if np.any(cam_of_image < 0):
        k = int(np.argmax(cam_of_image < 0))
        raise ProjectError(where["images"], f"image {im.ids[k]} uses unknown camera "
                           f"{im.camera_id[k]}")
    names = im.names
    photo_ids = ([Path(n).stem for n in names] if len({Path(n).stem for n in names}) ==
                 len(names) else [str(i) for i in im.ids.tolist()])
    zero = ~(np.abs(im.qvec).max(axis=1) > 0)
    if zero.any():
        raise ProjectError(where["images"], f"image {im.ids[int(np.argmax(zero))]}: the "
                           "quaternion QW QX QY QZ is zero (no rotation)")
    eo = np.array([pose_to_eo(q, t) for q, t in zip(im.qvec, im.tvec, strict=True)])
    # keypoints with a 3D point; a point repeated in one image keeps its first keypoint
    has = im.point3D_ids != -1
    rows = np.where(has, pt.rows(im.point3D_ids), -1)
    unknown = has & (rows < 0)
    if unknown.any():
        raise ProjectError(where["images"], f"unknown 3D point {im.point3D_ids[unknown][0]}")
    again = ck.repeated_in_image(im.offsets, rows, len(pt))
    photo_of = im.image_of_keypoint()
    dropped = [f"{p} in {names[k]}" for p, k in zip(im.point3D_ids[again].tolist(),
                                                     photo_of[again].tolist(), strict=True)]
    sel = np.flatnonzero((rows >= 0) & ~again)
    photo, point = photo_of[sel], rows[sel]
    cam = cam_of_image[photo]
    width = np.array([model.cameras[c].width for c in cam_ids], float)[cam]
    height = np.array([model.cameras[c].height for c in cam_ids], float)[cam]
    pmy = np.array([c[2] for c in cams])[cam]
    xy = np.column_stack([(im.xys[sel, 0] - width / 2) * pixel_mm,
                          (height / 2 - im.xys[sel, 1]) * pmy])
    notes = [f"COLMAP model: nominal pixel size {pixel_mm:g} mm (1 px = {pixel_mm * 1e3:g} µm), "
             "image origin at the image centre, y up; poses converted from world-to-camera"]
    if dropped:
        notes.append(f"{len(dropped)} repeated keypoint(s) of one point in one image left out "
                     f"(first kept): {', '.join(dropped[:10])}")
    cameras = Cameras([str(c) for c in cam_ids], np.array([c[0] for c in cams]),
                      np.array([c[1] for c in cams]),
                      np.array([c[3] for c in cams], dtype=object),
                      np.array([c[4] for c in cams]),
                      pixel_frame=np.array([[np.nan, np.nan, pixel_mm, c[2]] for c in cams]),
                      image_size_px=np.array([[model.cameras[c].width, model.cameras[c].height]
                                              for c in cam_ids], float))
    photos = Photos(photo_ids, cam_of_image, np.full(len(im), "", dtype=object), eo,
                    image=[str(n) for n in names])  # relative to images/ (review)
    # y is scaled by fx/fy (square pixels of size pixel_mm in x): its sigma is sigma_px in
    # y's own unit, sigma_px * pixel_mm * fx/fy, so that v'P v is that of the pixels
    sxy = None
    if np.any(pmy != pixel_mm):
        sxy = np.column_stack([np.full(len(photo), sigma_px * pixel_mm), sigma_px * pmy])
    image = ImagePoints(photo, point, xy, np.full(len(photo), sigma_px * pixel_mm) if sxy is
                        None else np.sqrt(0.5 * (sxy ** 2).sum(axis=1)), None, sxy)
    points = GroundPoints([str(p) for p in pt.ids.tolist()], pt.xyz.copy(),
                          np.full((len(pt), 3), np.nan),
                          np.full(len(pt), "tie", dtype=object))
    settings = Settings(name=name, angle_unit="deg", sigma_image_um=sigma_px * pixel_mm * 1e3,
                        datum="free")
    return Block(settings, cameras, photos, image, points, source=source, notes=notes)


def colmap_with_block(model: ColmapModel, eo: np.ndarray, xyz: np.ndarray,
                      errors: np.ndarray | None = None) -> ColmapModel:
    """A copy of `model` with the poses of `eo` (image order) and coordinates `xyz` (point
    order of the model, NaN = keep) and, if given, new per-point errors [px]."""
    im, pt = model.images, model.points
    poses = [eo_to_pose(e) for e in eo[:len(im)]]
    qvec = np.array([q for q, _ in poses]).reshape(len(im), 4)
    tvec = np.array([t for _, t in poses]).reshape(len(im), 3)
    images = replace(im, qvec=qvec, tvec=tvec, camera_id=im.camera_id.copy(),
                     ids=im.ids.copy(), names=list(im.names), offsets=im.offsets.copy(),
                     xys=im.xys.copy(), point3D_ids=im.point3D_ids.copy())
    xyz = np.asarray(xyz, float)
    new = np.where(np.isfinite(xyz).all(axis=1)[:, None], xyz, pt.xyz)
    error = pt.error.copy()
    if errors is not None:
        errors = np.asarray(errors, float)
        error = np.where(np.isfinite(errors), errors, error)
    points = replace(pt, ids=pt.ids.copy(), xyz=new, rgb=pt.rgb.copy(), error=error,
                     offsets=pt.offsets.copy(), image_ids=pt.image_ids.copy(),
                     point2D_idxs=pt.point2D_idxs.copy())
    return ColmapModel(dict(model.cameras), images, points)


def read_colmap_block(folder: str | Path, **kw) -> Block:
    folder = Path(folder)
    return colmap_to_block(read_colmap(folder), name=kw.pop("name", folder.name),
                           source=str(folder), files=model_files(folder), **kw)
