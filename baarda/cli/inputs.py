"""Input options shared by the commands that read a block (`adjust`, `convert`, `screen`)."""

from __future__ import annotations

from baarda.block.photo_block import Block
from baarda.cli.common import add_encoding_option
from baarda.io.formats import FORMATS
from baarda.pipeline import read


def add_input_options(p) -> None:
    p.add_argument("--format", choices=FORMATS, help="input format (default: recognised from "
                   "the path)")
    p.add_argument("--crs", help="CRS of the ground coordinates (e.g. EPSG:32632); overrides "
                   "project.toml")
    p.add_argument("--pixel-mm", type=float, default=0.001, help="nominal pixel size for "
                   "COLMAP and BAL input [mm] (default 0.001: residuals in µm read as pixels)")
    p.add_argument("--sigma-px", type=float, default=1.0, help="image sigma for COLMAP and "
                   "BAL input [px] (default 1)")
    p.add_argument("--sigma-image-um", type=float, help="image sigma for AICON input [µm] "
                   "(default: the .phc file's)")
    add_encoding_option(p)
    p.add_argument("--free", action="store_true", help="adjust as a free network (datum by "
                   "minimal constraints; control points become check points). Default: "
                   "free for COLMAP, BAL and AICON input and for projects with datum = "
                   "\"free\", else the control")


def read_input(args) -> Block:
    """baarda.pipeline.read with the command's input options."""
    return read(args.input, args.format, crs=args.crs, pixel_mm=args.pixel_mm,
                sigma_px=args.sigma_px, sigma_image_um=args.sigma_image_um,
                datum="free" if args.free else None, encoding=args.encoding)
