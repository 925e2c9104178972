"""`baarda check OUT`: the invariants of a result folder, from its files alone."""

from __future__ import annotations

from pathlib import Path

from baarda.cli.argtypes import number
from baarda.cli.common import CHECK_FAILED, OK


def register(sub) -> None:
    p = sub.add_parser("check", help="check a result folder's invariants: sum of r = "
                       "redundancy, sigma0 from every used observation, the global test, "
                       "every RMS line")
    p.add_argument("folder", type=Path, help="a result folder written by baarda")
    p.add_argument("--rtol", type=number(1e-15, 1.0), default=1e-6, help="relative "
                   "agreement of the sums recomputed from the rows with the figures stated")
    p.add_argument("-q", "--quiet", action="store_true", help="print only what does not hold")
    p.set_defaults(func=run, prints_results=True)


def run(args) -> int:
    from baarda.report.check import check_folder

    findings = check_folder(args.folder, args.rtol)
    for f in findings:
        if not (args.quiet and f.ok):
            print(f.line())
    bad = [f for f in findings if not f.ok]
    print(f"{len(findings) - len(bad)} of {len(findings)} invariants hold in {args.folder}"
          + ("" if not bad else f"; {len(bad)} do not"))
    return CHECK_FAILED if bad else OK
