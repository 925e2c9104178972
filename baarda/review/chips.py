"""Image chips: the image around a measurement with where it was measured and where the
block predicts it (docs/review.md).

A photo's image is the file its input names (Photos.image: a Bundler list.txt's path, an
NVM file name, a DBAT script's image path; relative to the input's folder), else a file
named by the photo id, or by that file's name, in the folders `image_folders` finds
(--images DIR, then INPUT/images, and images/ beside or above INPUT: COLMAP's images/
beside sparse/, OpenSfM's images/); the id in a request is looked up in the block first,
and in a folder's listing, never joined into a path.  Image coordinates (mm) become pixels
as the reader made them (Cameras.pixel_frame, block/pixels.py, the conversion `--gcp-list`
uses too): column = c0 + x / pw, row = r0 - y / ph, with (c0, r0) the pixel of their origin
(the image's centre, W/2 and H/2 of the image file, where the reader did not know the
image: Bundler, NVM, COLMAP, OpenSfM, DBAT; the principal point of MicMac's camera) and pw,
ph the pixel's width and height (DBAT's and COLMAP's may differ); pixels are counted from
the upper-left corner of the upper-left pixel, as Pillow counts.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block
from baarda.block.pixels import frame_to_pixels

EXTENSIONS = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".JPG", ".JPEG", ".PNG", ".TIF")
HALF = 48  # chip half-width (pixels of the image)
ZOOM = 4  # chip pixels per image pixel


class NoImage(LookupError):
    """No image of the photo (the message says why)."""


def image_folders(input_path: Path, images: Path | None = None) -> list[Path]:
    """The folders to look for images in, those that exist."""
    p = Path(input_path)
    base = p if p.is_dir() else p.parent
    cand = ([images] if images is not None else []) + \
        [base / "images", base.parent / "images", base.parent.parent / "images"]
    out = []
    for c in cand:
        c = c.resolve()
        if c.is_dir() and c not in out:
            out.append(c)
    return out


def find_image(folders: list[Path], photo: str, named: str = "",
               source: str = "") -> Path | None:
    """The image file of a photo id: the file the input names (`named`, relative to the
    input `source`'s folder), else, in each of the folders, the file at the id's or the
    named file's relative path where it has folders (COLMAP's "cam1/0001.jpg" under
    images/), then a file whose name is the id, the id with an image extension, or the
    named file's name; never a path built from the id."""
    if named:
        given = Path(named)
        if not given.is_absolute() and source:
            src = Path(source)
            given = (src if src.is_dir() else src.parent) / given
        if given.is_file():
            return given
    names = {photo} | {photo + e for e in EXTENSIONS}
    if named:
        names.add(Path(named).name)
    nested = sorted({n for n in (photo, named) if n and _parts(n)[1:]})
    for folder in folders:
        for n in nested:  # a name with folders (COLMAP's "cam1/0001.jpg") under the folder
            found = _below(folder, _parts(n))
            if found is not None:
                return found
        try:
            listing = {q.name: q for q in folder.iterdir() if q.is_file()}
        except OSError:
            continue
        for n in sorted(names):
            if n in listing:
                return listing[n]
    return None


def image_of(block: Block, folders: list[Path], photo: str) -> Path | None:
    """The image file of a photo of the block (find_image with the name its input gave)."""
    i = block.photos.ids.index(photo)
    named = block.photos.image[i] if block.photos.image is not None else ""
    return find_image(folders, photo, named or "", block.source)


def _parts(name: str) -> list[str]:
    """The parts of a relative image name, / or \\ between them."""
    return [p for p in name.replace("\\", "/").split("/") if p and p != "."]


def _below(folder: Path, parts: list[str]) -> Path | None:
    """The file at `parts` below `folder`, each part found in its folder's listing (so that
    '..' or an absolute name never leads out of it); None where a part is missing."""
    here = folder
    for i, part in enumerate(parts):
        try:
            entries = {q.name: q for q in here.iterdir()}
        except OSError:
            return None
        q = entries.get(part)
        if q is None:
            return None
        if i == len(parts) - 1:
            return q if q.is_file() else None
        if not q.is_dir():
            return None
        here = q
    return None


