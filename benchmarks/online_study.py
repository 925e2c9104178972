"""Issue 33's replay study: blunders found at measurement time (the on-line bundle, each
photo tested as it comes, the worst rejected observation re-measured = taken out) next to
data snooping of the whole block at the end, on the same simulated blocks.

    baarda evaluate -o STUDY --strips 20 --photos 30 --trials 20 --blunders 30 \\
        --blunder-size-mdb 1 3 --strategies online,snoop --seed 33
    PYTHONPATH=$PWD python benchmarks/online_study.py STUDY

prints, per strategy, the share of planted blunders located strictly (that very component
taken out by its own test), identified up to its group and located with the groups taken
out or set aside as a whole, with the good components lost per trial; for the on-line
bundle the share rejected at the step the blunder was taken in and the share not checkable
then, each with 95 % Clopper-Pearson intervals, and the located shares by size in MDB.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from baarda.evaluation.rates import clopper_pearson


def _rate(k: int, n: int) -> str:
    lo, hi = clopper_pearson(k, n)
    return f"{k}/{n} = {k / n:.3f} [{lo:.3f}, {hi:.3f}]" if n else "-"


def main(folder: Path) -> None:
    b = pd.read_csv(folder / "blunders.csv", keep_default_na=False, na_values=[""],
                    dtype={"photo": str, "point": str})
    t = pd.read_csv(folder / "trials.csv", keep_default_na=False, na_values=[""])
    s = json.loads((folder / "summary.json").read_text())
    first = s.get("first_adjustment") or s.get("rates", {}).get("first_adjustment", {})
    print(f"{folder}: {t['trial'].nunique()} trials, {len(b) // b['strategy'].nunique()} "
          "blunders planted")
    if first:
        print(f"planted blunders significant in the first adjustment of the whole block: "
              f"{_rate(first['planted_significant'], first['planted'])}")
    for name, g in b.groupby("strategy", sort=False):
        tt = t[t["strategy"] == name]
        n = len(g)
        good = int((tt["n_observations"] - tt["n_planted"]).sum())
        nf = int(tt["n_false"].sum())
        if "strict" in g:  # issue 44: the strict count and the group count apart
            print(f"\n{name}: located strictly {_rate(int(g['strict'].sum()), n)}, "
                  f"identified up to its group {_rate(int(g['identified'].sum()), n)}, "
                  f"good components lost {nf / len(tt):.2f} per trial")
        print(f"{'' if 'strict' in g else chr(10)}{name}: located (alone or with a group "
              f"rejected or set aside as a whole) {_rate(int(g['located'].sum()), n)}")
        print(f"  good observations taken out {nf / len(tt):.2f} per trial "
              f"({_rate(nf, good)} of the good components)")
        print(f"  failed trials {int(tt['failed'].notna().sum())}, "
              f"{tt['seconds'].mean():.1f} s per trial")
        if g["at_entry"].notna().any():
            e = g["at_entry"]
            print(f"  rejected at the step it was taken in {_rate(int((e == 'reject').sum()), n)}")
            print(f"  not checkable then (suspect: r < 0.001) "
                  f"{_rate(int((e == 'suspect').sum()), n)}")
            print(f"  accepted then {_rate(int((e == 'accept').sum()), n)}")
            late = g[(e != "reject") & g["located"]]
            print(f"  located later (a later ray or photo made it significant) "
                  f"{_rate(len(late), n)}")
            ok = g[e != "suspect"]
            print(f"  of the checkable ones: rejected when taken in "
                  f"{_rate(int((ok['at_entry'] == 'reject').sum()), len(ok))}, located "
                  f"{_rate(int(ok['located'].sum()), len(ok))}")
        size = np.abs(g["size_mdb"])
        for lo, hi in ((1.0, 1.5), (1.5, 2.0), (2.0, 3.0)):
            sel = (size >= lo) & (size < hi)
            k = int(g.loc[sel, "located"].sum())
            print(f"  {lo:g}-{hi:g} MDB: located {_rate(k, int(sel.sum()))}"
                  + (f", rejected when taken in "
                     f"{_rate(int((g.loc[sel, 'at_entry'] == 'reject').sum()), int(sel.sum()))}"
                     if g["at_entry"].notna().any() else ""))
    both = b.pivot_table(index=["trial", "photo", "point", "component"], columns="strategy",
                         values="located", aggfunc="first")
    if {"online", "snoop"} <= set(both.columns):
        a, c = both["online"].astype(bool), both["snoop"].astype(bool)
        print(f"\nthe same blunders: located by both {int((a & c).sum())}, on-line only "
              f"{int((a & ~c).sum())}, snooping only {int((~a & c).sum())}, neither "
              f"{int((~a & ~c).sum())}")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
