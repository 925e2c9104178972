"""GCP image measurements added to any block (`--gcp-list FILE`, `baarda.read(gcp_list=...)`;
the file, OpenDroneMap's gcp_list.txt, is read by io/gcp_list.py; gcp_placement.with_gcp_list
places the block in the GCPs' frame).

Each GCP becomes a control point of its own (its name, or "gcp NAME" where a point of the
block has that id), with the coordinates of the file and the block's control sigma
(settings.sigma_control_m; a height given as NaN is not observed); each of its measurements
an image observation in the block's image coordinates (block/pixels.py) with the image
sigma of the other observations of its camera.  The input's own control points become tie
points (the file replaces them, as --control does).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from baarda.block.control import without_input_control_notes
from baarda.block.photo_block import Block, ImagePoints
from baarda.block.pixels import known_grid, pixels_to_mm
from baarda.errors import ProjectError


@dataclass(frozen=True)
class GcpList:
    """A gcp_list.txt as read: its CRS and per GCP the name, coordinates in the CRS (k, 3)
    [NaN: not given] and line of its first measurement; per measurement (m) the GCP (index),
    the image name, the pixel (u, v) (origin at the upper-left corner, the first pixel's
    centre at 0, 0) and its line."""

    path: str
    crs: str
    crs_line: int
    ids: list[str]
    xyz: np.ndarray
    first_line: np.ndarray
    gcp: np.ndarray
    image: list[str]
    uv_px: np.ndarray
    line: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


def photo_of_image(block: Block, names: list[str], source: str,
                   lines: np.ndarray) -> np.ndarray:
    """The photo (index) of each image name: a photo id equal to the name or to its stem
    (readers name photos by the image file's stem); ProjectError naming the line of the
    first name that is no photo of the block."""
    index = block.photo_index
    out = np.empty(len(names), np.int64)
    for k, name in enumerate(names):
        j = index.get(name)
        if j is None:
            j = index.get(Path(name).stem)
        if j is None:
            j = index.get(Path(name).name)
        if j is None:
            ids = block.photos.ids
            sample = ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "")
            raise ProjectError(source, f"image {name!r} is not a photo of "
                               f"{block.source or block.settings.name} (its photos: {sample})",
                               int(lines[k]), "image_name")
        out[k] = j
    return out


def with_image_sizes(block: Block, photo: np.ndarray,
                     sizes: list[tuple[int, int] | None]) -> Block:
    """The block with the image size of each camera that has none (and a pixel size)
    taken from the image files of its photos (`photo` indices, `sizes` (width, height) [px]
    or None where no file was found), with a note."""
    cams = block.cameras
    if cams.pixel_frame is None:
        return block
    size = (np.full((len(cams), 2), np.nan) if cams.image_size_px is None
            else cams.image_size_px.copy())
    filled = []
    for p, wh in zip(photo.tolist(), sizes, strict=True):
        c = int(block.photos.camera[p])
        if wh is not None and not np.isfinite(size[c]).all():
            size[c] = wh
            filled.append(f"camera {cams.ids[c]} {wh[0]} x {wh[1]} px")
    if not filled:
        return block
    return replace(block, cameras=replace(cams, image_size_px=size),
                   notes=list(block.notes) + ["image size from the image files beside the "
                                              "input: " + ", ".join(filled)])


def add_gcps(block: Block, gcps: GcpList) -> Block:
    """The block with the GCPs as control points and their measurements as image
    observations (module docstring); the coordinates are the file's, in its CRS (the block's
    orientations and points are not moved here)."""
    src = gcps.path
    photo = photo_of_image(block, gcps.image, src, gcps.line)
    seen: dict[tuple[int, int], int] = {}
    for k, (g, p) in enumerate(zip(gcps.gcp.tolist(), photo.tolist(), strict=True)):
        first = seen.setdefault((g, p), int(gcps.line[k]))
        if first != int(gcps.line[k]):
            raise ProjectError(src, f"GCP {gcps.ids[g]} is measured twice on image "
                               f"{gcps.image[k]} (first on line {first})", int(gcps.line[k]),
                               "image_name")
    cam = block.photos.camera[photo]
    unknown = np.flatnonzero(~known_grid(block.cameras)[cam])
    if len(unknown):
        k = int(unknown[0])
        raise ProjectError(src, f"image {gcps.image[k]}: the image size of its camera "
                           f"{block.cameras.ids[cam[k]]} is not known (the input states none "
                           "and its image file was not found beside it), so its pixels "
                           "cannot be placed", int(gcps.line[k]), "im_x")
    size = block.cameras.image_size_px[cam]  # type: ignore[index]  # known_grid
    outside = (gcps.uv_px < -0.5) | (gcps.uv_px > size - 0.5)
    if outside.any():
        k, axis = (int(v[0]) for v in np.nonzero(outside))
        raise ProjectError(src, f"pixel {gcps.uv_px[k, axis]:g} lies outside image "
                           f"{gcps.image[k]} ({size[k, 0]:g} x {size[k, 1]:g} px, pixel "
                           f"centres 0 .. {size[k, axis] - 1:g})", int(gcps.line[k]),
                           ("im_x", "im_y")[axis])
    xy = pixels_to_mm(block.cameras, cam, gcps.uv_px)
    sigma_xy = _camera_sigmas(block)[cam]

    pts = block.points
    taken = set(pts.ids)
    names = [g if g not in taken else f"gcp {g}" for g in gcps.ids]
    k0 = len(pts)
    ctrl = np.asarray(block.settings.sigma_control_m, float)
    sig = np.where(np.isfinite(gcps.xyz), ctrl[None, :], np.nan)
    old_ctrl = pts.role == "control"
    role = np.concatenate([np.where(old_ctrl, "tie", pts.role),
                           np.full(len(gcps), "control")]).astype(object)
    points = replace(pts, ids=list(pts.ids) + names,
                     xyz=np.vstack([pts.xyz, gcps.xyz]),
                     sigma=np.vstack([np.where(old_ctrl[:, None], np.nan, pts.sigma), sig]),
                     role=role)
    im = block.image
    n = len(photo)
    image = ImagePoints(np.concatenate([im.photo, photo]),
                        np.concatenate([im.point, k0 + gcps.gcp]),
                        np.vstack([im.xy_mm, xy]),
                        np.concatenate([im.sigma_mm, np.sqrt(0.5 * (sigma_xy ** 2).sum(axis=1))]),
                        None if im.model is None else
                        np.concatenate([im.model, np.full(n, "", dtype=object)]),
                        np.vstack([im.sigma_xy, sigma_xy]))
    notes = without_input_control_notes(block.notes)  # the input's control is replaced
    if old_ctrl.any():
        notes.append(f"{src}: its GCPs replace the input's {int(old_ctrl.sum())} control "
                     "point(s) (now tie points)")
    rays = np.bincount(gcps.gcp, minlength=len(gcps))
    notes.append(f"GCPs from {src}: {len(gcps)} control point(s), {n} image measurement(s) "
                 f"({int(rays.min())} to {int(rays.max())} per GCP), sigma "
                 f"{', '.join(f'{v:g}' for v in ctrl)} m (the block's control sigma), pixels "
                 "from the upper-left corner (first pixel's centre at 0, 0)")
    return replace(block, points=points, image=image, notes=notes)


def _camera_sigmas(block: Block) -> np.ndarray:
    """(n_cameras, 2) the median image sigma [mm] of x and y of each camera's observations
    (the settings' image sigma where a camera has none)."""
    im = block.image
    cam = block.photos.camera[im.photo] if len(im) else np.zeros(0, np.int64)
    out = np.full((len(block.cameras), 2), block.settings.sigma_image_um * 1e-3)
    sxy = im.sigma_xy
    for c in np.unique(cam):
        out[c] = np.median(sxy[cam == c], axis=0)
    return out
