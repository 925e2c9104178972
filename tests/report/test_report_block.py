"""The report of a simulated block with injected blunders."""

import re

import numpy as np
import pytest
from htmlrows import table_rows
from result_files import resign

from baarda.cli import main
from baarda.io.result_folder import read_results
from baarda.report.maps import block_map, residual_vectors


def rejected_keys(obs):
    r = obs[obs["rejected"]]
    return {(k, p if isinstance(p, str) else "", q, c) for k, p, q, c in
            zip(r["kind"], r["photo"], r["point"], r["component"], strict=True)}


def labels(keys):
    return {(f"photo {p} " if p else "") + f"point {q} {c}" for _, p, q, c in keys}


@pytest.mark.slow
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
    # the figures and the histogram of MSB/MDB (issue 30)
    assert h.count("<img") == 12 and h.count('src="data:image/png;base64,') == 12
    assert 'id="render-status"' in h
    for sec in ("Project summary", "Global test", "Data snooping log", "Group statistics",
                "Histograms", "Block map", "Image residual vectors", "Redundancy",
                "Snooping table (ANAPLOT)"):
        assert sec in h


@pytest.mark.slow
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
    assert html.read_text(encoding="utf-8").count("<img") == 12
    assert main(["report", out]) == 2  # nothing to do
    assert main(["report", out, "-o", str(report_case.out / "observations.csv")]) == 2
    assert main(["report", out, "--text", "--class-width", "0.3"]) == 2


def test_bad_results_name_file_line_column(report_case, tmp_path, capsys):
    import shutil

    bad = tmp_path / "out"
    shutil.copytree(report_case.out, bad)
    lines = (bad / "observations.csv").read_text().splitlines()
    lines[3] = lines[3].replace(",False,", ",maybe,", 1)
    (bad / "observations.csv").write_text("\n".join(lines) + "\n")
    resign(bad)  # the run's own file, with a bad cell
    assert main(["report", str(bad), "--text"]) == 2
    err = capsys.readouterr().err
    assert "observations.csv, line 4, column 'rejected'" in err


def test_a_folder_without_its_run_manifest_is_refused(report_case, tmp_path):
    """Every run lists its files in run.json; a folder without it is not read (no paths
    for folders of earlier versions: issue 27)."""
    import shutil

    from baarda.errors import ProjectError

    old = tmp_path / "out"
    shutil.copytree(report_case.out, old)
    (old / "run.json").unlink()
    with pytest.raises(ProjectError, match=r"run.json: file not found: not a result folder"):
        read_results(old)


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
    assert h.count("<img") == 8  # histograms, block map, vectors, 5 of geometry; no w, r, MDB
    assert "no redundancy numbers in the results" in h
    assert "no data snooping run" in text_report(res)
    g = {s.name: s for s in group_statistics(res.obs)}
    planted = {f"photo {b['photo']} point {b['point']} {b['component']}"
               for b in report_case.truth["blunders"]}
    assert g["image x+y"].min_at in planted or g["image x+y"].max_at in planted


def test_large_colour_maps_bin_their_tie_points_and_keep_uncontrolled_points_apart():
    """Issue 31, item 7: beyond HEXBIN_FROM tie points a colour map bins them on a hexagonal
    grid (each cell its worst value), control stays on top, uncontrolled points are a layer
    of their own under the colours (rings), not crosses over everything."""
    import matplotlib.pyplot as plt
    import pandas as pd
    from matplotlib.collections import PathCollection, PolyCollection

    from baarda.report.maps import HEXBIN_FROM, _colour_map

    rng = np.random.default_rng(1)
    n = HEXBIN_FROM + 500
    pts = pd.DataFrame({"X": rng.uniform(0, 1000, n), "Y": rng.uniform(0, 800, n),
                        "role": ["control"] * 10 + ["tie"] * (n - 10),
                        "r_min": rng.uniform(0, 1, n), "uncontrolled": np.arange(n) < 40})
    fig, ax = plt.subplots()
    _colour_map(ax, fig, pts, "r_min", "r", "RdYlGn", 0.0, 1.0, worst=np.min)
    hexes = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert len(hexes) == 1 and np.nanmin(hexes[0].get_array()) >= 0
    rings = [c for c in ax.collections if isinstance(c, PathCollection)
             and c.get_label().startswith("uncontrolled")]
    assert len(rings) == 1 and rings[0].get_zorder() < hexes[0].get_zorder()
    assert len(rings[0].get_offsets()) == 40
    plt.close(fig)
