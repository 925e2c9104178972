"""Input options shared by the commands that read a block (`adjust`, `convert`, `screen`)."""

from __future__ import annotations

from pathlib import Path

from baarda.block.camera import KINDS
from baarda.block.photo_block import Block
from baarda.cli.argtypes import positive
from baarda.cli.common import add_encoding_option
from baarda.errors import ProjectError
from baarda.io.formats import FORMATS
from baarda.io.project import DATUMS
from baarda.pipeline import read


def add_input_options(p) -> None:
    p.add_argument("--format", choices=FORMATS, help="input format (default: recognised from "
                   "the path)")
    p.add_argument("--crs", help="CRS of the ground coordinates (e.g. EPSG:32632); overrides "
                   "project.toml")
    p.add_argument("--sigma-image-um", type=positive("µm"), metavar="UM", help="a-priori sigma of "
                   "every image coordinate [µm], any input. Default: the input's own (its "
                   "files, project.toml)")
    p.add_argument("--sigma-px", type=positive("px"), metavar="PX", help="the same in pixels: with "
                   "the camera's pixel size (DBAT, PhotoModeler, MicMac) or --pixel-mm "
                   "(default 1 px for COLMAP, BAL, OpenSfM)")
    p.add_argument("--pixel-mm", type=positive("mm"), metavar="MM", help="pixel size [mm] of input "
                   "without one: COLMAP, BAL, OpenSfM (default 0.001: residuals in µm read "
                   "as pixels), a PhotoModeler export without image size; for a native "
                   "project or AICON it converts --sigma-px. Refused where the input has "
                   "its own")
    add_encoding_option(p)
    p.add_argument("--camera-model", choices=[k for k in KINDS if k != "brown_backward"],
                   help="put every camera on this model (docs/camera_models.md; coefficients "
                   "start at 0). Default: the input's")
    p.add_argument("--calibrate", metavar="NAMES", help="self-calibration: the camera "
                   "parameters to estimate for every camera, a comma list of c, x0, y0 and "
                   "the model's coefficients (e.g. c,x0,y0,k1,k2,p1,p2), 'all' or 'none'. "
                   "Default: project.toml [calibration], or what the source program "
                   "estimated (AICON, DBAT, BAL)")
    p.add_argument("--calibration-group", choices=("camera", "strip"), help="camera: the "
                   "parameters of a camera are shared by all its photos; strip: estimated "
                   "per camera and strip. Default: project.toml [calibration] group, else "
                   "camera")
    p.add_argument("--camera", metavar="FILE", help="a DBAT camera file (e.g. DBAT's "
                   "calibration result) replacing a DBAT script's camera; with --calibrate "
                   "none it is held fixed. Default: the script's camera")
    p.add_argument("--control", metavar="FILE", help="control points replacing the input's "
                   "own (matched by id): DBAT's text format 'id[, name], X, Y, Z[, sigmas]' "
                   "(no sigma: fixed) or a native ground_points.csv. Default: the input's")
    p.add_argument("--datum", choices=DATUMS, help="control: the control fixes the block; "
                   "free: a free network (minimal constraints; control points become check "
                   "points); inner: a free network whose coordinates and standard deviations "
                   "are given in the inner datum of all its points (S-transformation). "
                   "Default: free for COLMAP, BAL and AICON input, else project.toml's datum "
                   "(default control)")
    p.add_argument("--free", action="store_true", help="the same as --datum free")
    p.add_argument("--check-gcp", metavar="IDS", help="use these control points (GCPs) as "
                   "check points: a comma list of ids, or 'alternate' for every other one "
                   "(the 2nd, 4th, ... in the order read). Default: all are control")


def read_input(args) -> Block:
    """baarda.pipeline.read with the command's input options."""
    return read(args.input, args.format, crs=args.crs, pixel_mm=args.pixel_mm,
                sigma_px=args.sigma_px, sigma_image_um=args.sigma_image_um,
                datum=datum_option(args), encoding=args.encoding,
                camera_model=args.camera_model, calibrate=calibrate_option(args.calibrate),
                camera=args.camera, calibration_group=args.calibration_group,
                check_gcp=args.check_gcp, control=args.control)


def input_paths(args) -> list[Path]:
    """The files a command reads (its input, --camera, --control): checked against the
    output folder, never written over."""
    return [Path(p) for p in (args.input, args.camera, args.control) if p is not None]


def datum_option(args) -> str | None:
    """--datum or --free (None: the input's datum)."""
    if args.free and args.datum not in (None, "free"):
        raise ProjectError("command line", f"--free and --datum {args.datum} contradict")
    return "free" if args.free else args.datum


def calibrate_option(text: str | None):
    """--calibrate: None, 'all', 'none' or a tuple of parameter names."""
    if text is None or text in ("all", "none"):
        return text
    return tuple(p.strip() for p in text.split(",") if p.strip())
