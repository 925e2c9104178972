"""The report of a simulated block with injected blunders."""

import re

import numpy as np
import pytest
from htmlrows import table_rows

from baarda.cli import main
from baarda.output.result_folder import read_results
from baarda.report.maps import block_map, residual_vectors


def rejected_keys(obs):
    r = obs[obs["rejected"]]
    return {(k, p if isinstance(p, str) else "", q, c) for k, p, q, c in
            zip(r["kind"], r["photo"], r["point"], r["component"], strict=True)}


def labels(keys):
    return {(f"photo {p} " if p else "") + f"point {q} {c}" for _, p, q, c in keys}


def test_snooping_table_marks_exactly_the_rejected(report_case):
    want = rejected_keys(report_case.obs)
    assert len(want) >= 3  # the simulation planted 5 blunders
    planted = {("image", b["photo"], str(b["point"]), b["component"])
               for b in report_case.truth["blunders"]}
    assert want <= planted  # snooping rejected only planted blunders (seed 1)
    rows = table_rows(report_case.html, "snooping-table")
    marked = {tuple(c[:4]) for cls, c in rows if cls == "rejected"}
    assert marked == want
    assert all(c[9] == "REJECTED" for cls, c in rows if cls == "rejected")
    assert not any(c[9] == "REJECTED" for cls, c in rows if cls != "rejected")


def test_snooping_table_shows_the_files_values(report_case):
    o = report_case.obs.set_index(["photo", "point", "component"])
    for _, c in table_rows(report_case.html, "snooping-table"):
        if c[0] != "image":
            continue
        r = o.loc[(c[1], c[2], c[3])]
        assert float(c[4]) == pytest.approx(r["redundancy"], abs=5e-4)
        assert float(c[5]) == pytest.approx(r["residual"], rel=1e-3)
        assert float(c[6]) == pytest.approx(r["sigma_residual"], rel=1e-3)
        assert float(c[7]) == pytest.approx(r["w"], abs=5e-3)


def test_maps_mark_exactly_the_rejected(report_case):
    res = read_results(report_case.out)
    want = labels(rejected_keys(report_case.obs))
    assert set(block_map(res, {}).marked) == want
    v = residual_vectors(res, limit=15)
    assert set(v.marked) == {s for s in want if s.startswith("photo")}
    for s in want:
        assert s in report_case.html  # named in the figure captions


def test_group_statistics_in_html_match_the_file(report_case):
    o = report_case.obs
    act = o[(o["kind"] == "image") & ~o["rejected"]]
    rows = {c[0]: c for _, c in table_rows(report_case.html, "groups")}
    for name, sel in (("image x", act["component"] == "x"), ("image y", act["component"] == "y"),
                      ("image x+y", slice(None))):
        v = act.loc[sel, "residual"].to_numpy()
        c = rows[name]
        assert int(c[2]) == len(v)
        assert float(c[4]) == pytest.approx(np.sqrt(np.mean(v**2)), abs=0.006)
        assert float(c[5]) == pytest.approx(v.min(), abs=0.006)
        assert float(c[7]) == pytest.approx(v.max(), abs=0.006)
    n_rej = int((o["rejected"] & (o["component"] == "y")).sum())
    assert int(rows["image y"][9]) == n_rej


def test_html_is_self_contained(report_case):
    h = report_case.html
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", h)
    assert "<link" not in h and "@import" not in h
    # six figures and the histogram of MSB/MDB (issue 30)
    assert h.count("<img") == 7 and h.count('src="data:image/png;base64,') == 7
    assert 'id="render-status"' in h
    for sec in ("Project summary", "Global test", "Data snooping log", "Group statistics",
                "Histograms", "Block map", "Image residual vectors", "Redundancy",
                "Snooping table (ANAPLOT)"):
        assert sec in h


