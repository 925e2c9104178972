"""Result tables keep every number as computed (issue 26): each float cell reads back to the
same double, text is quoted as the csv module quotes it, and the Parquet observation table
holds the same numbers."""

import csv
import io
import json

import numpy as np
import pandas as pd
import pytest

from baarda.io.observations_file import read_observations
from baarda.io.result_folder import read_results
from baarda.output import tables
from baarda.output.bundle_results import write_results
from baarda.output.tables import csv_chunks, csv_text, write_csv
from baarda.pipeline import snoop
from baarda.simulate.aerial import FlightPlan, simulate_block

EDGES = [0.0, -0.0, np.inf, -np.inf, np.nan, 1e-300, -5e-324, 1.7976931348623157e308,
         1234567890.5, 1234567891.5, 9999999999.5, 0.99999999995, 0.999999999949999,
         1e-5, 1e-4, 9.9999999995e-5, 0.0001, 123456789012.0, 1e10, 1e9, 9999999999.0,
         99999999995.0, 1e-13, 1e-14, 1e31, 1e32, 0.1, 0.5, 1.5, 2.5, 1e22, 1e23, 1e-22,
         123.456, -0.000123456789, 4.043202913e-06, 6461234.5678901234, 5812345.000001]


def text(df, chunk_rows=tables.CHUNK_ROWS):
    return b"".join(csv_chunks(df, chunk_rows)).decode("utf-8")


def values(n: int, seed: int = 1) -> np.ndarray:
    """Values of every size, near-ties of decimal rounding, and projected coordinates."""
    rng = np.random.default_rng(seed)
    wide = rng.standard_normal(n) * 10.0 ** rng.integers(-25, 30, n)
    ties = (rng.integers(10**9, 10**10, n) + 0.5) * 10.0 ** rng.integers(-15, 10, n)
    near = np.nextafter(ties, np.where(rng.random(n) < 0.5, -np.inf, np.inf))
    lambert = 6.4e6 + rng.random(n) * 1e5  # Lambert-93 Y: 10 digits kept 1-10 mm only
    return np.concatenate([wide, ties, near, lambert, rng.random(n), EDGES])


def test_every_float_reads_back_to_the_same_double():
    v = values(20_000)
    df = pd.DataFrame({"a": v, "b": -v[::-1]})
    back = pd.read_csv(io.StringIO(text(df, chunk_rows=777)))
    for c in df.columns:
        x, y = df[c].to_numpy(), back[c].to_numpy()
        assert np.array_equal(x, y, equal_nan=True), c
        ok = ~np.isnan(x)
        assert np.array_equal(np.signbit(x[ok]), np.signbit(y[ok])), c  # -0 stays -0
    cells = [c.split(",")[0] for c in text(pd.DataFrame({"a": v, "b": 0.0})).splitlines()[1:]]
    finite = np.isfinite(v)
    # the shortest text that reads back: as many significant digits as Python's repr
    assert [digits(c) for c, ok in zip(cells, finite, strict=True) if ok] == \
        [digits(repr(float(x))) for x in v[finite]]
    assert {"0.1", "6461234.567890123", "5812345.000001"} <= set(cells)
    assert "nan" not in cells and "" in cells


def digits(number: str) -> str:
    """The significant digits of a number's text."""
    mantissa = number.lower().lstrip("-").split("e")[0].replace(".", "")
    return mantissa.strip("0") or "0"


