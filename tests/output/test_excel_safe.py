"""Ids a spreadsheet would run as a formula (issue 43): written as given by default (round
trips), quoted as OWASP recommends with --excel-safe (adjust, convert) and in a report's CSV
downloads, and read back as given by baarda's own readers (docs/format.md)."""

import base64
import csv
import io
import re
import shutil
from pathlib import Path

import pandas as pd
import pytest

from baarda.cli import main
from baarda.io.table import Table, unquoted_formulas
from baarda.output.tables import csv_chunks, spreadsheet_cell

DEMO = Path(__file__).parents[2] / "examples" / "demo"
IDS = {"001003": "=HYPERLINK(\"http://x\",\"a\")", "002005": "+49", "003007": "-12",
       "004009": "@SUM(A1)"}


def test_a_cell_is_quoted_as_owasp_recommends():
    assert [spreadsheet_cell(v) for v in ("=1+2", "+1", "-x", "@A", "\tt", "\rr", "ok",
                                           "a,b", 'q"')] == [
        "\"'=1+2\"", "\"'+1\"", "\"'-x\"", "\"'@A\"", "\"'\tt\"", "\"'\rr\"", "ok", '"a,b"',
        '"q"""']
    df = pd.DataFrame({"point": ['=A"1', "p", "-3"], "x": [-1.5, 2.0, float("nan")],
                       "n": [-1, 2, 3]})
    safe = b"".join(csv_chunks(df, excel_safe=True)).decode()
    assert safe == "point,x,n\n\"'=A\"\"1\",-1.5,-1\np,2,2\n\"'-3\",,3\n"
    plain = b"".join(csv_chunks(df)).decode()
    assert plain == "point,x,n\n\"=A\"\"1\",-1.5,-1\np,2,2\n-3,,3\n"  # verbatim
    rows = list(csv.reader(io.StringIO(safe)))  # what a spreadsheet's CSV import sees
    assert [r[0] for r in rows[1:]] == ['\'=A"1', "p", "'-3"]
    assert list(unquoted_formulas(pd.Series([r[0] for r in rows[1:]]).to_numpy(str))) == \
        ['=A"1', "p", "-3"]


def _with_formula_ids(tmp_path: Path) -> Path:
    project = tmp_path / "demo"
    shutil.copytree(DEMO, project)
    for name in ("ground_points.csv", "image_points.csv"):
        p = project / name
        frame = pd.read_csv(p, dtype=str, keep_default_na=False)
        frame["point"] = frame["point"].replace(IDS)
        frame.to_csv(p, index=False)
    return project


def _cells(path: Path, column: str) -> set[str]:
    with open(path, newline="", encoding="utf-8") as f:
        return {row[column] for row in csv.DictReader(f)}


@pytest.mark.slow
def test_adjust_convert_and_report_write_tables_for_spreadsheets(tmp_path, capsys):
    project = _with_formula_ids(tmp_path)
    plain, safe = tmp_path / "plain", tmp_path / "safe"
    assert main(["adjust", str(project), "-o", str(plain), "-q"]) == 0
    assert main(["adjust", str(project), "-o", str(safe), "-q", "--excel-safe"]) == 0
    # by default as given; with --excel-safe each quoted, numbers untouched
    assert set(IDS.values()) <= _cells(plain / "points.csv", "point")
    cells = _cells(safe / "points.csv", "point")
    assert {"'" + v for v in IDS.values()} <= cells and not set(IDS.values()) & cells
    text = (safe / "points.csv").read_text(encoding="utf-8")
    assert "\"'+49\"," in text and not re.search(r"^[=+\-@]", text, flags=re.M)
    assert '"excel_safe": true' in (safe / "run.json").read_text()
    assert (plain / "photos.csv").read_bytes() == (safe / "photos.csv").read_bytes()
    # baarda reads the ids back as given
    assert set(Table(safe / "points.csv", ["point"]).column("point")) == \
        set(Table(plain / "points.csv", ["point"]).column("point"))
    assert main(["check", str(safe), "-q"]) == 0
    # a project converted --excel-safe adjusts to the same tables, byte for byte
    converted = tmp_path / "converted"
    assert main(["convert", str(project), "-o", str(converted), "-q", "--excel-safe"]) == 0
    assert "\"'@SUM(A1)\"" in (converted / "ground_points.csv").read_text(encoding="utf-8")
    again = tmp_path / "again"
    assert main(["adjust", str(converted), "-o", str(again), "-q"]) == 0
    for name in ("points.csv", "observations.csv"):
        assert (again / name).read_bytes() == (plain / name).read_bytes()
    # the report's CSV downloads are for people: quoted, from either folder
    for folder in (plain, safe):
        assert main(["report", str(folder), "-o", str(tmp_path / "r.html"), "-q"]) == 0
        page = (tmp_path / "r.html").read_text(encoding="utf-8")
        downloads = [base64.b64decode(m).decode() for m in
                     re.findall(r"data:text/csv;base64,([A-Za-z0-9+/=]+)", page)]
        assert downloads and any("\"'+49\"" in d for d in downloads)
        assert not any(re.search(r"^[=+\-@]|,[=+@]", d, flags=re.M) for d in downloads)
    capsys.readouterr()
