"""The result folder of a detection-power study (`baarda evaluate`): blunders.csv,
trials.csv, power.csv (the located share per size class, what the report draws),
b_method_power.csv and summary.json (docs/evaluation.md)."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

from baarda.evaluation.power import b_method_table, power_table
from baarda.evaluation.study import Study
from baarda.output.atomic import write_text
from baarda.output.run_folder import RunFolder, staged


def study_document(study: Study, run: str = "") -> dict:
    """summary.json of a study: its options, the rates with their intervals, the time."""
    o = study.options
    plan = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(o.plan).items()}
    return {"run": run, "method": "evaluation", "trials": o.trials, "blunders": o.blunders,
            "size_mdb": list(o.size_mdb), "kinds": list(o.kinds),
            "strategies": list(o.strategies), "seed": o.seed, "alpha0": o.tests.alpha0,
            "beta0": o.tests.beta0, "plan": plan, "seconds": study.seconds,
            "rates": study.rates(), "summary": study.summary().splitlines()}


def write_study(out: str | Path | RunFolder, study: Study) -> list[Path]:
    """Write blunders.csv, trials.csv, power.csv, b_method_power.csv and summary.json into
    one run; returns the paths."""
    with staged(out) as run:
        paths = [run.file(n) for n in ("blunders.csv", "trials.csv", "power.csv",
                                       "b_method_power.csv", "summary.json")]
        write_text(paths[0], study.blunders.to_csv(index=False))
        write_text(paths[1], study.trials.to_csv(index=False))
        write_text(paths[2], power_table(study).to_csv(index=False))
        write_text(paths[3], b_method_table(study).to_csv(index=False))
        write_text(paths[4], json.dumps(study_document(study, run.run_id), indent=1,
                                        default=float) + "\n")
    return paths