def pixel_frame(block: Block, cam: int, pixel_mm: float | None) -> tuple[float, ...]:
    """(c0, r0, pw, ph) of a camera (module docstring; c0, r0 NaN: the image's centre);
    pixel_mm: the pixel where the reader gives none (NoImage without one)."""
    frame = block.cameras.pixel_frame
    if frame is not None and np.isfinite(frame[cam, 2:]).all() and (frame[cam, 2:] > 0).all():
        c0, r0, pw, ph = (float(v) for v in frame[cam])
        return c0, r0, pw, ph
    pix = block.cameras.pixel_mm
    p = float(pix[cam]) if pix is not None and np.isfinite(pix[cam]) and pix[cam] > 0 \
        else pixel_mm
    if p is None:
        raise NoImage(f"camera {block.cameras.ids[cam]} has no pixel size: give the input's "
                      "pixel size to see its images")
    return math.nan, math.nan, p, p


def to_pixel(frame: tuple[float, ...], width: int, height: int, x: float, y: float
             ) -> tuple[float, float]:
    """(column, row) of image coordinates x, y (mm) on an image of width x height pixels
    (from its upper-left corner, y down), with a camera's `pixel_frame` (c0, r0, pw, ph)."""
    col, row = frame_to_pixels(np.array([frame], float), np.array([[width, height]], float),
                               np.array([[x, y]], float))[0]
    return float(col), float(row)


def chip_png(block: Block, folders: list[Path], photo: str, ray: dict,
             pixel_mm: float | None = None) -> tuple[bytes, dict]:
    """A PNG of the image around a ray of `photo` (ray: session.rays' dict: x, y measured,
    pred_x, pred_y predicted without it, sigma_pred_x, sigma_pred_y, mm): the measured
    position as a green cross, the predicted one as a red circle with its 1-sigma ellipse.
    pixel_mm: the pixel size where the camera has none (the command line's --pixel-mm).  Returns
    (the PNG, {mm_per_px: image mm per chip pixel, cx, cy: the chip pixel of the measured
    position; mm_per_px_y: of y, where pixels are not square}).  NoImage when there is no
    image or it cannot be read."""
    from PIL import Image, ImageDraw, UnidentifiedImageError

    i = block.photos.ids.index(photo)
    path = image_of(block, folders, photo)
    if path is None:
        raise NoImage(f"no image of photo {photo}")
    cam = int(block.photos.camera[i])
    c0, r0, pw, ph = pixel_frame(block, cam, pixel_mm)
    try:
        with Image.open(path) as im:
            width, height = im.size

            frame = (c0, r0, pw, ph)

            def px(x, y):
                return to_pixel(frame, width, height, x, y)

            c, r = px(ray["x"], ray["y"])
            box = (int(round(c)) - HALF, int(round(r)) - HALF,
                   int(round(c)) + HALF, int(round(r)) + HALF)
            crop = im.convert("RGB").crop(box)
    except (OSError, UnidentifiedImageError, ValueError) as e:
        raise NoImage(f"the image of photo {photo} cannot be read ({path.name}: {e})") \
            from None
    chip = crop.resize((2 * HALF * ZOOM, 2 * HALF * ZOOM), Image.Resampling.NEAREST)
    d = ImageDraw.Draw(chip)

    def at(x, y):
        cc, rr = px(x, y)
        return (cc - box[0]) * ZOOM, (rr - box[1]) * ZOOM

    mx, my = at(ray["x"], ray["y"])
    if ray.get("pred_x") is not None and ray.get("pred_y") is not None:
        qx, qy = at(ray["pred_x"], ray["pred_y"])
        sx = (ray.get("sigma_pred_x") or 0.0) / pw * ZOOM
        sy = (ray.get("sigma_pred_y") or 0.0) / ph * ZOOM
        d.line([(mx, my), (qx, qy)], fill=(255, 200, 0), width=1)
        d.ellipse([qx - sx, qy - sy, qx + sx, qy + sy], outline=(255, 40, 40), width=2)
        d.ellipse([qx - 3, qy - 3, qx + 3, qy + 3], fill=(255, 40, 40))
    d.line([(mx - 8, my), (mx + 8, my)], fill=(0, 255, 0), width=2)
    d.line([(mx, my - 8), (mx, my + 8)], fill=(0, 255, 0), width=2)
    out = io.BytesIO()
    chip.save(out, "PNG")
    return out.getvalue(), {"mm_per_px": pw / ZOOM, "mm_per_px_y": ph / ZOOM, "cx": mx,
                            "cy": my}
