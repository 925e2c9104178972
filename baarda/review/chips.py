"""Image chips: the image around a measurement with where it was measured and where the
block predicts it (docs/review.md).

Images are looked up by photo id in the folders `image_folders` finds (--images DIR, then
INPUT/images, and images/ beside or above INPUT: COLMAP's images/ beside sparse/, OpenSfM's
images/); a photo id is a name looked up in a folder's listing, never a path.  Image
coordinates (mm, origin at the image centre, y up) become pixels with the camera's pixel
size: col = W/2 + x/p, row = H/2 - y/p.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block

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


def find_image(folders: list[Path], photo: str) -> Path | None:
    """The image file of a photo id: a file of one of the folders whose name is the id (or
    the id with an image extension); never a path built from the id."""
    names = {photo} | {photo + e for e in EXTENSIONS}
    for folder in folders:
        try:
            listing = {q.name: q for q in folder.iterdir() if q.is_file()}
        except OSError:
            continue
        for n in names:
            if n in listing:
                return listing[n]
    return None


def chip_png(block: Block, folders: list[Path], photo: str, ray: dict,
             pixel_mm: float | None = None) -> tuple[bytes, dict]:
    """A PNG of the image around a ray of `photo` (ray: session.rays' dict: x, y measured,
    pred_x, pred_y predicted without it, sigma_pred_x, sigma_pred_y, mm): the measured
    position as a green cross, the predicted one as a red circle with its 1-sigma ellipse.
    pixel_mm: the pixel size where the camera has none (COLMAP's nominal pixel).  Returns
    (the PNG, {mm_per_px: image mm per chip pixel, cx, cy: the chip pixel of the measured
    position}).  NoImage when there is no image or it cannot be read."""
    from PIL import Image, ImageDraw, UnidentifiedImageError

    path = find_image(folders, photo)
    if path is None:
        raise NoImage(f"no image of photo {photo}")
    i = block.photos.ids.index(photo)
    cam = int(block.photos.camera[i])
    pix = block.cameras.pixel_mm
    p = float(pix[cam]) if pix is not None and np.isfinite(pix[cam]) and pix[cam] > 0 \
        else pixel_mm
    if p is None:
        raise NoImage(f"camera {block.cameras.ids[cam]} has no pixel size: give the input's "
                      "pixel size to see its images")
    try:
        with Image.open(path) as im:
            width, height = im.size

            def px(x, y):
                return width / 2 + x / p, height / 2 - y / p

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
        sx = (ray.get("sigma_pred_x") or 0.0) / p * ZOOM
        sy = (ray.get("sigma_pred_y") or 0.0) / p * ZOOM
        d.line([(mx, my), (qx, qy)], fill=(255, 200, 0), width=1)
        d.ellipse([qx - sx, qy - sy, qx + sx, qy + sy], outline=(255, 40, 40), width=2)
        d.ellipse([qx - 3, qy - 3, qx + 3, qy + 3], fill=(255, 40, 40))
    d.line([(mx - 8, my), (mx + 8, my)], fill=(0, 255, 0), width=2)
    d.line([(mx, my - 8), (mx, my + 8)], fill=(0, 255, 0), width=2)
    out = io.BytesIO()
    chip.save(out, "PNG")
    return out.getvalue(), {"mm_per_px": p / ZOOM, "cx": mx, "cy": my}
