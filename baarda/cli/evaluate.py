"""`baarda evaluate`: a Monte Carlo study of blunder-detection strategies on simulated
blocks (baarda/evaluation, docs/evaluation.md)."""

from __future__ import annotations

from baarda.cli.argtypes import (
    choices_list,
    integer,
    non_negative,
    scheduler_address,
    seed,
)
from baarda.cli.common import (
    add_control_arguments,
    add_flight_plan_arguments,
    add_out_argument,
    add_quiet_option,
    add_terrain_and_sigma_arguments,
    add_test_options,
    open_run,
    tests_option,
)
from baarda.cli.console import console
from baarda.errors import ProjectError


def register(sub) -> None:
    from baarda.evaluation.strategies import DEFAULT_STRATEGIES, STRATEGIES
    from baarda.simulate.aerial import FlightPlan

    p = sub.add_parser("evaluate", help="detection power, measured: blunder-detection "
                       "strategies on simulated blocks with planted blunders")
    add_out_argument(p, "output folder")
    d = FlightPlan()
    add_flight_plan_arguments(p, d)
    add_control_arguments(p, d)
    add_terrain_and_sigma_arguments(p, d)
    p.add_argument("--trials", type=integer(1, 10**7), default=100, help="simulated blocks")
    p.add_argument("--blunders", type=integer(0, 10**9), default=1,
                   help="blunders planted per trial (0: noise only, the false-rejection rate)")
    p.add_argument("--blunder-size-mdb", type=non_negative(hi=1e6), nargs="+", default=[1.0],
                   metavar="A", help="size in units of each observation's own MDB: A, or "
                   "drawn uniformly between A and B (sign random)")
    p.add_argument("--blunder-kinds", default="x,y", type=choices_list("xyXYZ", what="kinds"),
                   help="comma list of x,y (image) and X,Y,Z (control)")
    p.add_argument("--strategies", default=",".join(DEFAULT_STRATEGIES),
                   type=choices_list(STRATEGIES, what="strategies"),
                   help=f"comma list of {', '.join(STRATEGIES)} (docs/evaluation.md)")
    add_test_options(p, project=False)
    p.add_argument("--seed", type=seed, default=0, help="random seed: the same seed gives "
                   "the same rows however the trials are run")
    p.add_argument("--workers", type=integer(1, 1024), default=1, help="local worker processes")
    p.add_argument("--scheduler", metavar="ADDRESS", type=scheduler_address,
                   help="a running Dask distributed scheduler, e.g. tcp://host:8786 (instead "
                   "of --workers)")
    add_quiet_option(p)
    p.set_defaults(func=run)


def _options(args):
    from baarda.evaluation.study import StudyOptions
    from baarda.simulate.aerial import FlightPlan

    sizes = args.blunder_size_mdb
    if len(sizes) not in (1, 2) or sizes[0] > sizes[-1]:
        raise ProjectError("--blunder-size-mdb", "takes A, or A B with 0 <= A <= B, not "
                           + " ".join(f"{v:g}" for v in sizes))
    plan = FlightPlan(
        strips=args.strips, photos_per_strip=args.photos, forward_overlap=args.forward_overlap,
        side_overlap=args.side_overlap, image_scale=args.scale, focal_mm=args.focal,
        format_mm=args.format, pattern=args.pattern, stereo=args.stereo, control=args.control,
        control_spacing=args.control_spacing, height_chains=args.height_chains,
        relief_m=args.relief, sigma_image_um=args.sigma_image,
        sigma_control_m=tuple(args.sigma_control))
    try:
        return StudyOptions(
            plan=plan, trials=args.trials, blunders=args.blunders,
            size_mdb=(sizes[0], sizes[-1]),
            kinds=tuple(args.blunder_kinds.split(",")),  # both checked by the parser
            strategies=tuple(args.strategies.split(",")),
            seed=args.seed, tests=tests_option(None, args))
    except ValueError as e:
        raise ProjectError("command line", str(e)) from None


def run(args) -> int:
    from baarda.evaluation.study import run_study
    from baarda.output.atomic import write_bytes, write_text
    from baarda.output.evaluation_files import write_study
    from baarda.report.evaluation_plots import power_curves, read_study, study_html

    options = _options(args)
    con = console(args)
    with open_run(args, []) as run:
        try:
            study = run_study(options, workers=args.workers, scheduler=args.scheduler,
                              progress=con.counter("trials"))
        except (OSError, RuntimeError) as e:  # the scheduler cannot be reached or used
            if args.scheduler is None:
                raise
            raise ProjectError("--scheduler", f"{args.scheduler}: {e}") from None
        write_study(run, study)
        summary, power, curve = read_study(run.file)  # the report shows what was written
        png = power_curves(summary, power, curve)
        if png is not None:
            write_bytes(run.file("power.png"), png)
        write_text(run.file("report.html"), study_html(summary, power, png, run=run))
    con.print(study.summary())
    fewest = int(study.trials["n_planted"].min()) if len(study.trials) else 0
    if fewest < options.blunders:
        con.warn(f"--blunders {options.blunders}: some trials planted only {fewest} (the "
                 "blocks have no more observations of the kinds with a finite MDB)")
    con.verdict("evaluate", f"{options.trials} trials of {len(options.strategies)} "
                f"strateg{'y' if len(options.strategies) == 1 else 'ies'} -> {run.describe()}")
    return 0