def test_cli_text_and_html(report_case, tmp_path, capsys):
    out = str(report_case.out)
    assert main(["report", out, "--text", "--top", "5"]) == 0
    text = capsys.readouterr().out
    for s in ("GLOBAL TEST".lower(), "snooping log", "group statistics", "per strip",
              "image x residuals", "standardized residuals w", "snooping table"):
        assert s in text.lower()
    table = text[text.index("SNOOPING TABLE"):]
    for lab in labels(rejected_keys(report_case.obs)):
        parts = lab.split()
        assert re.search(rf"^image\s+{parts[1]}\s+{parts[3]}\s+{parts[4]}\s.*REJECTED$",
                         table, re.M), lab
    html = tmp_path / "r.html"
    assert main(["report", out, "-o", str(html), "-q"]) == 0
    assert html.read_text(encoding="utf-8").count("<img") == 7
    assert main(["report", out]) == 2  # nothing to do
    assert main(["report", out, "-o", str(report_case.out / "observations.csv")]) == 2
    assert main(["report", out, "--text", "--class-width", "0.3"]) == 2


def test_bad_results_name_file_line_column(report_case, tmp_path, capsys):
    import shutil

    bad = tmp_path / "out"
    shutil.copytree(report_case.out, bad)
    (bad / "run.json").unlink()  # a folder of an earlier version: its files are parsed
    lines = (bad / "observations.csv").read_text().splitlines()
    lines[3] = lines[3].replace(",False,", ",maybe,", 1)
    (bad / "observations.csv").write_text("\n".join(lines) + "\n")
    assert main(["report", str(bad), "--text"]) == 2
    err = capsys.readouterr().err
    assert "observations.csv, line 4, column 'rejected'" in err


def test_older_output_folder_still_reports(report_case, tmp_path):
    """Without the report's fields (x_mm, y_mm, cameras): cameras from the project named in
    'source', image-space plots left out with a note."""
    import json
    import shutil

    from baarda.report.html_report import html_report

    old = tmp_path / "out"
    shutil.copytree(report_case.out, old)
    (old / "run.json").unlink()  # written before run manifests existed
    s = json.loads((old / "summary.json").read_text())
    del s["cameras"], s["angle_unit"]
    s["source"] = str(report_case.project)
    (old / "summary.json").write_text(json.dumps(s))
    o = report_case.obs.drop(columns=["x_mm", "y_mm"])
    o.to_csv(old / "observations.csv", index=False)
    res = read_results(old)
    assert res.cameras and res.angle_unit == "gon"  # from the project folder
    assert any("no image coordinates" in n for n in res.notes)
    h = html_report(res)
    assert h.count("<img") == 6 and "no image coordinates in the results" in h
    s["source"] = str(tmp_path / "nowhere")
    (old / "summary.json").write_text(json.dumps(s))
    res = read_results(old)
    assert not res.cameras and any("footprints not drawn" in n for n in res.notes)


def test_missing_files(tmp_path):
    from baarda.errors import ProjectError

    with pytest.raises(ProjectError, match="not an output folder"):
        read_results(tmp_path / "none")
    with pytest.raises(ProjectError, match=r"summary.json: file not found"):
        read_results(tmp_path)
    (tmp_path / "summary.json").write_text("{bad")
    with pytest.raises(ProjectError, match=r"summary.json, line 1: not valid JSON"):
        read_results(tmp_path)


def test_results_without_statistics(report_case, tmp_path):
    """An adjustment written without quality control: residuals only; the extremes of the
    group statistics point at the planted blunders (Salsig's point)."""
    from baarda.io.project import read_project
    from baarda.output.bundle_results import write_results
    from baarda.pipeline import adjust
    from baarda.report.html_report import html_report
    from baarda.report.stats import group_statistics
    from baarda.report.text_report import text_report

    write_results(tmp_path / "out", adjust(read_project(report_case.project)))
    res = read_results(tmp_path / "out")
    h = html_report(res)
    assert h.count("<img") == 3  # histograms, block map, vectors; no w, no r/MDB maps
    assert "no redundancy numbers in the results" in h
    assert "no data snooping run" in text_report(res)
    g = {s.name: s for s in group_statistics(res.obs)}
    planted = {f"photo {b['photo']} point {b['point']} {b['component']}"
               for b in report_case.truth["blunders"]}
    assert g["image x+y"].min_at in planted or g["image x+y"].max_at in planted
