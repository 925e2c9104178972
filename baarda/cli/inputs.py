"""Reading any supported input for the commands: format, CRS and datum choices.

`add_input_options` adds the options shared by `convert` and `adjust`; `prepare` reads the
input (io/convert.py), moves it into a local frame when it has a CRS (io/crs.py) and picks
the datum: the control when there is control, else a free network (bundle/free.py; then
observations of points behind a camera at the approximations are left out).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from baarda.block.photo_block import Block
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.free_network import FreeBundleProblem, drop_points_behind
from baarda.io.crs import LocalFrame, localize
from baarda.io.formats import FORMATS, read_any
from baarda.output.bundle_results import write_results
from baarda.output.crs_results import write_results_crs


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


def read_input(args) -> Block:
    block = read_any(args.input, args.format, pixel_mm=args.pixel_mm, sigma_px=args.sigma_px,
                     sigma_image_mm=None if args.sigma_image_um is None
                     else args.sigma_image_um * 1e-3)
    if args.crs:
        block = replace(block, settings=replace(block.settings, crs=args.crs))
    return block


@dataclass
class Prepared:
    block: Block  # as read (CRS coordinates)
    adjusted: Block  # what is adjusted (local frame, observations left out)
    problem: BundleProblem
    frame: LocalFrame | None

    def write(self, out: Path, result, quality) -> list:
        if self.frame is None:
            return write_results(out, result, quality)
        return write_results_crs(out, result, quality, self.frame, self.block)


def prepare(args, say=None) -> Prepared:
    block = read_input(args)
    adj, frame = (localize(block) if block.settings.crs else (block, None))
    if adj.points.controlled.any():
        problem = BundleProblem(adj)
    else:
        adj, dropped = drop_points_behind(adj)
        if say and dropped:
            say(f"free network: {dropped} observation(s) of points behind a camera left out")
        problem = FreeBundleProblem(adj)
    if say:
        for note in adj.notes:
            say(f"note: {note}")
    return Prepared(block, adj, problem, frame)