def test_text_bool_int_columns_as_the_csv_module_writes_them():
    n = 5003
    i = np.arange(n)
    ids = [f"p{k}" if k % 97 else 'a,"b"' for k in i]
    missing = [None if k % 7 == 0 else "é" for k in i]
    obj = ["x\ny" if k % 11 == 0 else ("01001" if k % 13 == 0 else "") for k in i]
    df = pd.DataFrame({"id": pd.array(ids, dtype="str"), "missing": pd.array(missing,
                       dtype="str"), "obj": np.array(obj, dtype=object), "flag": i % 3 == 0,
                       "count": i - 50, "u": (i % 5).astype(np.uint8),
                       "nullable": pd.array([None if k % 5 == 0 else k for k in i],
                                            dtype="Int64"),
                       "mixed": np.array([1, "x", 2.5, None] * (n // 4) + [1] * (n % 4),
                                         dtype=object)})
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(df.columns)
    for k in range(n):
        w.writerow([ids[k], missing[k] or "", obj[k], str(bool(k % 3 == 0)), k - 50, k % 5,
                    "" if k % 5 == 0 else k, ["1", "x", "2.5", ""][k % 4] if k < n - n % 4
                    else "1"])
    assert text(df, chunk_rows=777) == buf.getvalue()
    assert text(df) == text(df, chunk_rows=777)


def test_long_tables_formatted_in_threads_give_the_same_bytes(monkeypatch):
    df = pd.DataFrame({"a": values(500), "b": "photo", "c": True})
    one = text(df)
    monkeypatch.setattr(tables, "THREAD_ROWS", 1)
    assert text(df, chunk_rows=100) == one


def test_small_tables_and_presentation_formats(tmp_path):
    assert csv_text(pd.DataFrame({"a": [np.nan, 1.0]})) == 'a\n""\n1\n'  # not a blank line
    assert csv_text(pd.DataFrame({"a": [], "b": []})) == "a,b\n"
    df = pd.DataFrame({"a": [1 / 3, 2.0], "b": ["x", "y"]})
    assert csv_text(df, "%.4f") == "a,b\n0.3333,x\n2.0000,y\n"  # plans: pandas' format
    write_csv(tmp_path / "t.csv", df)
    assert (tmp_path / "t.csv").read_text() == "a,b\n0.3333333333333333,x\n2,y\n"


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A snooped block written as CSV and as Parquet."""
    root = tmp_path_factory.mktemp("tables")
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=6, blunders=4,
                                         check_points=2, relief_m=30.0, seed=3))
    qc = snoop(block)
    write_results(root / "csv", qc)
    write_results(root / "parquet", qc, parquet=True)
    return root, qc


def test_result_tables_read_back_equal_the_api(folders):
    root, qc = folders
    stored = pd.read_csv(root / "csv" / "observations.csv",
                         keep_default_na=False, na_values=[""], dtype={"point": str})
    table = qc.table()
    for c in table.columns:
        if table[c].dtype == float:
            assert np.array_equal(stored[c].to_numpy(), table[c].to_numpy(),
                                  equal_nan=True), c
    res = qc.adjustment
    photos = pd.read_csv(root / "csv" / "photos.csv")
    assert np.array_equal(photos[["X0", "Y0", "Z0"]].to_numpy(), res.eo[:, :3])


def test_parquet_holds_the_numbers_of_the_csv(folders):
    root, qc = folders
    pq = root / "parquet"
    assert not (pq / "observations.csv").exists()
    stored = pd.read_parquet(pq / "observations.parquet")
    pd.testing.assert_frame_equal(stored, qc.table())  # the numbers as computed
    manifest = json.loads((pq / "run.json").read_text())
    assert "observations.parquet" in manifest["files"]
    a = read_results(pq).obs
    b = read_observations(root / "csv" / "observations.csv")
    assert list(a.columns) == list(b.columns)
    for c in a.columns:
        if a[c].dtype == float:
            assert np.array_equal(a[c].to_numpy(), b[c].to_numpy(), equal_nan=True), c
        else:
            assert (a[c].astype(str).to_numpy() == b[c].astype(str).to_numpy()).all(), c


def test_parquet_folder_checked_against_its_manifest(folders, tmp_path):
    import shutil

    from baarda.errors import ProjectError

    root, _ = folders
    shutil.copytree(root / "parquet", tmp_path / "p")
    f = tmp_path / "p" / "observations.parquet"
    f.write_bytes(f.read_bytes() + b"\0")
    with pytest.raises(ProjectError, match="observations.parquet.*not the file"):
        read_results(tmp_path / "p")


def test_cli_adjust_parquet_and_report(tmp_path, capsys):
    from baarda.cli import main

    assert main(["adjust", "examples/demo", "-o", str(tmp_path / "out"), "--parquet",
                 "-q"]) == 0
    names = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert "observations.parquet" in names and "observations.csv" not in names
    capsys.readouterr()
    assert main(["report", str(tmp_path / "out"), "--text"]) == 0
    assert "SNOOPING TABLE" in capsys.readouterr().out


def test_the_text_of_a_long_table_is_formatted_chunk_by_chunk():
    """Issue 40 (memory): the cells are formatted per chunk of rows, so pyarrow holds about
    one chunk's text while a long table is written, never the whole table's (which it held
    before: the observation table's write phase peaked 170 MB above the statistics for
    BAL-scale 100 cameras)."""
    import pyarrow as pa

    df = pd.DataFrame({c: values(120_000) for c in "abcd"})
    size, held, base = 0, 0, pa.total_allocated_bytes()  # what other tests left
    for chunk in csv_chunks(df, chunk_rows=10_000):
        size += len(chunk)
        held = max(held, pa.total_allocated_bytes() - base)
    assert size > 8_000_000 and held < size / 4, (size, held)


def test_a_table_given_as_columns_is_written_as_its_dataframe(monkeypatch):
    """Issue 40 (memory): observations.csv is written from the result's arrays (a mapping of
    columns, `tables.Columns`) without building a DataFrame; every cell is the text the same
    table as a DataFrame gives: floats, NaN, bools, integers, text quoted or empty, one value
    for every row, on chunk boundaries and in threads, and spreadsheet-safe."""
    n = 2_345
    i = np.arange(n)
    cols = {"adjustment": "bundle", "v": values(n)[:n], "flag": i % 3 == 0, "count": i - 50,
            "point": np.array([f"p{k}" if k % 97 else 'a,"b"' for k in i], dtype=object),
            "empty": np.full(n, "", dtype=object),
            "missing": np.array([None if k % 7 == 0 else ("=1+1" if k % 5 == 0 else "é")
                                 for k in i], dtype=object),
            "fixed": np.array(["x\ny" if k % 11 == 0 else "01001" for k in i]),
            "mixed": np.array([1, "x", None, True] * (n // 4) + [1] * (n % 4), dtype=object),
            "nan": np.full(n, np.nan)}
    df = pd.DataFrame(cols)
    frame_text = text(df, chunk_rows=500)
    assert text(cols, chunk_rows=500) == frame_text
    assert text(cols) == frame_text
    assert b"".join(csv_chunks(cols, 300, excel_safe=True)) == \
        b"".join(csv_chunks(df, 300, excel_safe=True))
    assert "'=1+1" in b"".join(csv_chunks(cols, 300, excel_safe=True)).decode()
    monkeypatch.setattr(tables, "THREAD_ROWS", 1)
    assert text(cols, chunk_rows=100) == frame_text
    assert tables.n_rows(cols) == n and tables.n_rows({}) == 0
    assert text({"a": np.zeros(0)}) == "a\n"


def test_the_observation_columns_are_the_observation_table(folders):
    """qc.columns() (what the writer formats) holds table()'s columns, in order, and the
    file written from them is the DataFrame's text."""
    _, qc = folders
    cols, df = qc.columns(), qc.table()
    assert list(cols) == list(df.columns)
    assert text(cols, chunk_rows=97) == text(df)


def test_observation_groups_in_the_order_of_the_first_row():
    """summary.json's observation_groups: each distinct (kind, component) pair once, in the
    order of its first row, as pandas' drop_duplicates of the text gives them (a kind that
    is a number as its text)."""
    from baarda.output.results import observation_groups

    kind = np.array(["image", "control", "image", "gnss", "control", 3.0, "image"] * 50,
                    dtype=object)
    comp = np.array(["x", "Z", "y", "X", "X", "x", "x"] * 50, dtype=object)
    groups = observation_groups({"kind": kind, "component": comp})
    pairs = pd.DataFrame({"kind": kind, "component": comp}).astype(str).drop_duplicates()
    assert list(groups) == list(dict.fromkeys(pairs["kind"])) == \
        ["image", "control", "gnss", "3.0"]
    assert {k: list(cs) for k, cs in groups.items()} == \
        {k: list(pairs["component"][pairs["kind"] == k]) for k in groups}
    assert groups["control"] == {"Z": "control Z", "X": "control X"}  # control by axis
    text_only = {"kind": kind[:4].astype(str), "component": comp[:4].astype(str)}
    assert list(observation_groups(text_only)) == ["image", "control", "gnss"]
