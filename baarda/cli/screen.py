"""`baarda screen PROJECT -o OUT`: the screening chain; writes a cleaned project and its log."""

from __future__ import annotations

from pathlib import Path

from baarda.cli.common import (
    add_out_argument,
    add_test_options,
    announce_compile,
    open_run,
    progress,
    tests_option,
)
from baarda.cli.inputs import add_input_options, input_paths, read_input
from baarda.options import ScreeningOptions, TestOptions


def add_options(p) -> None:
    """Options of the screening stages (shared with `baarda adjust --screen`)."""
    d = ScreeningOptions()
    p.add_argument("--stages", default="1,2,3",
                   help="stages to run: 1 photo pairs, 2 strip formation, 3 control "
                   "(default 1,2,3)")
    p.add_argument("--pair-transform", default=d.pair_transform,
                   choices=["auto", "similarity", "affine", "projective"],
                   help="2D transformation of the photo pairs (auto: projective with 7 or "
                   "more common points, affine with 6, else similarity)")
    p.add_argument("--pair-test", default=d.pair_statistic, choices=["w", "tau"],
                   help="test of the photo pairs: w with the pooled sigma of all pairs "
                   "(default) or tau with each pair's own variance factor")
    p.add_argument("--pair-alpha0", type=float, default=d.pair_alpha0,
                   help=f"significance level of the photo-pair tests (default {d.pair_alpha0})")
    p.add_argument("--pair-tolerance", type=float, default=None, metavar="MM",
                   help="photo pairs: errors smaller than this (mm) are left to stage 2 "
                   "(default: the parallax the relief of the control heights causes)")
    p.add_argument("--rho-max", type=float, default=d.rho_max,
                   help="errors whose w-tests correlate more than this are not separable "
                   f"(default {d.rho_max})")


def options(args, tests: TestOptions | None = None) -> ScreeningOptions:
    """The screening options of the command line; `tests`: alpha0, beta0 and alpha_global
    resolved over the project's (cli/common.tests_option)."""
    try:
        stages = tuple(sorted({int(s) for s in str(args.stages).split(",") if s.strip()}))
    except ValueError:
        stages = ()
    if not stages or not set(stages) <= {1, 2, 3}:
        raise SystemExit(f"baarda: error: --stages '{args.stages}': a comma list of 1, 2, 3")
    return ScreeningOptions(stages=stages, tests=tests, pair_alpha0=args.pair_alpha0,
                            pair_transform=args.pair_transform,
                            pair_statistic=args.pair_test, rho_max=args.rho_max,
                            pair_tolerance_mm=args.pair_tolerance)


def register(sub) -> None:
    p = sub.add_parser("screen", help="pre-adjustment screening: photo pairs, strip formation, "
                       "control; writes a cleaned project and the screening log")
    p.add_argument("input", type=Path, help="project folder (project.toml + CSV files) or any "
                   "supported input (see docs/formats.md); the cleaned block is written as a "
                   "project")
    add_out_argument(p, "folder of the cleaned project (and "
                                           "screening_log.csv, screening.txt)")
    add_test_options(p, what="the w-tests of stages 2 and 3 and of the bundle after them",
                     alpha_global=True)
    add_options(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress display")
    add_input_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from baarda.output.project_files import write_project
    from baarda.output.screening_log import write_screening_log
    from baarda.pipeline import screen_block

    with open_run(args, input_paths(args)) as run:
        say = progress(args.quiet)
        block = read_input(args)
        if say:
            say(f"read {block.summary()}")
        announce_compile(say, len(block.photos))
        res = screen_block(block, options(args, tests_option(block.settings, args)),
                           progress=say)
        write_project(res.block, run)
        write_screening_log(run, res.log)
    if not args.quiet:
        print(res.summary())
        print(f"cleaned project and screening log written to {run.describe()}")
    return 0
