"""The counts of a result (observations, redundancy, vTPv, sigma0) are computed once per
result: the tables of self-calibration asked sigma0 once per camera, and each time summed
the whole observation vector (issue 40: 16 of the 35 s of writing a 1,000-camera BAL
result)."""

import numpy as np

import baarda
from baarda.adjustment import counts
from tests.test_pipeline import synthetic_bal


def test_the_counts_are_computed_once_per_result(tmp_path, monkeypatch):
    res = baarda.adjust(baarda.read(str(synthetic_bal(tmp_path / "problem-6-60.txt.bz2"))))
    lin = res.lin
    assert res.problem.calibration.n and len(res.block.cameras) == 6  # a camera per photo
    calls = []
    count = np.count_nonzero
    monkeypatch.setattr(counts.np, "count_nonzero", lambda a: calls.append(1) or count(a))
    res.camera_table()
    res.calibration_lines()
    res.to_dict()
    assert 0 < len(calls) <= 3, len(calls)  # one count: the image rows, control, extra rows
    vtpv = float(np.sum(lin.w * lin.e**2) + np.sum(lin.wc * lin.ec**2))
    assert res.vtpv == vtpv and res.redundancy == res.n_observations - res.n_unknowns
    assert res.sigma0 == np.sqrt(vtpv / res.redundancy)
