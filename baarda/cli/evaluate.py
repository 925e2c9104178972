"""`baarda evaluate`: a Monte Carlo study of blunder-detection strategies on simulated
blocks (baarda/evaluation, docs/evaluation.md)."""

from __future__ import annotations

import sys
import time

from baarda.cli.common import (
    add_control_arguments,
    add_flight_plan_arguments,
    add_out_argument,
    add_terrain_and_sigma_arguments,
    open_run,
)
from baarda.errors import ProjectError


def register(sub) -> None:
    from baarda.evaluation.study import DEFAULT_STRATEGIES, STRATEGIES
    from baarda.simulate.aerial import FlightPlan

    p = sub.add_parser("evaluate", help="detection power, measured: blunder-detection "
                       "strategies on simulated blocks with planted blunders")
    add_out_argument(p, "output folder")
    d = FlightPlan()
    add_flight_plan_arguments(p, d)
    add_control_arguments(p, d)
    add_terrain_and_sigma_arguments(p, d)
    p.add_argument("--trials", type=int, default=100, help="simulated blocks")
    p.add_argument("--blunders", type=int, default=1, help="blunders planted per trial "
                   "(0: noise only, the false-rejection rate)")
    p.add_argument("--blunder-size-mdb", type=float, nargs="+", default=[1.0],
                   metavar="A", help="size in units of each observation's own MDB: A, or "
                   "drawn uniformly between A and B (sign random)")
    p.add_argument("--blunder-kinds", default="x,y", help="comma list of x,y (image) and "
                   "X,Y,Z (control)")
    p.add_argument("--strategies", default=",".join(DEFAULT_STRATEGIES),
                   help=f"comma list of {', '.join(STRATEGIES)} (docs/evaluation.md)")
    p.add_argument("--alpha0", type=float, default=0.001, help="level of the w-test")
    p.add_argument("--beta0", type=float, default=0.80, help="power of the B-method")
    p.add_argument("--seed", type=int, default=0, help="random seed: the same seed gives "
                   "the same rows however the trials are run")
    p.add_argument("--workers", type=int, default=1, help="local worker processes")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask distributed "
                   "scheduler, e.g. tcp://host:8786 (instead of --workers)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress display")
    p.set_defaults(func=run)


def _options(args):
    from baarda.evaluation.study import StudyOptions
    from baarda.options import TestOptions
    from baarda.simulate.aerial import FlightPlan

    sizes = args.blunder_size_mdb
    if len(sizes) not in (1, 2):
        raise ProjectError("command line", "--blunder-size-mdb takes A or A B")
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
            kinds=tuple(k.strip() for k in args.blunder_kinds.split(",") if k.strip()),
            strategies=tuple(s.strip() for s in args.strategies.split(",") if s.strip()),
            seed=args.seed, tests=TestOptions(args.alpha0, args.beta0))
    except ValueError as e:
        raise ProjectError("command line", str(e)) from None


def _bar(quiet: bool):
    """A progress line with the ETA on stderr, or None."""
    if quiet:
        return None
    t0 = time.perf_counter()

    def show(done: int, total: int) -> None:
        el = time.perf_counter() - t0
        eta = el / done * (total - done)
        print(f"\r[{'#' * (30 * done // total):<30}] {done}/{total} trials, "
              f"{el:.0f} s, ETA {eta:.0f} s", end="" if done < total else "\n",
              file=sys.stderr, flush=True)
    return show


def run(args) -> int:
    from baarda.evaluation.study import run_study
    from baarda.output.atomic import write_text
    from baarda.output.evaluation_files import write_study
    from baarda.report.evaluation_plots import power_curves, read_study, study_html

    options = _options(args)
    with open_run(args, []) as run:
        study = run_study(options, workers=args.workers, scheduler=args.scheduler,
                          progress=_bar(args.quiet))
        write_study(run, study)
        summary, power, curve = read_study(run.file)  # the report shows what was written
        png = power_curves(summary, power, curve)
        if png is not None:
            run.file("power.png").write_bytes(png)
        write_text(run.file("report.html"), study_html(summary, power, png))
    if not args.quiet:
        print(study.summary())
    return 0
