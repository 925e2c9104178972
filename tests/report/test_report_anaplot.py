"""The ANAPLOT snooping table and the snooping log."""

import numpy as np
import pandas as pd
import pytest

from baarda.report.anaplot import flag_of, format_log, format_snooping, snooping_table


def obs() -> pd.DataFrame:
    return pd.DataFrame({
        "kind": ["image"] * 5 + ["control"],
        "photo": ["a", "a", "b", "b", "c", ""],
        "point": ["1", "1", "2", "2", "3", "9"],
        "component": ["x", "y", "x", "y", "x", "Z"],
        "residual": [1.0, -30.0, 2.0, 0.5, 0.0, 0.2],
        "sigma_residual": [2.0, 4.0, 2.0, 1.0, 0.0, 0.05],
        "redundancy": [0.2, 0.5, 0.3, 0.1, 0.0, 0.4],
        "w": [-0.5, 7.5, -1.0, -0.5, np.nan, -4.0],
        "rejected": [False, True, False, False, False, False],
        "flagged": [False, False, False, False, False, True],
    })


def test_flags():
    assert list(flag_of(obs())) == ["", "REJECTED", "", "", "uncontrolled", "FLAGGED"]


def test_sorted_by_significance_and_filtered():
    t = snooping_table(obs())
    assert list(t["w"].abs().fillna(-1)) == [7.5, 4.0, 1.0, 0.5, 0.5, -1]
    assert list(t["unit"][:2]) == ["µm", "m"]
    t = snooping_table(obs(), top=1)  # rejected and flagged are always kept
    assert list(t["flag"]) == ["REJECTED", "FLAGGED"]
    t = snooping_table(obs(), min_abs_w=0.9, always="")
    assert list(t["w"]) == [7.5, -4.0, -1.0]
    t = snooping_table(obs(), sort="input", top=2, always="")
    assert list(t["point"]) == ["1", "1"]
    with pytest.raises(ValueError):
        snooping_table(obs(), sort="size")


def test_text_columns_are_the_files_values():
    text = format_snooping(snooping_table(obs()), k_w=3.29)
    lines = text.splitlines()
    assert "RED-N" in lines[1] and "PARX" in lines[1] and "EXPD" in lines[1] \
        and "SIGF" in lines[1]
    row = next(s for s in lines if "REJECTED" in s).split()
    assert row[:4] == ["image", "a", "1", "y"]
    assert [float(x) for x in row[4:8]] == [0.5, -30.0, 4.0, 7.5]
    ctl = next(s for s in lines if "FLAGGED" in s).split()
    assert [float(x) for x in ctl[3:7]] == [0.4, 0.2, 0.05, -4.0]


def test_log_units():
    s = {"rejection_log": [
        {"iteration": 1, "sigma0": 1.5, "action": "reject", "statistic": "w", "value": 7.0,
         "mdb": 29.0, "mdb_unit": "µm", "observations": ["image photo a point 1 y"]},
        {"iteration": 2, "sigma0": 1.1, "action": "reject", "statistic": "w", "value": -5.0,
         "mdb": 0.25, "mdb_unit": "m", "observations": ["control point 9 Z"]}],
        "snooping_converged": True}
    text = format_log(s)
    assert "29.0 µm" in text and "0.250 m" in text
    assert "no data snooping" in format_log({})
    assert "no observation rejected" in format_log({"rejection_log": [],
                                                    "snooping_converged": True})
