"""`baarda evaluate --strategies online`: the replay with re-measurement as a strategy of a
study, next to snooping on the same blundered blocks."""

import numpy as np

from baarda.evaluation.study import StudyOptions, run_study
from baarda.simulate.aerial import FlightPlan


def test_online_strategy_in_a_study():
    opts = StudyOptions(plan=FlightPlan(strips=2, photos_per_strip=6, pattern=4, seed=0),
                        trials=2, blunders=3, size_mdb=(2.0, 3.0),
                        strategies=("online", "snoop"), seed=5)
    study = run_study(opts)
    b = study.blunders
    on, sn = b[b["strategy"] == "online"], b[b["strategy"] == "snoop"]
    assert len(on) == len(sn) == 6
    assert set(on["at_entry"]) <= {"reject", "accept", "suspect", "held"}
    assert sn["at_entry"].isna().all()
    # the same blunders: planted once, run through both strategies
    keys = ["trial", "photo", "point", "component", "size"]
    assert on[keys].to_numpy().tolist() == sn[keys].to_numpy().tolist()
    r = study.rates()["strategies"]
    assert r["online"]["rejected_at_entry"] == int((on["at_entry"] == "reject").sum())
    lo, hi = r["online"]["at_entry_ci"]
    assert lo <= r["online"]["at_entry_rate"] <= hi
    assert "rejected_at_entry" not in r["snoop"]
    assert "rejected when taken in" in study.summary()
    t = study.trials
    assert np.isfinite(t.loc[t["strategy"] == "online", "sigma0_final"]).all()


def test_online_remeasure_strategy_loses_nothing():
    """`online-remeasure`: the operator measures a rejected image point again and gets its
    value without the blunder; the blunders it flags are those it measured again, and the
    block at the end keeps every observation of the blundered block but the ones rejected
    again (none here)."""
    opts = StudyOptions(plan=FlightPlan(strips=2, photos_per_strip=6, pattern=4, seed=0),
                        trials=2, blunders=3, size_mdb=(2.0, 3.0),
                        strategies=("online-remeasure", "online"), seed=5)
    study = run_study(opts)
    b, t = study.blunders, study.trials
    re, on = b[b["strategy"] == "online-remeasure"], b[b["strategy"] == "online"]
    assert re["located"].sum() >= on["located"].sum() - 1
    assert re["located"].mean() >= 0.8
    s_re = t.loc[t["strategy"] == "online-remeasure", "sigma0_final"].to_numpy()
    assert np.isfinite(s_re).all() and (np.abs(s_re - 1.0) < 0.25).all()


def test_strict_and_group_counts_are_told_apart():
    """Issue 44: a blunder is located strictly only when its own test rejected it; one in a
    group rejected or set aside as a whole (grouped's partners, the on-line points set aside
    and never taken in again) is located up to the group, and every good member of the
    group is a good component lost.  On the small study of test_online_strategy_in_a_study
    (2 trials, 6 blunders): snooping strict = located; grouped and on-line credit groups
    (located 4 and 5 of 6, strictly 2 and 1); the strict set of the on-line strategy is
    what its replay took out or measured again by its own rejection (recomputed here)."""
    from baarda.evaluation.study import planted_block
    from baarda.online.replay import replay

    opts = StudyOptions(plan=FlightPlan(strips=2, photos_per_strip=6, pattern=4, seed=0),
                        trials=2, blunders=3, size_mdb=(1.0, 3.0),
                        strategies=("snoop", "grouped", "online"), seed=5)
    study = run_study(opts)
    b = study.blunders
    n = {s: tuple(int(g[c].sum()) for c in ("strict", "located", "identified"))
         for s, g in b.groupby("strategy")}
    assert n == {"snoop": (2, 2, 6), "grouped": (2, 4, 6), "online": (1, 5, 5)}
    assert (b["strict"] <= b["located"]).all() and (b["located"] <= b["identified"]).all()
    r = study.rates()["strategies"]
    assert r["online"]["strict"]["k"] == 1 and r["online"]["located"] == 5
    assert "online     located strictly 1/6 = 0.167" in study.summary()
    # independently: the on-line strict set is the replay's removals, its aside groups not
    on = b[b["strategy"] == "online"]
    for t in range(2):
        rp = replay(planted_block(opts, t).blundered, opts.tests, remove="worst")
        out = {(k, p, q, c) for _, k, p, q, c, _ in rp.removed}
        aside = {k for _, keys in rp.aside for k in keys}
        for _, row in on[on["trial"] == t].iterrows():
            key = (row["kind"], row["photo"], row["point"], row["component"])
            assert row["strict"] == (key in out)
            assert row["located"] == (key in out or key in aside)
