"""The report at scale (issue 16): maps of a sample, tables of the worst, labels only where
shown, a folder with observations.parquet; triggered here on a small block through the
thresholds of ReportOptions."""

import re

import numpy as np
import pandas as pd
import pytest
from htmlrows import table_rows

from baarda.io.result_folder import read_results
from baarda.output.bundle_results import write_results
from baarda.pipeline import snoop
from baarda.report.anaplot import snooping_table
from baarda.report.html_report import html_report, plots
from baarda.report.maps import point_summary, sample_points
from baarda.report.stats import Labels, obs_label
from baarda.report.text_report import ReportOptions, text_report
from baarda.simulate.aerial import FlightPlan, simulate_block


def test_labels_are_obs_label_of_the_rows_asked_for(report_case):
    obs = read_results(report_case.out).obs
    full = obs_label(obs)
    lab = Labels(obs)
    sel = obs["kind"].to_numpy(str) == "control"
    assert list(np.asarray(lab[sel])) == list(full[sel])
    order = np.arange(len(obs))[::-7]
    assert list(np.asarray(lab[order][3:9])) == list(full[order][3:9])
    assert lab[5] == full[5] and len(lab[sel]) == int(sel.sum())


def test_snooping_table_of_a_large_table_same_rows(report_case):
    obs = read_results(report_case.out).obs
    big = pd.concat([obs] * 40, ignore_index=True)  # large enough for the preselection
    for top, min_w in ((5, None), (50, 1.0), (0, None)):
        fast = snooping_table(big, top=top, min_abs_w=min_w)
        t = big.copy()
        t["w"] = t["w"] * 1.0  # the same table, without the preselection:
        ref = snooping_table(t, top=top, min_abs_w=min_w, sort="w") if len(t) <= 4 * (
            top + 1000) else _full(t, top, min_w)
        pd.testing.assert_frame_equal(fast, ref)


def _full(t, top, min_w):
    from baarda.report import anaplot

    keep = anaplot._candidates
    try:
        anaplot._candidates = lambda df, *a: np.arange(len(df))
        return snooping_table(t, top=top, min_abs_w=min_w)
    finally:
        anaplot._candidates = keep


@pytest.mark.slow
def test_sampled_maps_and_tables_of_the_worst(report_case):
    res = read_results(report_case.out)
    pts = point_summary(res)
    opt = ReportOptions(max_points=30, max_rows=4, vector_photos=15)
    drawn, words = sample_points(pts, opt.max_points)
    again, _ = sample_points(pts, opt.max_points)
    assert drawn["point"].tolist() == again["point"].tolist()  # deterministic
    must = (pts["role"] != "tie") | pts["rejected"] | pts["flagged"] | pts["uncontrolled"]
    assert set(pts.loc[must, "point"]) <= set(drawn["point"])
    assert len(drawn) < len(pts) and f"{len(drawn)} of {len(pts)} points drawn" in words
    figs = plots(res, opt)
    for name in ("block_map", "redundancy_map", "reliability_map"):
        assert f"of {len(pts)} points drawn (a deterministic random sample of 30" in \
            figs[name].caption, name
    full = plots(res, ReportOptions(vector_photos=15))
    assert set(figs["block_map"].marked) == set(full["block_map"].marked)  # all rejected
    assert figs["reliability_map"].caption.startswith(
        full["reliability_map"].caption.split(";")[0])  # extremes of every point
    html = html_report(res, opt)
    n_photos = res.obs.loc[res.obs["kind"] == "image", "photo"].nunique()
    assert f"Per photo (4 of {n_photos} photos: those with the largest RMS x+y)" in html
    assert len(table_rows(html, "snooping-table")) <= 4
    assert "such rows shown" in html or len(table_rows(report_case.html, "snooping-table")) <= 4
    text = text_report(res, opt)
    assert f"PER PHOTO (4 of {n_photos} photos" in text
    assert "SMALLEST REDUNDANCY NUMBERS (10)" in text and "LARGEST MDB (PER KIND)" in text
    # below the thresholds nothing is sampled; the snooping table is bounded (issue 42):
    # its default 50 largest |w| and the rejected ones cut to SNOOP_ROWS, the rejected first
    from baarda.report.html_report import SNOOP_ROWS

    assert "points drawn" not in report_case.html
    rows = table_rows(report_case.html, "snooping-table")
    assert len(rows) == SNOOP_ROWS == 40 and "40 of " in report_case.html
    n_rej = int(report_case.obs["rejected"].astype(str).isin(["True", "true", "1"]).sum())
    assert n_rej >= 3 and [c[9] for _, c in rows].count("REJECTED") == n_rej


def test_tables_of_the_weakest_are_the_files_extremes(report_case):
    res = read_results(report_case.out)
    o = res.obs[~res.obs["rejected"] & np.isfinite(res.obs["w"])]
    html = report_case.html
    assert "<h3>smallest redundancy numbers</h3>" in html
    r = re.search(r"<h3>smallest redundancy numbers</h3>(?:<div class=\"wrap\">)?<table[^>]*>"
                  r"<thead>.*?</thead><tbody><tr>(.*?)</tr>", html).group(1)
    cells = re.findall(r"<td[^>]*>(.*?)</td>", r)
    assert float(cells[4]) == round(float(o["redundancy"].min()), 3)


@pytest.mark.slow
def test_report_of_a_parquet_folder(tmp_path):
    block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=5, blunders=2, seed=4))
    qc = snoop(block)
    write_results(tmp_path / "csv", qc)
    write_results(tmp_path / "pq", qc, parquet=True)
    a, b = read_results(tmp_path / "csv"), read_results(tmp_path / "pq")
    ta = text_report(a).replace(str(a.folder), "F").replace(str(a.run), "R")
    tb = text_report(b).replace(str(b.folder), "F").replace(str(b.run), "R")
    assert ta == tb  # the numbers as printed: the same
    assert "points drawn" not in html_report(b)
