"""Where the on-line replay's good rejections come from (issue 33's replay study,
docs/online.md): the trials of the study run again with the replay alone, each good
component it rejected put in one class.

    PYTHONPATH=$PWD python benchmarks/online_false_alarms.py [TRIALS]

TRIALS: how many of the study's trials (default 6; seed 33, 20 x 30 photos, 30 blunders of
1-3 MDB, as `baarda evaluate --strategies online,snoop --seed 33` runs them).  Classes:
  set aside   - a good member of a group of components the test could not tell apart, its
                point set aside and never taken in again;
  other coord - the other coordinate of a blundered image point, rejected with it;
  at entry    - rejected at the step it was taken in;
  later       - rejected when a verdict changed as the block grew.
"""

from __future__ import annotations

import sys

from baarda.evaluation.strategies import component_keys
from baarda.evaluation.study import StudyOptions, planted_block
from baarda.online.replay import replay
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
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 6)
