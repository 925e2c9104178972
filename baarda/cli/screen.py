"""`baarda screen PROJECT -o OUT`: the screening chain; writes a cleaned project and its log."""

from __future__ import annotations

from pathlib import Path

from baarda.cli.argtypes import alpha, choices_list, non_negative, number
from baarda.cli.common import (
    add_out_argument,
    add_quiet_option,
    add_test_options,
    announce_compile,
    open_run,
    progress,
)
from baarda.cli.console import console
from baarda.cli.inputs import (
    add_input_options,
    formats_help,
    input_paths,
    read_configured_input,
)
from baarda.options import ScreeningOptions, TestOptions


def add_options(p) -> None:
    """Options of the screening stages (shared with `baarda adjust --screen`)."""
    d = ScreeningOptions()
    p.add_argument("--stages", default="1,2,3", type=choices_list("123", what="stages"),
                   help="stages to run: 1 photo pairs, 2 strip formation, 3 control "
                   "(default 1,2,3)")
    p.add_argument("--pair-transform", default=d.pair_transform,
                   choices=["auto", "similarity", "affine", "projective"],
                   help="2D transformation of the photo pairs (auto: projective with 7 or "
                   "more common points, affine with 6, else similarity)")
    p.add_argument("--pair-test", default=d.pair_statistic, choices=["w", "tau"],
                   help="test of the photo pairs: w with the pooled sigma of all pairs "
                   "(default) or tau with each pair's own variance factor")
    p.add_argument("--pair-alpha0", type=alpha, default=d.pair_alpha0,
                   help=f"significance level of the photo-pair tests (default {d.pair_alpha0})")
    p.add_argument("--pair-tolerance", type=non_negative("mm", 1e3), default=None, metavar="MM",
                   help="photo pairs: errors smaller than this (mm) are left to stage 2 "
                   "(default: the parallax the relief of the control heights causes)")
    p.add_argument("--rho-max", type=number(0, 1, lo_open=True), default=d.rho_max,
                   help="errors whose w-tests correlate more than this are not separable "
                   f"(default {d.rho_max})")


def options(args, tests: TestOptions | None = None) -> ScreeningOptions:
    """The screening options of the command line; `tests`: alpha0, beta0 and alpha_global
    resolved over the project's (io/configuration.py)."""
    stages = tuple(sorted(int(s) for s in args.stages.split(",")))  # checked by the parser
    return ScreeningOptions(stages=stages, tests=tests, pair_alpha0=args.pair_alpha0,
                            pair_transform=args.pair_transform,
                            pair_statistic=args.pair_test, rho_max=args.rho_max,
                            pair_tolerance_mm=args.pair_tolerance)


def register(sub) -> None:
    p = sub.add_parser("screen", help="pre-adjustment screening: photo pairs, strip formation, "
                       "control; writes a cleaned project and the screening log")
    p.add_argument("input", type=Path, help=formats_help() + " (docs/formats.md); the "
                   "cleaned block is written as a project")
    add_out_argument(p, "folder of the cleaned project (and "
                                           "screening_log.csv, screening.txt)")
    add_test_options(p, what="the w-tests of stages 2 and 3 and of the bundle after them",
                     alpha_global=True)
    add_options(p)
    add_quiet_option(p)
    add_input_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from baarda.output.project_files import write_project
    from baarda.output.screening_log import write_screening_log
    from baarda.pipeline import screen_block

    con = console(args)
    with open_run(args, input_paths(args)) as run:
        say = progress(args)
        block, config = read_configured_input(args)
        if say:
            say(f"read {block.summary()}")
        for note in block.notes:
            con.note(note)
        announce_compile(args, len(block.photos))
        res = screen_block(block, options(args, config.tests),
                           progress=say)
        write_project(res.block, run)
        write_screening_log(run, res.log)
    con.print(res.summary())
    con.print(f"cleaned project and screening log written to {run.describe()}")
    con.verdict("screen", f"{_removed(res)} -> {run.describe()}")
    return 0


def _removed(res) -> str:
    """What the screening took out, in numbers."""
    return (f"{int((~res.image_keep).sum())} image point(s) and the control of "
            f"{len(res.control_removed)} point(s) removed")
