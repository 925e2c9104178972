"""A table is data (baarda/table_data.py) and its three renderers show the same cells: the
number format is the table's, by the row's unit where it depends on it."""

import math

from baarda.report.html_base import html_table
from baarda.report.quality_pdf import _styles, pdf_table
from baarda.report.stats import GroupStats, format_groups, group_table
from baarda.table_data import Column, TableData, cell, text_lines


def test_cell_rules():
    assert cell(-0.0004, ".3f") == "0.000"  # no negative zero
    assert cell(1.23456, "+.2f") == "+1.23"
    assert cell(math.nan, ".3f") == "-"
    assert cell(math.inf, "inf") == "∞"
    assert cell(True) == "yes" and cell(False) == ""
    assert cell(7) == "7" and cell(None) == ""


def test_the_format_follows_the_unit_of_the_row():
    g = [GroupStats("control X", "m", 4, 0.01234, 0.02, -0.03, "a", 0.04, "b"),
         GroupStats("image x", "µm", 9, 1.2345, 2.0, -3.0, "c", 4.0, "d", 1)]
    t = group_table(g)
    assert [r[3] for r in t.cells()] == ["0.012", "1.23"]
    lines = format_groups(g).split("\n")
    assert lines[1][14:19] == "    m" and lines[1][27:37] == "     0.012"
    html = html_table(t)
    assert "<td>0.012</td>" in html and "<td>1.23</td>" in html
    pdf = pdf_table(t, _styles())[0]
    assert pdf._cellvalues[1][3] == "0.012" and pdf._cellvalues[2][3] == "1.23"
    assert pdf._cellvalues[0][6] == "at (min)" and lines[0][59:61] == "at"


def test_text_layout_labels_and_empty_cells():
    t = TableData.of([Column("k", text=True, width=4), Column("w", fmt=".2f", width=6,
                                                               gap=1, label="w ")],
                     [{"k": "a", "w": 1.5}, {"k": "b", "w": None}])
    assert text_lines(t, header=False) == ["a    w   1.50", "b"]
