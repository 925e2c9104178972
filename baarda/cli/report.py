"""`baarda report OUT -o report.html` and `baarda report OUT --text`."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from baarda.cli.argtypes import Pair, integer, non_negative, number, positive
from baarda.cli.common import add_quiet_option, progress
from baarda.cli.console import console

if TYPE_CHECKING:
    from baarda.report.text_report import ReportOptions


def add_histogram_options(p) -> None:
    p.add_argument("--class-width", type=positive(hi=1e6), default=1.0,
                   help="histogram class width (µm for image residuals; default 1)")
    p.add_argument("--range", type=number(-1e6, 1e6), nargs=2, default=[-25.0, 25.0],
                   metavar=("LO", "HI"), action=Pair, strict=True,
                   help="centres of the first and last class (default -25 25)")
    p.add_argument("--line-width", type=integer(1, 10**4), default=60,
                   help="longest '*' bar of a text histogram before bars are scaled")


def register(sub) -> None:
    p = sub.add_parser("report", help="adjustment report: HTML (plots embedded) or text")
    p.add_argument("results", type=Path, help="output folder of baarda adjust")
    p.add_argument("-o", "--out", type=Path, help="HTML file to write")
    p.add_argument("--text", action="store_true", help="print the text report")
    p.add_argument("--quality", type=Path, metavar="HTML", help="write the quality report "
                   "(camera parameters with standard deviations and correlations, GCP, check "
                   "point and GNSS residuals, reprojection errors per image, r, w and MDB, "
                   "snooping log, external reliability; docs/odm.md) as an HTML file")
    p.add_argument("--pdf", type=Path, metavar="PDF", help="write the same quality report "
                   "as a PDF")
    add_histogram_options(p)
    p.add_argument("--w-class-width", type=positive(hi=1e6), default=0.5, help="class width for w")
    p.add_argument("--w-range", type=number(-1e6, 1e6), nargs=2, default=[-6.0, 6.0],
                   metavar=("LO", "HI"), action=Pair, strict=True,
                   help="centres of the first and last class of the w histogram")
    p.add_argument("--top", type=integer(0, 10**9), default=50,
                   help="snooping table: rows with the largest |w| shown besides every "
                   "rejected and flagged observation (default 50)")
    p.add_argument("--min-w", type=non_negative(hi=1e6),
                   help="snooping table: only |w| >= this (besides rejected and flagged)")
    p.add_argument("--sort", choices=["w", "input"], default="w",
                   help="snooping table order: largest |w| first, or file order")
    p.add_argument("--exaggeration", type=positive(hi=1e9),
                   help="residual vector exaggeration (default: automatic)")
    p.add_argument("--vector-photos", type=integer(0, 10**9), default=8,
                   help="photos drawn with residual vectors (those with rejected or flagged "
                   "observations first)")
    p.add_argument("--max-points", type=integer(1, 10**9), default=50_000,
                   help="maps draw at most this many points: beyond it a deterministic "
                   "sample with every control, check, rejected, flagged and uncontrolled "
                   "point (said in the caption; default 50000)")
    p.add_argument("--max-rows", type=integer(1, 10**9), default=1_000,
                   help="the per-photo and snooping tables list at most this many rows: the "
                   "worst (default 1000)")
    p.add_argument("--templates", type=Path, metavar="DIR", help="a folder of Jinja2 "
                   "templates that override the reports' own (adjustment.html.j2, "
                   "quality.html.j2, style.css, macros.html.j2): restyle or brand the pages")
    add_quiet_option(p, "text report (--text) and no list of the files written")
    p.set_defaults(func=run)


def options(args) -> ReportOptions:
    from baarda.report.text_report import ReportOptions

    return ReportOptions(width=args.class_width, lo=args.range[0], hi=args.range[1],
                         line_width=args.line_width, w_width=args.w_class_width,
                         w_lo=args.w_range[0], w_hi=args.w_range[1], top=args.top,
                         min_abs_w=args.min_w, sort=args.sort, exaggeration=args.exaggeration,
                         vector_photos=args.vector_photos, max_points=args.max_points,
                         max_rows=args.max_rows)


def run(args) -> int:
    from baarda.errors import ProjectError
    from baarda.io.result_folder import read_results
    from baarda.output.run_folder import check_output_file, run_files
    from baarda.report.histogram import classes
    from baarda.report.text_report import text_report

    if args.out is None and not args.text and args.quality is None and args.pdf is None:
        raise ProjectError(str(args.results), "nothing to do: give -o report.html, --text, "
                           "--quality quality.html and/or --pdf quality.pdf")
    opt = options(args)
    for w, lo, hi in ((opt.width, opt.lo, opt.hi), (opt.w_width, opt.w_lo, opt.w_hi)):
        try:
            classes(w, lo, hi)
        except ValueError as e:
            raise ProjectError("command line", str(e)) from None
    if args.templates is not None and not os.path.isdir(args.templates):
        raise ProjectError(str(args.templates), "not a folder of templates")
    for out in (args.out, args.quality, args.pdf):
        if out is not None:
            check_output_file(out, [args.results, *run_files(args.results)])
    con = console(args)
    args.prints_results = args.text  # the text report is the result
    res = read_results(args.results)
    n_rej = int(res.obs["rejected"].sum())
    counts = (f"{len(res.obs)} observation components, {len(res.obs) - n_rej} used and "
              f"{n_rej} rejected")
    if args.text:
        con.print(text_report(res, opt), end="")
    written = []
    quality = args.quality is not None or args.pdf is not None
    cal = None
    if args.out is not None or quality:  # the camera, control and GNSS parts: built once
        from baarda.report.quality_report import calibration_parts

        cal = calibration_parts(res)
    if args.out is not None:
        from baarda.report.html_report import html_report, write_html

        say = progress(args)
        if say:
            say(f"read {args.results}: {counts}")
        write_html(args.out, html_report(res, opt, cal, args.out, args.templates))
        con.print(f"report written to {args.out}")
        written.append(str(args.out))
    if quality:
        from baarda.report.html_report import write_html
        from baarda.report.quality_html import quality_page
        from baarda.report.quality_pdf import write_quality_pdf
        from baarda.report.quality_report import quality_content

        parts = quality_content(res, cal)  # once for the page and the PDF
        if args.quality is not None:
            write_html(args.quality, quality_page(res, parts, args.templates,
                                                    args.quality))
            con.print(f"quality report written to {args.quality}")
            written.append(str(args.quality))
        if args.pdf is not None:
            n = write_quality_pdf(res, args.pdf, parts)
            con.print(f"quality report written to {args.pdf} ({n} pages)")
            written.append(f"{args.pdf} ({n} pages)")
    con.verdict("report", f"{args.results}: {counts}" + (
        f" -> {', '.join(written)}" if written else ""))
    return 0
