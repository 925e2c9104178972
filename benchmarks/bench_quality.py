"""Issue 3: baarda's adjustment plus rigorous qvv of every observation (assess) against
pycolmap's bundle adjustment alone, on the same block in the same run.

    PYTHONPATH=$PWD python benchmarks/bench_quality.py [--photos 1000] [--repeat 3] [--profile]

Target: wall time of baarda.adjust + baarda.bundle.bundle_quality.assess / pycolmap BA <= 1.0.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_bundle  # noqa: E402
import common  # noqa: E402

TARGET = 1.0


def report(recs: dict, args) -> str:
    a, p = recs["baarda"], recs["pycolmap"]
    ta = [r["adjust_s"] for r in a["runs"]]
    tq = [r["assess_s"] for r in a["runs"]]
    tt = [r["adjust_s"] + r["assess_s"] for r in a["runs"]]
    tp = [r["seconds"] for r in p["runs"]]
    first_a, first_p = a["runs"][0], p["runs"][0]
    rows = [
        ["engine", "wall s", "first call s", "RSS growth MB", "max RSS MB"],
        ["baarda adjust() + assess()", common.fmt_t(tt),
         f"{a['compile_adjust_s'] + a['compile_assess_s']:.2f} (numba)",
         f"{first_a['total_delta_mb']:.1f}", f"{a['process_max_rss_mb']:.0f}"],
        ["  of which adjust()", common.fmt_t(ta), f"{a['compile_adjust_s']:.2f}",
         f"{first_a['adjust_delta_mb']:.1f}", ""],
        ["  of which assess()", common.fmt_t(tq), f"{a['compile_assess_s']:.2f}", "", ""],
        ["pycolmap BA alone (Ceres)", common.fmt_t(tp), f"{p['cold_s']:.2f}",
         f"{first_p['delta_mb']:.1f}", f"{p['process_max_rss_mb']:.0f}"],
    ]
    ratio = common.med(tt) / common.med(tp)
    lines = ["Issue 3: adjustment + rigorous qvv of all observations vs pycolmap BA alone",
             "=" * 72]
    lines += common.header(recs, args)
    lines += ["", common.table(rows), ""]
    lines += [f"assess(): qvv, r, w, tau, MDB, external reliability of {a['n_components']} "
              f"observation components; sum of redundancy numbers {a['sum_r']:.3f} = "
              f"redundancy {a['redundancy']}; max |w| {a['max_abs_w']:.2f}",
              f"iterations: baarda {a['iterations']} (Gauss-Newton), pycolmap "
              f"{p['iterations']} (LM)"]
    lines += common.agreement(recs)
    lines += ["", f"RATIO baarda (adjust + assess) / pycolmap BA = {ratio:.2f} (median; "
              f"min/min {(min(tt)) / min(tp):.2f}); target <= {TARGET}: "
              f"{'MET' if ratio <= TARGET else 'NOT MET'}"]
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = common.parser(__doc__)
    ap.add_argument("--both", action="store_true", help="print the issue 2 table as well")
    args = ap.parse_args(argv)
    recs = common.run_engines(args, quality=True)
    if args.both:
        print(bench_bundle.report(recs, args))
        print()
    print(report(recs, args))
    if args.profile:
        print()
        print(common.profiles(recs))


if __name__ == "__main__":
    main()
