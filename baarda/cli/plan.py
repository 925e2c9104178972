"""`baarda plan -o OUT`: design-stage reliability of a flight plan or of a project's design.

`baarda modified-snoop PROJECT -o OUT`: Gruen's modified data snooping with a reliability
table (approximate sqrt(qvv); exact values only inside the +-k_q band).
"""

from __future__ import annotations

from pathlib import Path

from baarda.cli.argtypes import SIGMA_M, SIGMA_UM, number
from baarda.cli.common import (
    add_encoding_option,
    add_flight_plan_arguments,
    add_out_argument,
    add_quiet_option,
    add_test_options,
    announce_compile,
    open_run,
    progress,
    requested_settings,
)
from baarda.cli.console import console
from baarda.errors import ProjectError
from baarda.output.run_folder import check_output_file
from baarda.simulate.aerial import FlightPlan


def register(sub) -> None:
    d = FlightPlan()
    p = sub.add_parser("plan", help="design-stage reliability of a planned block (no "
                       "measurements): sqrt(qvv), MDB, external reliability, precision, advice")
    add_out_argument(p, "output folder")
    p.add_argument("--project", type=Path, help="take the design (photos, points, stereo "
                   "models, control, weights) of this project instead of a flight plan")
    add_encoding_option(p)
    p.add_argument("--adjusted", action="store_true", help="with --project: geometry from an "
                   "adjustment of the project (default: its approximate orientations)")
    add_flight_plan_arguments(p, d)
    p.add_argument("--sigma-image", type=SIGMA_UM, default=d.sigma_image_um, help="µm")
    p.add_argument("--bridging", type=number(0.5, 1e3), default=2.0, help="control every I base "
                   "lengths "
                   "on the perimeter (Gruen's bridging distance)")
    p.add_argument("--bridging-y", type=number(0.1, 1e3),
                   help="control grid across the strips in strip distances (default: as "
                   "--bridging with 50 %% side overlap or more, else 0.5: "
                   "height points on every row of tie points between strips)")
    p.add_argument("--relief", type=number(-1e4, 1e4, unit="m"), default=0.0,
                   help="terrain relief in m (flat)")
    p.add_argument("--interior", default="height", choices=["height", "full", "none"],
                   help="control at the interior grid positions")
    p.add_argument("--twin-control", action="store_true",
                   help="each control point with a close companion")
    p.add_argument("--sigma-control", type=SIGMA_M, nargs=3, metavar=("X", "Y", "Z"),
                   help="m (default: error-free control)")
    add_test_options(p)
    p.add_argument("--what-if", action="store_true", help="recompute the plan with each "
                   "remedy (twin control, 5x5 points, 60 %% side overlap, stereo)")
    p.add_argument("--derive-table", type=Path, metavar="CSV", help="also derive a reliability "
                   "table for this flight plan (control every L/3, L/2, L; single and twin) "
                   "for `modified-snoop --table`")
    p.add_argument("--no-plots", action="store_true", help="no plan_maps.png")
    p.add_argument("--name", default="plan", help="name of the design block")
    add_quiet_option(p, "printed report")
    p.set_defaults(func=run_plan)

    m = sub.add_parser("modified-snoop", help="Gruen's modified data snooping: approximate "
                       "sqrt(qvv) from a reliability table, exact values only where needed")
    m.add_argument("project", type=Path, help="project folder")
    add_encoding_option(m)
    add_out_argument(m, "output folder")
    m.add_argument("--table", default="baarda", help="'baarda' (our study table), 'gruen' "
                   "(Table 2 of Gruen 1980) or a CSV written by `plan --derive-table`")
    m.add_argument("--k-q", type=number(0, 100, lo_open=True), default=25.0,
                   help="tolerance of the approximations in %% (Gruen: 25)")
    m.add_argument("--tau", action="store_true", help="Pope's tau (sigma0 a posteriori) "
                   "instead of Baarda's w")
    add_test_options(m)
    add_quiet_option(m)
    m.set_defaults(func=run_modified)


def _flight(args) -> FlightPlan:
    return FlightPlan(strips=args.strips, photos_per_strip=args.photos,
                      forward_overlap=args.forward_overlap, side_overlap=args.side_overlap,
                      image_scale=args.scale, focal_mm=args.focal, format_mm=args.format,
                      pattern=args.pattern, stereo=args.stereo,
                      sigma_image_um=args.sigma_image, relief_m=args.relief, name=args.name)


