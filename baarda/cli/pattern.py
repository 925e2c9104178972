"""`baarda pattern SPEC`: reliability of a point pattern for on-line relative orientation,
without measurements (redundancy numbers, r0, trace(Qgg), critical transfers; text and SVG)."""

from __future__ import annotations

import os
from pathlib import Path

from baarda.cli.argtypes import COFACTOR, number, pattern_spec, positive
from baarda.cli.common import add_quiet_option
from baarda.cli.console import console
from baarda.errors import ProjectError
from baarda.options import DEFAULT_QTIE, DEFAULT_QYY, PATTERNS
from baarda.output.atomic import write_text
from baarda.output.run_folder import check_output_file


def register(sub) -> None:
    p = sub.add_parser("pattern", help="point-pattern design for relative orientation with "
                       "scale transfer (Kratky's Figures 2, 4, 7)")
    p.add_argument("spec", type=pattern_spec(PATTERNS, MAX_SIDE), help="pattern: "
                   f"{', '.join(PATTERNS)}, CxR, CxR+corners, CxR+edges, or a CSV file with "
                   "columns name,x,y[,tie] (left image mm)")
    p.add_argument("--ties", type=int, default=0, choices=[0, 3, 5],
                   help="tie points (the left column) for the scale transfer")
    p.add_argument("--focal", type=number(1, 1e4, unit="mm"), default=152.0,
                   help="principal distance, mm")
    p.add_argument("--base", type=positive("mm", 1e3), default=92.0, help="base in the image, mm")
    p.add_argument("--width", type=positive("mm", 1e3), default=92.0,
                   help="half width of the pattern in y, mm")
    p.add_argument("--twin-offset", type=positive("mm", 1e3), default=1.0,
                   help="distance of doubled points from their original, mm")
    p.add_argument("--qyy", type=COFACTOR, default=DEFAULT_QYY, help="q_yy / q_xx (default 2)")
    p.add_argument("--qtie", type=COFACTOR, default=DEFAULT_QTIE,
                   help="cofactor of x'' at tie points / "
                   "q_xx (default 1)")
    p.add_argument("--serious", type=positive(hi=1e3), default=0.8,
                   help="ratio to the diagonal from which a transfer is listed as serious "
                   "(default 0.8)")
    p.add_argument("--matrix", action="store_true", help="print the full Qvv P matrix")
    p.add_argument("--svg", type=Path, help="write the drawing as SVG")
    add_quiet_option(p, "printed pattern")
    p.set_defaults(func=run, prints_results=True)


#: the most columns and rows of a CxR pattern (a relative orientation measures a few dozen)
MAX_SIDE = 20


def run(args) -> int:
    from baarda.pipeline import pattern_drawing, point_pattern

    say = console(args).print
    spec_path = Path(args.spec)
    from_file = spec_path.suffix.lower() == ".csv" or os.path.isfile(spec_path)
    if args.svg is not None:
        check_output_file(args.svg, [spec_path] if from_file else [])
    try:
        d, title = point_pattern(args.spec, ties=args.ties, focal=args.focal, base=args.base,
                                 width=args.width, twin_offset=args.twin_offset, qyy=args.qyy,
                                 serious=args.serious, qtie=args.qtie)
    except ProjectError:
        raise
    except ValueError as e:  # --ties that the pattern's left column does not have
        raise ProjectError("--ties", str(e)) from None
    say(pattern_drawing(d, title), end="")
    if args.matrix:
        labels = [d.label(i) for i in range(d.n)]
        say("Qvv P (column j: effect of an error in observation j):")
        say("        " + "".join(f"{s:>7}" for s in labels))
        for i, s in enumerate(labels):
            say(f"  {s:>6}" + "".join(f"{v:7.3f}" for v in d.qvvp[i]))
    if args.svg is not None:
        write_text(args.svg, pattern_drawing(d, title, svg=True))
        say(f"drawing written to {args.svg}")
    return 0
