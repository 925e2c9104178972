"""The image sigma and the pixel size of every input format, resolved in one place
(`--sigma-image-um`, `--sigma-px`, `--pixel-mm`; baarda.read's `sigma_image_um`,
`sigma_px`, `pixel_mm`):

| FormatSpec.pixels | pixel size | --pixel-mm | --sigma-px | --sigma-image-um |
|---|---|---|---|---|
| nominal (COLMAP, BAL, OpenSfM) | none: nominal | yes (default 0.001 mm) | yes (default 1) | yes |
| camera (DBAT, MicMac) | the camera's | refused | in the camera's pixels | yes |
| header (PhotoModeler) | line 2's image size | only when line 2 lacks it | in its pixels | yes |
| mm (native project, AICON) | none: mm | only to convert --sigma-px | needs --pixel-mm | yes |

The image sigma replaces the input's for every image observation (x and y); without one
each input keeps its own (the files' sigmas, project.toml's image_um).  An option that does
not apply to the input's format, and both sigmas at once, are errors that name the option
and the format.  Every image sigma, given or read, lies within SIGMA_IMAGE_UM.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from baarda.block.photo_block import Block
from baarda.errors import ProjectError
from baarda.io.formats import spec
from baarda.options import ImageOptions

PIXEL_MM, SIGMA_PX = 0.001, 1.0  # the nominal pixel (1 px = 1 µm) and sigma of "nominal"
SIGMA_IMAGE_UM = (1e-3, 1e5)  # the image sigmas baarda takes [µm]: 1 nm .. 100 mm


def _positive(name: str, value: float | None) -> None:
    if value is not None and not (np.isfinite(value) and value > 0):
        raise ProjectError("command line", f"{name} {value!r}: must be a positive number")


def check_sigma_um(value: float, where: str, line: int | None = None,
                   column: str | None = None) -> None:
    """ProjectError when an image sigma [µm] lies outside SIGMA_IMAGE_UM (0 and 1e-300
    give infinite weights, 1e308 overflows the statistics)."""
    low, high = SIGMA_IMAGE_UM
    if not (np.isfinite(value) and low <= value <= high):
        raise ProjectError(where, f"image standard deviation {value!r} µm: expected "
                           f"{low:g} to {high:g} µm", line, column)


def resolve_image_options(fmt: str, pixel_mm: float | None = None,
                          sigma_px: float | None = None,
                          sigma_image_um: float | None = None) -> ImageOptions:
    """The image options of input format `fmt` (module docstring); ProjectError naming an
    option that does not apply to it."""
    for name, v in (("--pixel-mm", pixel_mm), ("--sigma-px", sigma_px),
                    ("--sigma-image-um", sigma_image_um)):
        _positive(name, v)
    if sigma_px is not None and sigma_image_um is not None:
        raise ProjectError("command line", "--sigma-px and --sigma-image-um both give the "
                           "image sigma: give one")
    if sigma_image_um is not None:
        check_sigma_um(sigma_image_um, "command line", column="--sigma-image-um")
    policy = spec(fmt).pixels  # io/formats.py: PIXEL_POLICIES
    what = spec(fmt).title
    if policy == "nominal":
        pixel = PIXEL_MM if pixel_mm is None else pixel_mm
        if sigma_image_um is not None:
            return ImageOptions(pixel, sigma_image_um * 1e-3 / pixel, None)
        return ImageOptions(pixel, SIGMA_PX if sigma_px is None else sigma_px, None)
    if policy == "mm":
        if sigma_px is not None and pixel_mm is None:
            raise ProjectError("command line", f"--sigma-px needs --pixel-mm for {what} "
                               "input (its image coordinates are in mm, it has no pixel "
                               "size); or give --sigma-image-um")
        if pixel_mm is not None and sigma_px is None:
            raise ProjectError("command line", f"--pixel-mm does not apply to {what} input "
                               "(its image coordinates are in mm) unless it converts "
                               "--sigma-px")
        um = sigma_image_um if sigma_px is None or pixel_mm is None else sigma_px * pixel_mm * 1e3
        if um is not None:
            check_sigma_um(um, "command line", column="--sigma-px")
        return ImageOptions(None, None, um)
    if pixel_mm is not None and policy == "camera":
        raise ProjectError("command line", f"--pixel-mm does not apply to {what} input: its "
                           "pixel size is the camera's (sensor size / image size)")
    return ImageOptions(pixel_mm, sigma_px, sigma_image_um)


def with_image_sigma(block: Block, sigma_um: float) -> Block:
    """The block with the a-priori sigma of every image coordinate set to sigma_um [µm]."""
    image = replace(block.image, sigma_mm=np.full(len(block.image), sigma_um * 1e-3),
                    sigma_xy_mm=None)
    return replace(block, image=image,
                   settings=replace(block.settings, sigma_image_um=float(sigma_um)),
                   notes=list(block.notes) + [f"image sigma {sigma_um:g} µm for every "
                                              "observation (given)"])


def check_image_sigmas(block: Block) -> None:
    """Every image sigma of a block as read within SIGMA_IMAGE_UM (the readers name the
    line of a bad value where they can; this names the input for the others)."""
    sig = block.image.sigma_mm if block.image.sigma_xy_mm is None else block.image.sigma_xy_mm
    if not len(sig):
        return
    um = np.asarray(sig, float).ravel() * 1e3
    low, high = SIGMA_IMAGE_UM
    bad = np.flatnonzero(~((um >= low) & (um <= high)))
    if len(bad):
        k = int(bad[0]) // (1 if sig.ndim == 1 else 2)
        im = block.image
        raise ProjectError(block.source or block.settings.name,
                           f"image standard deviation {um[bad[0]]:g} µm of point "
                           f"{block.points.ids[im.point[k]]} on photo "
                           f"{block.photos.ids[im.photo[k]]}: expected {low:g} to {high:g} µm")