def run_plan(args) -> int:
    con = console(args)
    with open_run(args, [args.project]) as run:
        files, verdict = _plan(args, run)
    if not con.quiet:
        con.print((Path(args.out) / "plan_report.txt").read_text(encoding="utf-8"))
    con.print("written: " + ", ".join(str(f) for f in files))
    con.verdict("plan", f"{verdict} -> {run.describe()}")
    return 0


def _plan(args, run) -> tuple[list[Path], str]:
    from baarda.output.plan_files import write_plan, write_reliability_table
    from baarda.planning.advice import advise, what_if
    from baarda.planning.design import ControlLayout
    from baarda.planning.design_reliability import plan as plan_design
    from baarda.planning.gruen_study import derive_table, simulate_cases

    if args.derive_table:
        check_output_file(args.derive_table, [args.project])
        if args.project:
            raise ProjectError("--derive-table", "needs a flight plan, not --project")
    say = progress(args) or (lambda m: None)
    flight = None
    wi = None
    if args.project:
        from baarda.io.configuration import read_configured
        from baarda.pipeline import as_design

        block, config = read_configured(args.project, None, requested_settings(args),
                                        encoding=args.encoding)
        subject, layout = as_design(block), None
        title = f"design of project {args.project}"
    else:
        from baarda.io.configuration import resolve_config

        config = resolve_config(requested_settings(args))  # no project: the defaults
        flight = _flight(args)
        by = args.bridging_y
        if by is None:
            by = args.bridging if flight.side_overlap >= 0.5 else 0.5
        layout = ControlLayout(spacing=args.bridging, spacing_y=by, interior=args.interior,
                               twin=args.twin_control,
                               sigma_m=tuple(args.sigma_control) if args.sigma_control else None)
        subject = flight
        title = (f"{flight.strips} strips x {flight.photos_per_strip} photos, "
                 f"{flight.forward_overlap:.0%}/{flight.side_overlap:.0%} overlap, "
                 f"{flight.pattern}x{flight.pattern} points, "
                 f"{'stereo' if flight.stereo else 'mono'}, control every {args.bridging:g} "
                 f"bases{', twin' if args.twin_control else ''}")
    announce_compile(args)
    if flight is not None and args.what_if:
        say("computing the remedies")
        assert layout is not None  # set with the flight
        wi = what_if(flight, layout)
    plan = plan_design(subject, layout, config.tests, adjusted=args.adjusted)
    say(f"design block: {plan.block.summary()}")
    advice = advise(plan, flight)
    files = write_plan(run, plan, advice, wi, title, plots=not args.no_plots)
    from baarda.output.atomic import write_text
    from baarda.report.plan_page import plan_html

    write_text(run.file("plan_report.html"), plan_html(run.file, title, run=run))
    if args.derive_table:
        if flight is not None:
            length = flight.photos_per_strip - 1
            cases = simulate_cases(flight, (length / 3, length / 2, float(length)))
            write_reliability_table(args.derive_table,
                                    derive_table(cases, f"baarda plan ({title})"),
                                    header=f"reliability table derived by baarda plan: {title}")
            files.append(args.derive_table)
    return files, (f"redundancy {plan.redundancy}, {len(advice)} weak place(s) with remedies "
                   "in plan_report.txt")


def run_modified(args) -> int:
    con = console(args)
    with open_run(args, [args.project]) as run:
        text, verdict = _modified(args, run)
    con.print(text + f"results written to {run.describe()}")
    con.verdict("modified-snoop", f"{verdict} -> {run.describe()}")
    return 0


def _modified(args, run) -> tuple[str, str]:
    from baarda.io.configuration import read_configured
    from baarda.output.plan_files import write_modified_snooping
    from baarda.pipeline import adjust, prepare
    from baarda.planning.modified_snoop import modified_snoop
    from baarda.planning.reliability_tables import baarda_table, gruen_table, read_table

    say = progress(args)
    table = {"baarda": baarda_table, "gruen": gruen_table}.get(args.table)
    table = table() if table else read_table(args.table)
    block, config = read_configured(args.project, None, requested_settings(args),
                                    encoding=args.encoding)
    announce_compile(args, len(block.photos))
    res = adjust(prepare(block, config=config), progress=say)
    ms = modified_snoop(res, table=table, k_q=args.k_q / 100.0, tests=config.tests,
                        statistic="tau" if args.tau else "w")
    df = ms.table()
    text = res.summary() + "\n\n" + ms.summary() + "\n"
    rej = df[df["rejected"]]
    if len(rej):
        text += "rejected:\n" + rej[["kind", "photo", "point", "component", "class", "residual",
                                     "statistic", "exact"]].to_string(index=False) + "\n"
    write_modified_snooping(run, df, text)
    return text, f"sigma0 {res.sigma0:.4g}, {len(rej)} rejected"
