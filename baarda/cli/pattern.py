"""`baarda pattern SPEC`: reliability of a point pattern for on-line relative orientation,
without measurements (redundancy numbers, r0, trace(Qgg), critical transfers; text and SVG)."""

from __future__ import annotations

from pathlib import Path

from baarda.options import DEFAULT_QTIE, DEFAULT_QYY, PATTERNS
from baarda.output.atomic import write_text


def register(sub) -> None:
    p = sub.add_parser("pattern", help="point-pattern design for relative orientation with "
                       "scale transfer (Kratky's Figures 2, 4, 7)")
    p.add_argument("spec", help=f"pattern: {', '.join(PATTERNS)}, CxR, CxR+corners, CxR+edges, "
                   "or a CSV file with columns name,x,y[,tie] (left image mm)")
    p.add_argument("--ties", type=int, default=0, choices=[0, 3, 5],
                   help="tie points (the left column) for the scale transfer")
    p.add_argument("--focal", type=float, default=152.0, help="principal distance, mm")
    p.add_argument("--base", type=float, default=92.0, help="base in the image, mm")
    p.add_argument("--width", type=float, default=92.0, help="half width of the pattern in y, "
                   "mm")
    p.add_argument("--twin-offset", type=float, default=1.0, help="distance of doubled points "
                   "from their original, mm")
    p.add_argument("--qyy", type=float, default=DEFAULT_QYY, help="q_yy / q_xx (default 2)")
    p.add_argument("--qtie", type=float, default=DEFAULT_QTIE,
                   help="cofactor of x'' at tie points / "
                   "q_xx (default 1)")
    p.add_argument("--serious", type=float, default=0.8, help="ratio to the diagonal from "
                   "which a transfer is listed as serious (default 0.8)")
    p.add_argument("--matrix", action="store_true", help="print the full Qvv P matrix")
    p.add_argument("--svg", type=Path, help="write the drawing as SVG")
    p.set_defaults(func=run)


def run(args) -> int:
    from baarda.pipeline import pattern_drawing, point_pattern

    spec_path = Path(args.spec)
    d, title = point_pattern(args.spec, ties=args.ties, focal=args.focal, base=args.base,
                             width=args.width, twin_offset=args.twin_offset, qyy=args.qyy,
                             serious=args.serious, qtie=args.qtie)
    print(pattern_drawing(d, title), end="")
    if args.matrix:
        labels = [d.label(i) for i in range(d.n)]
        print("Qvv P (column j: effect of an error in observation j):")
        print("        " + "".join(f"{s:>7}" for s in labels))
        for i, s in enumerate(labels):
            print(f"  {s:>6}" + "".join(f"{v:7.3f}" for v in d.qvvp[i]))
    if args.svg is not None:
        if spec_path.is_file() and args.svg.resolve() == spec_path.resolve():
            raise FileExistsError(f"output {args.svg} is the input file")
        write_text(args.svg, pattern_drawing(d, title, svg=True))
        print(f"drawing written to {args.svg}")
    return 0
