"""Identification measured (issue 30): a small version of the study in docs/evaluation.md,
"Identification, not only detection" (the 200-trial numbers there come from `baarda
evaluate` with the same options and --trials 200)."""

import json

import pytest

from baarda.evaluation.study import StudyOptions, run_study
from baarda.output.evaluation_files import study_document
from baarda.simulate.aerial import FlightPlan

PLAN = FlightPlan(strips=3, photos_per_strip=8, pattern=5)


@pytest.mark.slow
def test_grouped_rejection_locates_separable_blunders_and_identifies_the_others():
    s = run_study(StudyOptions(plan=PLAN, trials=40, blunders=1, size_mdb=(1.5, 1.5),
                               strategies=("snoop", "grouped"), seed=0))
    r = s.rates()["strategies"]
    g = r["grouped"]
    assert g["separable_located"]["n"] > 15 and g["inseparable_identified"]["n"] > 10
    assert g["separable_located"]["rate"] >= 0.97
    assert g["inseparable_identified"]["rate"] >= 0.95
    assert g["false_per_trial"] <= 1.5
    # snooping by Baarda's rule flips a coin between inseparable twins; grouping does not
    assert g["inseparable_located"]["rate"] > r["snoop"]["inseparable_located"]["rate"]
    assert r["snoop"]["inseparable_identified"]["rate"] >= 0.95
    doc = study_document(s)
    json.dumps(doc)  # the intervals go into summary.json
    assert len(doc["rates"]["strategies"]["grouped"]["inseparable_identified"]["ci"]) == 2
    assert any(line.startswith("spill-over: ") for line in doc["summary"])


@pytest.mark.slow
def test_noise_only_blocks_have_false_alarms_at_the_block_level():
    s = run_study(StudyOptions(plan=PLAN, trials=40, blunders=0, strategies=("snoop",),
                               seed=1))
    f = s.rates()["first_adjustment"]
    b = f["blocks_with_false_alarm"]
    assert b["n"] == 40 and 0.25 <= b["rate"] <= 0.75  # about half of correct blocks
    assert b["independent_tests"] == pytest.approx(0.62, abs=0.03)
    assert f["meaning"] == "false alarms"
