"""Detection power, measured (issue 17): the B-method's promises checked by simulation, and
the same rows from every way of running the trials."""

import json

import numpy as np
import pandas as pd
import pytest

from baarda.evaluation.study import StudyOptions, run_study, run_trial
from baarda.simulate.aerial import FlightPlan

PLAN = FlightPlan(strips=2, photos_per_strip=4, pattern=5, relief_m=50.0)


@pytest.mark.slow
def test_one_mdb_is_found_with_the_power_beta0():
    """One blunder of exactly 1 MDB per trial, 300 trials: the share whose own w-test is
    significant in the first adjustment has beta0 = 0.80 inside its 95 % interval."""
    s = run_study(StudyOptions(plan=PLAN, trials=300, blunders=1, size_mdb=(1.0, 1.0),
                               strategies=(), seed=0))
    f = s.rates()["first_adjustment"]
    assert f["planted"] == 300
    lo, hi = f["power_ci"]
    assert lo <= 0.80 <= hi, f
    assert abs(f["power"] - 0.80) < 0.06
    # the w-test's sizes: exactly 1 MDB in units of each observation's own MDB
    assert np.allclose(np.abs(s.blunders["size_mdb"]), 1.0)


@pytest.mark.slow
def test_without_blunders_the_w_test_rejects_alpha0():
    """Noise only, 300 trials: the share of tested components with a significant w-test has
    alpha0 = 0.001 inside its 95 % interval."""
    s = run_study(StudyOptions(plan=PLAN, trials=300, blunders=0, strategies=(), seed=1))
    f = s.rates()["first_adjustment"]
    lo, hi = f["false_ci"]
    assert f["unplanted"] > 80_000 and lo <= 0.001 <= hi, f


OPTIONS = StudyOptions(plan=PLAN, trials=6, blunders=2, size_mdb=(1.0, 4.0),
                       strategies=("snoop", "tau", "threshold"), seed=5)


def _rows(study):
    return (study.blunders, study.trials.drop(columns="seconds"))


def test_the_same_rows_in_a_process_pool():
    local = _rows(run_study(OPTIONS))
    pool = _rows(run_study(OPTIONS, workers=2))
    for a, b in zip(local, pool, strict=True):
        pd.testing.assert_frame_equal(a, b)
    assert len(local[0]) == 6 * 2 * 3 and len(local[1]) == 6 * 3


@pytest.mark.slow
def test_the_same_rows_on_a_dask_cluster():
    """A scheduler and two worker processes on localhost, started here."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        remote = _rows(run_study(OPTIONS, scheduler=cluster.scheduler_address))
    local = _rows(run_study(OPTIONS))
    for a, b in zip(local, remote, strict=True):
        pd.testing.assert_frame_equal(a, b)


@pytest.mark.slow
def test_command_line(tmp_path):
    from baarda.cli import main

    out = tmp_path / "out"
    assert main(["evaluate", "-o", str(out), "--strips", "2", "--photos", "4", "--pattern",
                 "5", "--relief", "50", "--trials", "4", "--blunders", "1",
                 "--blunder-size-mdb", "2", "4", "--strategies", "snoop,robust,screen",
                 "-q"]) == 0
    names = {"blunders.csv", "trials.csv", "summary.json", "power.png", "report.html",
             "run.json", "power.csv", "b_method_power.csv"}
    assert names <= {p.name for p in out.iterdir()}
    power = pd.read_csv(out / "power.csv")  # what the report shows, written by evaluate
    b_all = pd.read_csv(out / "blunders.csv")
    for name, part in power.groupby("series"):
        if name in ("snoop", "robust", "screen"):
            sub = b_all[b_all["strategy"] == name]
            assert part["n"].sum() == len(sub) and part["located"].sum() == sub["located"].sum()
    curve = pd.read_csv(out / "b_method_power.csv")
    at1 = np.interp(1.0, curve["size_mdb"], curve["power"])
    assert at1 == pytest.approx(0.80, abs=2e-3)  # beta0 at 1 MDB
    page = (out / "report.html").read_text(encoding="utf-8")
    assert 'id="power-counts"' in page and '<section id="curves">' in page
    doc = json.loads((out / "summary.json").read_text())
    assert set(doc["rates"]["strategies"]) == {"snoop", "robust", "screen"}
    b = pd.read_csv(out / "blunders.csv")
    assert len(b) == 4 * 3 and set(b.columns) >= {"trial", "strategy", "size_mdb", "w_first",
                                                  "located", "rank"}
    assert (np.abs(b["size_mdb"]) >= 2).all() and (np.abs(b["size_mdb"]) <= 4).all()
    assert main(["evaluate", "-o", str(tmp_path / "x"), "--strategies", "guess"]) == 2


def test_the_online_strategy_on_a_trial_that_brings_a_large_new_photo():
    """Trial 1 of a 3 x 8 block, pattern 5, 5 blunders of 1-3 MDB: a photo of more rows
    than a factorisation takes came with new unknowns while rows without any were in the
    low-rank update (OnlineBundle._current read the new unknowns' corrections from it: a
    ValueError; tests/online/test_online_bundle.py has the case alone)."""
    o = StudyOptions(plan=FlightPlan(strips=3, photos_per_strip=8, pattern=5), trials=2,
                     blunders=5, size_mdb=(1.0, 3.0), strategies=("online",), seed=0)
    row, = run_trial(o, 1).trials
    assert row["failed"] == "" and row["n_observations"] == 1160
    assert row["n_planted"] == row["n_located"] == 5 and row["n_false"] == 4
    assert row["sigma0_final"] == pytest.approx(0.97948, abs=1e-5)
