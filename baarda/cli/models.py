"""`baarda models PROJECT -o OUT`: independent-model block adjustment (FOTEF).

PROJECT is a model project (project.toml, models.csv, ground_points.csv) or a bundle
project, whose photos are then formed into models by relative orientation.
"""

from __future__ import annotations

from pathlib import Path

from baarda.block.model_deformations import ALL
from baarda.cli.argtypes import (
    SIGMA_M,
    SIGMA_UM,
    choices_list,
    integer,
    non_negative,
    number,
    seed,
)
from baarda.cli.common import (
    MAX_PHOTOS,
    MAX_STRIPS,
    NOT_CONVERGED,
    OK,
    add_encoding_option,
    add_out_argument,
    add_quiet_option,
    add_test_options,
    announce_compile,
    open_run,
    progress,
    tests_option,
)
from baarda.cli.console import console
from baarda.cli.verdicts import models_verdict
from baarda.errors import ProjectError


def register(sub) -> None:
    p = sub.add_parser("models", help="independent-model block adjustment with data snooping "
                       "and tests of model deformations (FOTEF)")
    p.add_argument("project", type=Path, help="model project (models.csv) or bundle project")
    add_out_argument(p, "output folder")
    p.add_argument("--2d", dest="planimetric", action="store_true",
                   help="planimetric adjustment (4 parameters) with a separate height "
                   "adjustment instead of the spatial one (7 parameters)")
    p.add_argument("--level", action="store_true", help="2d: level the models by the tilts "
                   "of a spatial adjustment first")
    p.add_argument("--no-snoop", action="store_true", help="statistics only, no rejections")
    p.add_argument("--tau", action="store_true", help="snoop with Pope's tau")
    p.add_argument("--by-point", action="store_true",
                   help="reject the coordinates of a model point together")
    add_test_options(p)
    ext = p.add_mutually_exclusive_group()
    ext.add_argument("--external", dest="external", action="store_true", default=None,
                     help="external reliability on detail points and distances (default "
                     "up to 400 models)")
    ext.add_argument("--no-external", dest="external", action="store_false",
                     help="no external reliability (faster on large blocks)")
    p.add_argument("--deformations", default="all",
                   type=choices_list(ALL, what="deformations", special=("all", "none")),
                   help="comma list of model deformations "
                   f"to test ({', '.join(ALL)}), 'all' or 'none'")
    p.add_argument("--clusters", type=Path, help="clusters.csv (cluster, point): control "
                   "clusters to test")
    p.add_argument("--hypotheses", type=Path, help="hypotheses.csv: user-defined H")
    p.add_argument("--vce", action="store_true", help="estimate a variance component per "
                   "observation group (model coordinates XY and Z, projection centres, "
                   "control X, Y, Z), re-weight and adjust again until they converge; the "
                   "tests and snooping then use the estimated sigmas")
    add_encoding_option(p)
    p.add_argument("--covariance", action="store_true", help="bundle project: use the full "
                   "covariance of each model point from the relative orientation")
    add_quiet_option(p)
    p.set_defaults(func=run)
    q = sub.add_parser("simulate-models", help="simulate an independent-model block with "
                       "known truth (truth.json)")
    add_out_argument(q, "model project to write")
    q.add_argument("--strips", type=integer(1, MAX_STRIPS), default=2,
                   help="number of strips")
    q.add_argument("--models", type=integer(1, MAX_PHOTOS), default=4,
                   help="models per strip")
    q.add_argument("--layout", default="fotef", choices=["fotef", "grid"],
                   help="point layout: FOTEF's study or a regular grid")
    q.add_argument("--scale", type=number(1, 1e7), default=5000.0, help="image scale 1:SCALE")
    q.add_argument("--sigma-model", type=SIGMA_UM, nargs=2, default=[10.0, 15.0],
                   metavar=("XY", "Z"), help="µm")
    q.add_argument("--sigma-control", type=SIGMA_M, default=0.05, help="m")
    q.add_argument("--control-spacing", type=integer(1, MAX_PHOTOS), default=2,
                   help="planimetric control on the long borders every k bases")
    q.add_argument("--height-chains", type=integer(0, MAX_PHOTOS), default=1,
                   help="height control chains across the strips every k bases")
    q.add_argument("--tilt", type=non_negative("rad", 1.0), default=0.01,
                   help="model tilts, rad (std)")
    q.add_argument("--blunders", type=integer(0, 10**9), default=0, help="gross errors planted")
    q.add_argument("--deformation", action="append", default=[], metavar="NAME=UM",
                   type=deformation, help="plant a block-invariant deformation "
                   f"({', '.join(ALL)}) of this size in µm")
    q.add_argument("--seed", type=seed, default=0, help="random seed")
    add_quiet_option(q, "closing line on stdout")
    q.set_defaults(func=run_simulate)


def deformation(text: str) -> tuple[str, float]:
    """--deformation NAME=SIZE_UM (a finite size)."""
    import argparse
    import math

    name, _, size = text.partition("=")
    try:
        value = float(size)
    except ValueError:
        value = math.nan
    if name not in ALL or not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"NAME=SIZE_UM with NAME one of {', '.join(ALL)} "
                                         f"and a finite size, not {text!r}")
    return name, value


def run(args) -> int:
    con = console(args)
    with open_run(args, [args.project]) as run:
        bq = _adjust_models(args, run)
    con.print(bq.summary())
    con.print(f"results written to {run.describe()}")
    con.verdict("models", f"{models_verdict(bq.to_dict())} -> {run.describe()}")
    return OK if bq.converged else NOT_CONVERGED


def _adjust_models(args, run):
    from baarda.output.model_results import write_results
    from baarda.pipeline import adjust_models, read_models

    say = progress(args)
    block = read_models(args.project, covariance=args.covariance, encoding=args.encoding)
    if say:
        say(f"read {block.summary()}")
    for note in block.notes:
        console(args).note(note)
    announce_compile(args)
    if args.deformations == "all":
        defs = ALL
    elif args.deformations == "none":
        defs = None
    else:
        defs = tuple(args.deformations.split(","))  # checked by the parser
    bq = adjust_models(block, "2d" if args.planimetric else "3d", snoop=not args.no_snoop,
                 statistic="tau" if args.tau else "w", by_point=args.by_point,
                 tests=tests_option(block.settings, args), external=args.external,
                 deformations=defs,
                 clusters=args.clusters, user=args.hypotheses,
                 level_models=args.level, vce=args.vce, progress=say)
    write_results(run, bq)
    return bq


def run_simulate(args) -> int:
    import json

    from baarda.output.atomic import write_text
    from baarda.output.project_files import write_model_project
    from baarda.simulate.model_blocks import ModelPlan, simulate_models

    defs = dict(args.deformation)
    plan = ModelPlan(strips=args.strips, models_per_strip=args.models, layout=args.layout,
                     image_scale=args.scale, sigma_model_um=tuple(args.sigma_model),
                     sigma_control_m=(args.sigma_control,) * 3,
                     control_spacing=args.control_spacing, height_chains=args.height_chains,
                     tilt_rad=args.tilt, blunders=args.blunders, deformations=defs,
                     seed=args.seed)
    with open_run(args, []) as run:
        try:
            block, truth = simulate_models(plan)
        except ValueError as e:  # more blunders than model coordinates
            raise ProjectError("--blunders", str(e)) from None
        write_model_project(block, run)
        write_text(run.file("truth.json"), json.dumps(truth, indent=1, default=float) + "\n")
    console(args).print(f"{block.summary()} -> {run.describe()}")
    return 0
