"""Input options shared by the commands that read a block (`adjust`, `convert`, `screen`)."""

from __future__ import annotations

from pathlib import Path

from baarda.block.camera import KINDS
from baarda.block.photo_block import Block
from baarda.cli.argtypes import positive
from baarda.cli.common import add_encoding_option, requested_settings
from baarda.io.formats import format_names, spec, titles
from baarda.options import DATUMS, Config
from baarda.pipeline import read_configured


def formats_help() -> str:
    """The formats baarda reads, for a command's input help (from the format registry)."""
    return "a native project folder (project.toml + CSV files) or " + titles() + " input"


def add_input_options(p) -> None:
    """The input options of a command that reads a block; the formats' lists are generated
    from the format registry (io/formats.py)."""
    p.add_argument("--format", choices=format_names(), help="input format (default: "
                   "recognised from the path): " + "; ".join(
                       f"{s.name}: {s.input}" for s in map(spec, format_names())))
    p.add_argument("--model", type=int, metavar="K", help="the model to read of a file with "
                   "several (NVM; 0-based; default the first, with a note naming how many)")
    p.add_argument("--crs", help="CRS of the ground coordinates (e.g. EPSG:32632); overrides "
                   "project.toml")
    p.add_argument("--sigma-image-um", type=positive("µm"), metavar="UM", help="a-priori sigma of "
                   "every image coordinate [µm], any input. Default: the input's own (its "
                   "files, project.toml)")
    p.add_argument("--sigma-px", type=positive("px"), metavar="PX", help="the same in pixels: "
                   f"with the camera's pixel size ({titles(('camera', 'header'))}) or "
                   f"--pixel-mm (default 1 px for {titles(('nominal',))})")
    p.add_argument("--pixel-mm", type=positive("mm"), metavar="MM", help="pixel size [mm] of "
                   f"input without one: {titles(('nominal',))} (default 0.001: residuals in µm "
                   f"read as pixels), {titles(('header',))} without image size; for "
                   f"{titles(('mm',))} input it converts --sigma-px. Refused where the input "
                   "has its own")
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
    p.add_argument("--tie-points", metavar="FILE", help="a Bundler file (bundle.out) of the "
                   "same chunk joining a Metashape cameras XML's markers with its tie points. "
                   "Default: a bundle.out beside the XML, if there is one")
    p.add_argument("--control", metavar="FILE", help="control points replacing the input's "
                   "own (matched by id): DBAT's text format 'id[, name], X, Y, Z[, sigmas]' "
                   "(no sigma: fixed) or a native ground_points.csv. Default: the input's")
    p.add_argument("--gcp-list", metavar="FILE", help="GCPs measured on the images, in "
                   "OpenDroneMap's gcp_list.txt (a CRS line, then 'geo_x geo_y geo_z im_x im_y "
                   "image_name [gcp_name]', pixels from the upper-left corner): added as "
                   "control points to any input whose image size is known (COLMAP; Bundler "
                   "and NVM with their images beside them), the block moved into the file's "
                   "CRS by a similarity; --check-gcp names the check points "
                   "(docs/formats.md)")
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
    """The command's input, configured by its options (read_configured_input)."""
    return read_configured_input(args)[0]


def read_configured_input(args) -> tuple[Block, Config]:
    """(block, configuration): io/configuration.read_configured with the command's input
    options, resolved once over the input's settings (io/configuration.py)."""
    return read_configured(args.input, args.format, requested_settings(args),
                           encoding=args.encoding, camera=args.camera,
                           check_gcp=args.check_gcp, control=args.control,
                           gcp_list=args.gcp_list, model=getattr(args, "model", None),
                           tie_points=getattr(args, "tie_points", None))


def input_paths(args) -> list[Path]:
    """The files a command reads (its input, --camera, --control, --gcp-list, --tie-points):
    checked against the output folder, never written over."""
    return [Path(p) for p in (args.input, args.camera, args.control,
                              getattr(args, "gcp_list", None),
                              getattr(args, "tie_points", None)) if p is not None]
