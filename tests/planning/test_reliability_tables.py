"""Reliability tables: lookup with fallbacks, design keys, reading with clear errors."""

import numpy as np
import pytest

from baarda.errors import ProjectError
from baarda.output.plan_files import write_reliability_table
from baarda.planning.design import ControlLayout, design_block
from baarda.planning.gruen_study import study_plan
from baarda.planning.reliability_tables import (
    DesignKey,
    baarda_table,
    design_key,
    gruen_table,
    read_table,
)


def test_gruen_recommended_values():
    t = gruen_table()
    cls = np.array(["R2", "R2", "RO3", "RI3", "RO4/9", "RI4/9", "CRO4/9", "CRI4/9"], object)
    comp = np.array(["x", "y", "y", "x", "y", "x", "y", "x"], object)
    single3 = t.lookup(cls, comp, DesignKey("3x3", control="single"))
    assert single3.tolist() == [0.0, 0.39, 0.49, 0.80, 0.65, 0.88, 0.68, 0.89]
    twin5 = t.lookup(cls, comp, DesignKey("5x5", control="twin"))
    assert twin5.tolist() == [0.0, 0.64, 0.72, 0.81, 0.78, 0.88, 0.82, 0.92]


def test_fallbacks_and_nearest_design():
    t = gruen_table()
    # control classes Gruen has no value for fall back to the non-control class
    v = t.lookup(np.array(["CR2", "CRO3", "R1"], object), np.array(["y", "x", "x"], object),
                 DesignKey("3x3"))
    assert v[0] == 0.39 and v[1] == 0.34 and np.isnan(v[2])
    # a pattern not in the table takes the nearest one (6x6 -> 5x5)
    assert t.lookup(np.array(["RO4/9"], object), np.array(["x"], object),
                    DesignKey("6x6"))[0] == 0.78


def test_baarda_table_has_x_and_y():
    t = baarda_table()
    v = t.lookup(np.array(["RO3", "RO3"], object), np.array(["x", "y"], object),
                 DesignKey("3x3"))
    assert 0.30 < v[0] < 0.38 and 0.45 < v[1] < 0.55


def test_design_key_of_blocks():
    k = design_key(design_block(study_plan(4, 5), ControlLayout(spacing=1.0, twin=True)))
    assert (k.pattern, k.stereo, k.control) == ("5x5", True, "twin")
    k = design_key(design_block(study_plan(4, 3, stereo=False), ControlLayout(spacing=1.0)))
    assert (k.pattern, k.stereo, k.control) == ("3x3", False, "single")


def test_read_table_errors(tmp_path):
    t = baarda_table()
    p = tmp_path / "t.csv"
    write_reliability_table(p, t, header="test")
    back = read_table(p)
    assert np.allclose(back.frame["value"], t.frame["value"], atol=1e-4)
    text = p.read_text().replace(",0.0000,", ",1.7,", 1)
    p.write_text(text)
    with pytest.raises(ProjectError, match=r"t\.csv, line \d+, column 'value'"):
        read_table(p)
    q = tmp_path / "bad.csv"
    q.write_text("class,value\nR2,0.4\n")
    with pytest.raises(ProjectError, match="lacks column"):
        read_table(q)
