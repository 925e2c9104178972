"""Issue 2: baarda's bundle adjustment against pycolmap's (Ceres) on the same block.

    PYTHONPATH=$PWD python benchmarks/bench_bundle.py [--photos 1000] [--repeat 3] [--profile]

Target: wall time of baarda.adjust / pycolmap bundle adjustment <= 0.5.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import common  # noqa: E402

TARGET = 0.5


def report(recs: dict, args) -> str:
    a, p = recs["baarda"], recs["pycolmap"]
    ta = [r["adjust_s"] for r in a["runs"]]
    tp = [r["seconds"] for r in p["runs"]]
    first_a, first_p = a["runs"][0], p["runs"][0]
    rows = [
        ["engine", "wall s", "iterations", "first call s", "RSS growth MB", "max RSS MB",
         "final v'Pv"],
        ["baarda adjust()", common.fmt_t(ta), str(a["iterations"]),
         f"{a['compile_adjust_s']:.2f} (numba)", f"{first_a['adjust_delta_mb']:.1f}",
         f"{a['process_max_rss_mb']:.0f}", f"{a['final_vtpv']:.8g}"],
        ["pycolmap BA (Ceres)", common.fmt_t(tp), f"{p['iterations']} (LM)",
         f"{p['cold_s']:.2f}", f"{first_p['delta_mb']:.1f}", f"{p['process_max_rss_mb']:.0f}",
         f"{p['final_vtpv']:.8g}"],
    ]
    ratio = common.med(ta) / common.med(tp)
    lines = ["Issue 2: bundle adjustment, baarda vs pycolmap", "=" * 72]
    lines += common.header(recs, args)
    lines += ["", common.table(rows), ""]
    setup = common.med([r["setup_seconds"] for r in p["runs"]])
    ceres = common.med([r["ceres_seconds"] for r in p["runs"]])
    lines += [f"pycolmap time = building the Ceres problem ({setup:.3f} s, incl. "
              f"control residual blocks) + Ceres solve ({ceres:.3f} s); "
              f"building the Reconstruction from the block ({p['build_s']:.2f} s, Python) "
              "not counted",
              f"baarda time = adjust(block): problem set-up, intersection of approximate "
              f"points, {a['iterations']} Gauss-Newton iterations, final factorisation",
              f"Ceres: {p['termination']}; {p['brief']}"]
    lines += common.agreement(recs)
    lines += ["", f"RATIO baarda / pycolmap = {ratio:.2f} (median; min/min "
              f"{min(ta) / min(tp):.2f}); target <= {TARGET}: "
              f"{'MET' if ratio <= TARGET else 'NOT MET'}"]
    return "\n".join(lines)


def main(argv=None) -> None:
    args = common.parser(__doc__).parse_args(argv)
    recs = common.run_engines(args, quality=False)
    print(report(recs, args))
    if args.profile:
        print()
        print(common.profiles(recs))


if __name__ == "__main__":
    main()
