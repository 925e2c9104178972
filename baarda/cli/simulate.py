"""`baarda simulate -o PROJECT`: a synthetic block with known truth (truth.json)."""

from __future__ import annotations

import json

from baarda.cli.argtypes import Pair, choices_list, integer, non_negative, positive, seed
from baarda.cli.common import (
    add_control_arguments,
    add_flight_plan_arguments,
    add_out_argument,
    add_quiet_option,
    add_terrain_and_sigma_arguments,
    open_run,
)
from baarda.cli.console import console
from baarda.errors import GeometryError, ProjectError
from baarda.output.atomic import write_text
from baarda.output.project_files import write_project
from baarda.simulate.aerial import FlightPlan, simulate_block


def register(sub) -> None:
    p = sub.add_parser("simulate", help="simulate an aerial block with known truth")
    add_out_argument(p, "project folder to write")
    d = FlightPlan()
    add_flight_plan_arguments(p, d)
    p.add_argument("--neat-area", action="store_true",
                   help="points only between the outer nadir lines")
    add_control_arguments(p, d)
    p.add_argument("--twin-control", action="store_true",
                   help="each control point with a close companion (a blunder in one shows)")
    p.add_argument("--check-points", type=integer(0, 10**9), default=d.check_points,
                   help="check points (not used in the adjustment, compared with it)")
    add_terrain_and_sigma_arguments(p, d)
    p.add_argument("--no-noise", action="store_true",
                   help="error-free observations (for checks of the adjustment itself)")
    p.add_argument("--blunders", type=integer(0, 10**9), default=0,
                   help="gross errors planted (listed in truth.json), at most one in each "
                   "observation of the chosen kinds")
    p.add_argument("--blunder-size", type=positive(hi=1e6), nargs=2, default=list(d.blunder_sigma),
                   action=Pair, metavar=("MIN", "MAX"), help="in a-priori sigmas")
    p.add_argument("--blunder-kinds", default="x,y", type=choices_list("xyXYZ", what="kinds"),
                   help="comma list of x,y,X,Y,Z")
    p.add_argument("--gnss", type=non_negative("m", 1e4), default=0.0, metavar="SIGMA_M",
                   help="GNSS antenna positions of every photo with this noise (m; gnss.csv); "
                   "0: none")
    p.add_argument("--gnss-offset", type=non_negative("m", 1e4), default=0.0, metavar="M",
                   help="a GNSS shift per strip, each component drawn with this standard "
                   "deviation (m; estimated per strip)")
    p.add_argument("--gnss-drift", type=non_negative("m/km", 1e4), default=0.0, metavar="M_PER_KM",
                   help="a GNSS drift per strip along the strip (m/km, drawn with this "
                   "standard deviation; estimated per strip)")
    p.add_argument("--imu", type=non_negative("deg", 90.0), default=0.0, metavar="SIGMA_DEG",
                   help="IMU attitudes of every photo with this noise (deg; imu.csv); 0: none")
    p.add_argument("--seed", type=seed, default=0,
                   help="random seed (the same seed gives the same project)")
    p.add_argument("--name", default="simulated", help="project name")
    add_quiet_option(p, "closing line on stdout")
    p.set_defaults(func=run)


def run(args) -> int:
    with open_run(args, []) as run:
        block = _simulate(args, run)
    for note in block.notes:
        console(args).note(note)
    console(args).print(f"{block.summary()} -> {run.describe()}")
    return 0


def _simulate(args, run):
    plan = FlightPlan(
        strips=args.strips, photos_per_strip=args.photos, forward_overlap=args.forward_overlap,
        side_overlap=args.side_overlap, image_scale=args.scale, focal_mm=args.focal,
        format_mm=args.format, pattern=args.pattern, stereo=args.stereo,
        neat_area=args.neat_area, control=args.control,
        control_spacing=args.control_spacing, height_chains=args.height_chains,
        twin_control=args.twin_control, check_points=args.check_points, relief_m=args.relief,
        sigma_image_um=args.sigma_image, sigma_control_m=tuple(args.sigma_control),
        noise=not args.no_noise, blunders=args.blunders,
        blunder_sigma=tuple(args.blunder_size),
        blunder_kinds=tuple(k.strip() for k in args.blunder_kinds.split(",") if k.strip()),
        gnss_sigma_m=args.gnss, gnss_offset_m=args.gnss_offset,
        gnss_drift_m_per_km=args.gnss_drift, imu_sigma_deg=args.imu,
        seed=args.seed, name=args.name)
    try:
        block, truth = simulate_block(plan)
    except GeometryError:  # no block at all: said in its words
        raise
    except ValueError as e:  # more blunders than the block has observations of their kinds
        raise ProjectError("--blunders", str(e)) from None
    write_project(block, run)
    write_text(run.file("truth.json"), json.dumps(truth, indent=1, default=float) + "\n")
    return block
