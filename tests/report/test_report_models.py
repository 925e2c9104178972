"""`baarda report` on the output of `baarda models`: the one observation schema."""

import json

import numpy as np
import pandas as pd
import pytest

from baarda.cli import main
from baarda.io.result_folder import read_results
from baarda.report.html_report import html_report
from baarda.report.stats import model_groups


def test_report_of_an_independent_model_block(tmp_path, capsys):
    assert main(["simulate-models", "-o", str(tmp_path / "p"), "--strips", "2", "--models",
                 "3", "--blunders", "2", "--seed", "4"]) == 0
    assert main(["models", str(tmp_path / "p"), "-o", str(tmp_path / "o"), "-q"]) == 0
    capsys.readouterr()
    assert main(["report", str(tmp_path / "o"), "--text"]) == 0
    text = capsys.readouterr().out
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    obs = pd.read_csv(tmp_path / "o" / "observations.csv", keep_default_na=False)
    assert s["method"] == "independent models (3d)" and list(s["adjustments"]) == ["3d"]
    assert set(obs["kind"]) == {"model", "control"} and (obs["photo"] == "").all()
    # the summary the adjustment wrote is the report's summary, line by line
    for sec in s["sections"]:
        assert sec["title"] in text and all(line in text for line in sec["lines"])
    assert "PER MODEL" in text and "model x" in text
    res = read_results(tmp_path / "o")
    t = model_groups(res.obs)
    assert list(t["model"]) == sorted(set(obs.loc[obs["kind"] == "model", "model"]))
    mx = res.obs[(res.obs["kind"] == "model") & (res.obs["component"] == "x")
                 & ~res.obs["rejected"] & (res.obs["model"] == t["model"][0])]
    assert t["rms_x"][0] == pytest.approx(np.sqrt(np.mean(mx["residual"] ** 2)), rel=1e-12)
    h = html_report(res)
    assert "Per model" in h and 'id="snooping-table"' in h
    assert res.global_test_passed == s["global_test"]["passed"]
    assert s["rejection_log"] == s["adjustments"]["3d"]["rejection_log"]
    assert len(s["rejection_log"]) == s["n_rejected"] >= 1  # the planted blunders
