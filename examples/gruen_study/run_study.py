"""Gruen (1980), "Internal reliability models for aerial bundle systems", reproduced.

    PYTHONPATH=. python examples/gruen_study/run_study.py [--write-table CSV]

Prints our class means next to Gruen's Table 2, the checks of the acceptance criteria
(R2(x) = 0, sum of redundancy numbers = redundancy), the control classes against Gruen's
fitted lines, and the +-25 % tolerance check of his Figure 9.  --write-table writes our
reliability table (baarda/planning/data/baarda_study.csv is made this way).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

from baarda.output.plan_files import write_reliability_table
from baarda.planning.gruen_study import (
    GRUEN_ROWS,
    STUDY_BLOCKS,
    TOLERANCE,
    control_curves,
    format_side_by_side,
    photo_grid,
    run_study,
    side_by_side_markdown,
    tolerance_check,
)
from baarda.planning.reliability_tables import gruen_table

FIG9 = {2.0: (2, 0.46), 3.0: (1, 0.44), 6.0: (1, 0.43)}  # i: (count per photo, mean) in Fig. 9


def _band_summary(tc: pd.DataFrame) -> str:
    """Per block and class: values below the band (and how many on half-coverage photos),
    above it, the lowest and the highest value outside, the reference."""
    tc = tc.assign(below_half=tc["low"] & tc["half_coverage"])
    g = tc.groupby(["block", "class", "component"])
    summ = g.agg(reference=("reference", "first"), below=("low", "sum"),
                 below_on_half_photos=("below_half", "sum"),
                 above=("low", lambda s: int((~s).sum())), lowest=("sqrt_qvv", "min"),
                 highest=("sqrt_qvv", "max")).reset_index()
    return summ.to_string(index=False, float_format=lambda v: f"{v:.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write-table", help="write our derived reliability table to this CSV")
    ap.add_argument("--markdown", action="store_true", help="only the side-by-side table as "
                    "Markdown (for docs/planning.md)")
    args = ap.parse_args()
    pd.set_option("display.width", 120)
    t0 = time.perf_counter()
    study = run_study()
    dt = time.perf_counter() - t0
    if args.markdown:
        print(side_by_side_markdown(study.side_by_side()))
        return
    print(f"Gruen's study: {len(study.cases)} blocks adjusted in {dt:.1f} s\n")
    for c in study.cases[:: 3]:
        print(f"  block {c.block} ({c.control}): {c.plan.block.summary()}")

    print("\n1. Class means of sqrt(qvv): ours / Gruen's Table 2  (* = differs by more than "
          f"{TOLERANCE})\n")
    sbs = study.side_by_side()
    print(format_side_by_side(sbs))
    d = sbs["difference"].abs()
    worst = sbs.loc[d.idxmax()]
    print(f"\n  {len(sbs)} values compared: largest difference {d.max():.3f} "
          f"({worst['class']}({worst['component']}) {worst['control']} {worst['column']}), "
          f"RMS {np.sqrt(np.mean(d**2)):.3f}, {int((d > TOLERANCE).sum())} beyond {TOLERANCE}")

    print("\n2. Acceptance checks per block: R2(x) = 0, sum of redundancy numbers = redundancy\n")
    ck = study.checks()
    print(ck.to_string(index=False, float_format=lambda v: f"{v:.6f}"))
    print(f"\n  largest sqrt(qvv) of R2(x): {ck['max_R2x'].max():.2e}; largest |sum r - "
          f"redundancy|: {np.max(np.abs(ck['sum_r'] - ck['redundancy'])):.2e} (all components), "
          f"image components alone short by at most "
          f"{np.max(ck['redundancy'] - ck['sum_r_image']):.2e} (the error-free control)")

    print("\n3. Control classes per control distribution against Gruen's fitted lines a + b i\n")
    cc = control_curves(study)
    print(cc.to_string(index=False, float_format=lambda v: f"{v:.3f}"))

    print("\n4. Figure 9: CRO4/9(y) observations below 0.51 = 0.68 (1 - 0.25), single control")
    tc = tolerance_check(study, gruen_table())
    for b in STUDY_BLOCKS:
        for c in study.cases:
            if c.block != b or c.control != "single":
                continue
            sel = tc[(tc["block"] == b) & (tc["spacing"] == c.spacing)
                     & (tc["class"] == "CRO4/9") & (tc["component"] == "y") & tc["low"]]
            paper = FIG9.get(c.spacing) if b == "73" else None
            head = (f"\n  block {b}, i = {c.spacing:g}: {len(sel)} observation(s)"
                    + (f", mean {sel['sqrt_qvv'].mean():.2f}" if len(sel) else "")
                    + (f", all on half-coverage photos: {bool(sel['half_coverage'].all())}"
                       if len(sel) else ""))
            if paper:
                head += f"   [Gruen: {paper[0]} per marked photo, mean {paper[1]:.2f}]"
            if b == "75":
                head += "   [Gruen: none in the 75-blocks]"
            print(head)
            if b == "73" and len(sel):
                print("  strips (rows) x photos: count per photo")
                print("\n".join("    " + ln for ln in photo_grid(
                    c, sel.groupby("photo").size().to_dict()).splitlines()))

    print("\n5. All individual values against Gruen's recommended means (+-25 %), single "
          "control: count outside the band (below / above), of the values tested\n")
    tested = {(c.block, c.spacing): len(c.plan.image()) for c in study.cases}
    if len(tc):
        print(_band_summary(tc))
    total_out = len(tc)
    total = sum(tested[(c.block, c.spacing)] for c in study.cases if c.control == "single")
    print(f"\n  {total_out} of {total} image coordinates outside the band "
          f"({total_out / total:.1%})")

    ours = study.derive_table()
    tco = tolerance_check(study, ours)
    print(f"\n6. Against our own table (x and y separately): {len(tco)} of {total} outside "
          "+-25 %")
    if len(tco):
        print(_band_summary(tco))

    print("\n7. Our reliability table (recommended values per pattern, x / y / pooled)\n")
    f = ours.frame
    for ctl in ("single", "twin"):
        for cls in dict.fromkeys(c for c, _ in GRUEN_ROWS):
            vals = []
            for pat in ("3x3", "5x5"):
                r = f[(f["pattern"] == pat) & (f["control"] == ctl) & (f["class"] == cls)]
                vals.append(" ".join(f"{k} {r[r['component'] == k]['value'].iloc[0]:.3f}"
                                     for k in ("x", "y", "xy") if (r["component"] == k).any()))
            print(f"  {cls:7s} {ctl:6s}  3x3: {vals[0]:32s} 5x5: {vals[1]}")
    if args.write_table:
        write_reliability_table(args.write_table, ours, header=(
            "baarda's reliability table: mean sqrt(qvv) per Gruen class (x, y and pooled xy),\n"
            "from the reproduced study of Gruen (1980): blocks 43, 73, 45, 75, three control\n"
            "distributions each (i = L/3, L/2, L), single and twin control; each block and\n"
            "distribution weighs the same.  Made by examples/gruen_study/run_study.py."))
        print(f"\nwritten {args.write_table}")


if __name__ == "__main__":
    main()
