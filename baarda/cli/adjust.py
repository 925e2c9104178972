"""`baarda adjust PROJECT -o OUT [--screen] [--snoop]` and `baarda snoop PROJECT -o OUT`."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from baarda.cli.common import (
    NOT_CONVERGED,
    OK,
    add_excel_safe_option,
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
from baarda.cli.verdicts import adjustment_verdict


def _common(p) -> None:
    p.add_argument("input", type=Path, help=formats_help() + " (docs/formats.md)")
    add_out_argument(p, "output folder")
    add_excel_safe_option(p)
    add_test_options(p, alpha_global=True)
    p.add_argument("--tau", action="store_true", help="snoop with Pope's tau (sigma0 a "
                   "posteriori) instead of Baarda's w (sigma0 a priori)")
    p.add_argument("--by-point", action="store_true",
                   help="reject both coordinates of an image point together")
    p.add_argument("--inseparable", choices=("flag", "group"), default="flag",
                   help="when the rejected observation cannot be told from others (|rho| >= "
                   "0.99): flag them (default) or reject the group where the block stays "
                   "determined (docs/quality.md)")
    p.add_argument("--robust", action="store_true", help="Danish-method re-weighting before "
                   "snooping (for blocks with many large errors)")
    p.add_argument("--vce", action="store_true", help="estimate a variance component per "
                   "observation group (image per camera, control X, Y, Z, GNSS, IMU, "
                   "distances), re-weight and adjust again until they converge; the tests "
                   "and snooping then use the estimated sigmas")
    p.add_argument("--gpkg", action="store_true", help="also write block.gpkg for GIS: "
                   "points, projection centres and image-residual vectors (exaggerated "
                   "1000 x on the ground) in the project's CRS")
    p.add_argument("--parquet", action="store_true", help="write the observation table as "
                   "observations.parquet instead of observations.csv (the same columns and "
                   "numbers; for blocks of millions of observations: written and read "
                   "several times faster; baarda report reads either)")
    p.add_argument("--damping", choices=("gn", "lm"), default="gn", help="the solver: gn "
                   "Gauss-Newton with step halving (default), lm Levenberg-Marquardt (damped "
                   "steps, for poor approximations); either way the statistics use the "
                   "undamped normal equations at the solution")
    add_quiet_option(p)
    add_input_options(p)


def register(sub) -> None:
    p = sub.add_parser("adjust", help="bundle block adjustment with observation statistics")
    _common(p)
    p.add_argument("--snoop", action="store_true", help="iterative data snooping")
    p.add_argument("--edits", type=Path, metavar="FILE", help="apply an operator's edits "
                   "before adjusting (edits.csv of baarda review: rejections, restorations, "
                   "re-measurements, points set aside; docs/review.md)")
    p.add_argument("--screen", action="store_true", help="screen the data first (photo "
                   "pairs, strip formation, control; see baarda screen); with --snoop, what "
                   "the snooping rejects is removed with the observations it cannot be told "
                   "from; the log is written to screening_log.csv")
    from baarda.cli.screen import add_options

    add_options(p)
    p.set_defaults(func=run_adjust)
    p = sub.add_parser("snoop", help="bundle adjustment with iterative data snooping")
    _common(p)
    p.set_defaults(func=run_snoop, snoop=True)


def run_adjust(args) -> int:
    con = console(args)
    edits = getattr(args, "edits", None)
    with open_run(args, input_paths(args) + ([edits] if edits else [])) as run:
        qc, text = _adjust(args, run)
    con.print(text)
    con.print(f"results written to {run.describe()}")
    check = _quality_check(args.out, qc)
    con.print("\n".join(check.lines()))  # the reports' first section, the same rows
    con.verdict(args.command, f"{adjustment_verdict(qc.to_dict())}; quality check "
                f"{check.headline} -> {run.describe()}")
    return OK if qc.adjustment.converged and not (qc.run and qc.run.incomplete) \
        else NOT_CONVERGED


def _quality_check(out, qc):
    """The quality check of the run just written (report/front.folder_quality_check)."""
    import numpy as np

    from baarda.report.front import folder_quality_check

    image = np.asarray(qc.model.kind) == "image"
    sigma = qc.model.sigma[image] * 1e3  # µm
    return folder_quality_check(out, float(np.median(sigma)) if len(sigma) else None)


def _adjust(args, run):
    """Read, adjust, assess and write into `run`; the assessment and the text to print."""
    from baarda.pipeline import (
        adjust,
        assess,
        prepare,
        screen,
        snoop,
        snoop_with_variance_components,
        with_variance_components,
    )

    say = progress(args)
    block, config = read_configured_input(args)  # the settings resolved once
    tests = config.tests
    if say:
        say(f"read {block.summary()}")
    # the computation is imported (and compiled, on a first run) once the input is read
    announce_compile(args, len(block.photos))
    from baarda.output.bundle_results import write_results

    statistic = "tau" if args.tau else "w"
    if getattr(args, "edits", None) is not None:
        return _edited(args, run, block, config)
    if getattr(args, "screen", False):
        from baarda.cli.screen import options
        from baarda.output.screening_log import write_screening_log

        res, qc = screen(block, options(args, tests), snoop=args.snoop,
                         statistic=statistic, progress=say)
        write_results(run, qc, **_format(args))
        write_screening_log(run, res.log)
        _gpkg(args, run, qc)
        return qc, res.summary() + "\n" + qc.summary()
    problem = prepare(block, config=config)
    est = None
    if getattr(args, "vce", False) and not args.snoop:
        problem, est = with_variance_components(problem, progress=say)
    for note in dict.fromkeys([*problem.block.notes, *problem.notes]):  # read, prepare
        console(args).note(note)
    if args.snoop and getattr(args, "vce", False):
        qc, _ = snoop_with_variance_components(problem, tests, statistic=statistic,
                                               by_point=args.by_point, robust=args.robust,
                                               inseparable=args.inseparable, progress=say)
    elif args.snoop:
        qc = snoop(problem, tests, statistic=statistic, by_point=args.by_point,
                   robust=args.robust, inseparable=args.inseparable, progress=say)
    else:
        qc = assess(adjust(problem, progress=say), tests)
    if est is not None:
        qc = replace(qc, variance_components=est.components())
    write_results(run, qc, **_format(args))
    _gpkg(args, run, qc)
    return qc, qc.summary()


def _edited(args, run, block, config):
    """--edits FILE: the block with the operator's edits, adjusted and assessed as `baarda
    review` does (review/session.adjusted), the edits copied into the folder."""
    from baarda.errors import GeometryError, ProjectError
    from baarda.output.bundle_results import write_results
    from baarda.review.edits import read_edits, write_edits
    from baarda.review.session import adjusted

    used = [o for o in ("snoop", "screen", "vce", "robust") if getattr(args, o, False)]
    if used:
        raise ProjectError("command line", f"--edits and --{used[0]}: the edits are the "
                           "operator's rejections (baarda review); give one or the other")
    edits = read_edits(args.edits)
    try:
        state = adjusted(block, config, edits)
    except GeometryError:
        raise
    except ValueError as e:
        raise ProjectError(str(args.edits), str(e)) from None
    write_results(run, state.qc, **_format(args))
    write_edits(run.file("edits.csv"), edits)
    _gpkg(args, run, state.qc)
    return state.qc, state.qc.summary()


def _format(args) -> dict:
    """write_results' options of the observation table: Parquet with --parquet."""
    return {"parquet": True} if getattr(args, "parquet", False) else {}


def _gpkg(args, run, qc) -> None:
    if getattr(args, "gpkg", False):
        from baarda.output.gpkg import write_gpkg

        write_gpkg(run.file("block.gpkg"), qc)


def run_snoop(args) -> int:
    return run_adjust(args)
