"""`baarda residuals FILE [FILE ...]`: statistics and histograms of residual listings
written by other programs (Salsig's post-processor VAN)."""

from __future__ import annotations

from pathlib import Path

from baarda.cli.argtypes import integer, positive
from baarda.cli.console import console
from baarda.cli.report import add_histogram_options


def register(sub) -> None:
    p = sub.add_parser("residuals", help="post-processor: group statistics and histograms of "
                       "residuals listed by another program (see docs/report.md)")
    p.add_argument("files", type=Path, nargs="+", help="residual listings (read together)")
    p.add_argument("--format", default="auto",
                   choices=["auto", "generic", "photomodeler", "baarda"],
                   help="input format (default: recognised from the header)")
    p.add_argument("--pixel-size", type=positive("µm", 1e6), metavar="UM",
                   help="pixel size in µm: PhotoModeler residuals (pixels) are converted to µm")
    add_histogram_options(p)
    p.set_defaults(func=run, class_width=None, range=None, prints_results=True)
    p.add_argument("--worst", type=integer(0, 10**6), default=10,
                   help="largest residuals listed per kind")


def run(args) -> int:
    from baarda.errors import ProjectError
    from baarda.io.residual_listings import read_residuals
    from baarda.report.text_report import residuals_report

    res = read_residuals(args.files, args.format, args.pixel_size)
    px = res.units["image"] == "px"
    width = args.class_width if args.class_width is not None else (0.1 if px else 1.0)
    rng = args.range if args.range is not None else ([-2.5, 2.5] if px else [-25.0, 25.0])
    try:
        text = residuals_report(res, width, rng[0], rng[1], args.line_width, args.worst)
    except ValueError as e:
        raise ProjectError("command line", str(e)) from None
    console(args).print(text, end="")
    return 0
