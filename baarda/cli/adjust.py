"""`baarda adjust PROJECT -o OUT` and `baarda snoop PROJECT -o OUT`."""

from __future__ import annotations

from pathlib import Path

from baarda.bundle.adjust import adjust
from baarda.bundle.quality import assess, snoop
from baarda.cli.common import check_output, progress
from baarda.io.project import read_project
from baarda.io.results import write_results


def _common(p) -> None:
    p.add_argument("project", type=Path, help="project folder (project.toml + CSV files)")
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder")
    p.add_argument("--alpha0", type=float, help="significance level of the w-test "
                   "(default: project.toml, else 0.001)")
    p.add_argument("--beta0", type=float, help="power of the tests (default 0.80)")
    p.add_argument("--tau", action="store_true", help="snoop with Pope's tau (sigma0 a "
                   "posteriori) instead of Baarda's w (sigma0 a priori)")
    p.add_argument("--by-point", action="store_true",
                   help="reject both coordinates of an image point together")
    p.add_argument("--robust", action="store_true", help="Danish-method re-weighting before "
                   "snooping (for blocks with many large errors)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress display")


def register(sub) -> None:
    p = sub.add_parser("adjust", help="bundle block adjustment with observation statistics")
    _common(p)
    p.add_argument("--snoop", action="store_true", help="iterative data snooping")
    p.set_defaults(func=run_adjust)
    p = sub.add_parser("snoop", help="bundle adjustment with iterative data snooping")
    _common(p)
    p.set_defaults(func=run_snoop, snoop=True)


def run_adjust(args) -> int:
    check_output(args.out, [args.project])
    say = progress(args.quiet)
    block = read_project(args.project)
    if say:
        say(f"read {block.summary()}")
    if args.snoop:
        qc = snoop(block, alpha0=args.alpha0, beta0=args.beta0,
                   statistic="tau" if args.tau else "w", by_point=args.by_point,
                   robust=args.robust, progress=say)
        result = qc.adjustment
    else:
        result = adjust(block, progress=say)
        qc = assess(result, args.alpha0, args.beta0)
    write_results(args.out, result, qc)
    if not args.quiet:
        print(qc.summary())
        print(f"results written to {args.out}")
    return 0


def run_snoop(args) -> int:
    return run_adjust(args)
