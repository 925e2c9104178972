"""`baarda online [FILE]`: on-line relative orientation with scale transfer, model by model,
with the ANAPLOT quality control after each model; `baarda online --bundle PROJECT` and
`--replay PROJECT`: the growing bundle block, every measurement tested as it is made
(cli/online_bundle.py; docs/online.md)."""

from __future__ import annotations

import sys
from pathlib import Path

from baarda.cli.argtypes import COFACTOR, SIGMA_UM, number
from baarda.cli.common import add_test_options, feed_lines, prompt_lines, tests_option
from baarda.cli.console import console
from baarda.options import DEFAULT_QTIE, DEFAULT_QYY
from baarda.output.atomic import write_text
from baarda.output.run_folder import check_output_file


def register(sub) -> None:
    p = sub.add_parser("online", help="on-line QC: strip bridging model by model (relative "
                       "orientation with scale transfer), or a bundle block tested measurement "
                       "by measurement (--bundle, --replay)")
    p.add_argument("file", nargs="?", type=Path,
                   help="measurement file, e.g. examples/online/strip.txt ('-' or none: "
                   "read lines from the prompt or from stdin)")
    p.add_argument("--focal", type=number(1, 1e4, unit="mm"),
                   help="principal distance in mm (or a camera line)")
    p.add_argument("--sigma", type=SIGMA_UM, default=10.0,
                   help="sigma of x'' in µm (default 10)")
    p.add_argument("--qyy", type=COFACTOR, default=DEFAULT_QYY, help="q_yy / q_xx (default 2)")
    p.add_argument("--qtie", type=COFACTOR, default=DEFAULT_QTIE,
                   help="cofactor of x'' at tie points / "
                   "q_xx (default 1 as Kratky; 5 accounts for the errors of the tie "
                   "coordinates, docs/online.md)")
    add_test_options(p, project=False)
    p.add_argument("--tau", action="store_true", help="test with Pope's tau instead of w")
    p.add_argument("--vce", action="store_true", help="estimate the variance components of "
                   "the y-parallaxes and of the x'' at the tie points over the strip so far "
                   "and orient and test each model with them (q_yy/q_xx and q_tie estimated; "
                   "a group with too little redundancy keeps --qyy / --qtie)")
    p.add_argument("-o", "--out", type=Path, help="write the strip coordinates (CSV); with "
                   "--bundle / --replay: the output folder")
    from baarda.cli.online_bundle import add_options

    add_options(p)
    p.set_defaults(func=run, prints_results=True)


def run(args) -> int:
    from baarda.cli.online_bundle import bundle_mode, run_bundle
    from baarda.pipeline import online_interpreter, strip_coordinates_csv

    if bundle_mode(args):
        return run_bundle(args)
    say = console(args).print
    interp = online_interpreter(say, focal=args.focal, sigma=args.sigma, qyy=args.qyy,
                                qtie=args.qtie, tests=tests_option(None, args),
                                statistic="tau" if args.tau else "w", vce=args.vce)
    if args.out is not None:
        check_output_file(args.out, [] if args.file in (None, Path("-")) else [args.file])
    if args.file is None or str(args.file) == "-":
        if sys.stdin.isatty():
            _prompt(interp)
        else:
            _batch(interp, sys.stdin, "<stdin>")
    else:
        from baarda.io.text_files import decode_text, file_bytes, split_lines

        name = str(args.file)
        text = decode_text(file_bytes(args.file), name, args.encoding)
        _batch(interp, split_lines(text), name)
    coordinates = strip_coordinates_csv(interp)
    if args.out is not None and coordinates:
        write_text(args.out, coordinates)
        say(f"strip coordinates written to {args.out}")
    return 0


def _batch(interp, lines, name: str) -> None:
    feed_lines(interp, lines, name, empty="no measurements: give a measurement file (e.g. "
               "examples/online/strip.txt, format in docs/online.md) or run baarda online "
               "in a terminal to type them")


def _prompt(interp) -> None:
    prompt_lines(interp, "baarda online: type 'help' for the commands, 'quit' to stop",
                 "online> ")  # a terminal
    try:
        interp.finish()
    except ValueError as e:
        print(f"error: {e}")
