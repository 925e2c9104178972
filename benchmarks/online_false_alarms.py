"""Where the on-line replay's good rejections come from (issue 33's replay study,
docs/online.md): the trials of the study run again with the replay alone, each good
component it rejected put in one class.

    PYTHONPATH=$PWD python benchmarks/online_false_alarms.py [TRIALS] [--remeasure]

TRIALS: how many of the study's trials (default 6; seed 33, 20 x 30 photos, 30 blunders of
1-3 MDB, as `baarda evaluate --strategies online,snoop --seed 33` runs them).  Classes:
  set aside   - a good member of a group of components the test could not tell apart, its
                point set aside and never taken in again;
  other coord - the other coordinate of a blundered image point, rejected with it;
  at entry    - rejected at the step it was taken in;
  later       - rejected when a verdict changed as the block grew.
With --remeasure the operator measures a rejected image point again (the `online-remeasure`
strategy: its value in the block without blunders); then it counts the good components
measured again, those lost (taken out after their re-measurement was rejected again, or
set aside), the blunders left in the final block, and sigma0 at the end.
"""

from __future__ import annotations

import sys

from baarda.evaluation.strategies import component_keys
from baarda.evaluation.study import StudyOptions, planted_block
from baarda.online.replay import image_values, replay
from baarda.simulate.aerial import FlightPlan

CLASSES = ("set aside", "other coord", "at entry", "later")


def classify(trial: int, options: StudyOptions) -> dict[str, int]:
    p = planted_block(options, trial)
    keys = component_keys(p.model)
    planted = {keys[i] for i in p.rows}
    rp = replay(p.blundered, options.tests, remove="worst")
    entry: dict = {}
    for a in rp.answers:
        for t in a.tested:
            entry.setdefault((t.kind, t.photo, t.point, t.component), a.step)
    out = dict.fromkeys(CLASSES, 0)
    for step, *key, _w in rp.removed:
        key = tuple(key)
        if key in planted:
            continue
        if any(b[1:3] == key[1:3] for b in planted):
            out["other coord"] += 1
        elif entry.get(key) == step:
            out["at entry"] += 1
        else:
            out["later"] += 1
    out["set aside"] = sum(k not in planted for _, group in rp.aside for k in group)
    return out


def remeasured(trial: int, options: StudyOptions) -> dict[str, float]:
    p = planted_block(options, trial)
    keys = component_keys(p.model)
    planted = {keys[i] for i in p.rows}
    value = image_values(p.block)
    rp = replay(p.blundered, options.tests, remove="worst",
                remeasure=lambda photo, point: value[(photo, point)])
    again = {tuple(r[1:5]) for r in rp.remeasured}
    lost = {tuple(r[1:5]) for r in rp.removed} | {k for _, g in rp.aside for k in g}
    return {"measured again": len(again - planted), "lost": len(lost - planted),
            "blunders left": len(planted - again - lost),
            "sigma0": float(rp.online.result().adjustment.sigma0)}


def main_remeasure(n: int) -> None:
    options = StudyOptions(plan=FlightPlan(strips=20, photos_per_strip=30), trials=n,
                           blunders=30, size_mdb=(1.0, 3.0), strategies=("online",), seed=33)
    rows = []
    for trial in range(n):
        c = remeasured(trial, options)
        rows.append(c)
        print(f"trial {trial}: good measured again {c['measured again']}, good lost "
              f"{c['lost']}, blunders left {c['blunders left']}, sigma0 {c['sigma0']:.4f}",
              flush=True)
    mean = {k: sum(r[k] for r in rows) / n for k in rows[0]}
    print(f"per trial ({n} trials): good measured again {mean['measured again']:.2f}, good "
          f"lost {mean['lost']:.2f}, blunders left {mean['blunders left']:.2f} of 30, "
          f"sigma0 at the end {mean['sigma0']:.4f}")


def main(n: int) -> None:
    options = StudyOptions(plan=FlightPlan(strips=20, photos_per_strip=30), trials=n,
                           blunders=30, size_mdb=(1.0, 3.0), strategies=("online",), seed=33)
    total = dict.fromkeys(CLASSES, 0)
    for trial in range(n):
        c = classify(trial, options)
        for k in CLASSES:
            total[k] += c[k]
        print(f"trial {trial}: " + ", ".join(f"{k} {c[k]}" for k in CLASSES), flush=True)
    print(f"per trial ({n} trials): " + ", ".join(f"{k} {total[k] / n:.2f}" for k in CLASSES)
          + f"; all {sum(total.values()) / n:.2f}")


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--remeasure"]
    (main_remeasure if "--remeasure" in sys.argv else main)(int(args[0]) if args else 6)
