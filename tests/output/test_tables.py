"""The vectorised CSV writer prints every table byte for byte as pandas' to_csv does, and
the Parquet observation table holds the same numbers (issue 16)."""

import json

import numpy as np
import pandas as pd
import pytest

from baarda.output import tables
from baarda.output.bundle_results import write_results
from baarda.output.result_folder import read_observations, read_results
from baarda.output.tables import csv_chunks, fast_csv_possible, pandas_csv_text, write_csv
from baarda.pipeline import snoop
from baarda.simulate.aerial import FlightPlan, simulate_block

EDGES = [0.0, -0.0, np.inf, -np.inf, np.nan, 1e-300, -5e-324, 1.7976931348623157e308,
         1234567890.5, 1234567891.5, 9999999999.5, 0.99999999995, 0.999999999949999,
         1e-5, 1e-4, 9.9999999995e-5, 0.0001, 123456789012.0, 1e10, 1e9, 9999999999.0,
         99999999995.0, 1e-13, 1e-14, 1e31, 1e32, 0.1, 0.5, 1.5, 2.5, 1e22, 1e23, 1e-22,
         123.456, -0.000123456789, 4.043202913e-06]


def fast(df, float_format=tables.RESULT_FORMAT, chunk_rows=1000):
    assert fast_csv_possible(df, float_format)
    return b"".join(csv_chunks(df, float_format, chunk_rows)).decode("utf-8")


def values(n: int, seed: int = 1) -> np.ndarray:
    """Values of every size and the ones whose %.10g rounding is a near or exact tie."""
    rng = np.random.default_rng(seed)
    wide = rng.standard_normal(n) * 10.0 ** rng.integers(-25, 30, n)
    ties = (rng.integers(10**9, 10**10, n) + 0.5) * 10.0 ** rng.integers(-15, 10, n)
    near = np.nextafter(ties, np.where(rng.random(n) < 0.5, -np.inf, np.inf))
    short = np.round(rng.standard_normal(n) * 1e4 * 10.0 ** rng.integers(0, 6, n)) / 1e4
    return np.concatenate([wide, ties, near, short, rng.random(n), EDGES])


@pytest.mark.slow
def test_floats_as_pandas_prints_them():
    v = values(20_000)
    df = pd.DataFrame({"a": v, "b": -v[::-1], "c": np.sqrt(np.abs(v))})
    for fmt in ("%.10g", "%.6g", "%.4g", "%.12g", "%.1g"):
        assert fast(df, fmt) == pandas_csv_text(df, fmt), fmt


def test_text_bool_int_columns_as_pandas_prints_them():
    n = 5003
    i = np.arange(n)
    df = pd.DataFrame({
        "id": pd.array([f"p{k}" if k % 97 else 'a,"b"' for k in i], dtype="str"),
        "missing": pd.array([None if k % 7 == 0 else "é" for k in i], dtype="str"),
        "obj": np.array(["x\ny" if k % 11 == 0 else "" for k in i], dtype=object),
        "v": values(1000)[:n], "flag": i % 3 == 0, "count": i - 50,
        "u": (i % 5).astype(np.uint8)})
    assert fast(df, chunk_rows=777) == pandas_csv_text(df)


def test_columns_of_other_objects_go_to_pandas(tmp_path):
    n = 30
    df = pd.DataFrame({"a": np.arange(n) / 7, "none": np.array([None] * n, dtype=object),
                       "mixed": np.array([1, "x", 2.5] * 10, dtype=object)})
    assert fast_csv_possible(df)  # by its dtypes; the objects are found out when read
    with pytest.raises(TypeError):
        csv_chunks(df)
    write_csv(tmp_path / "t.csv", df, fast=True)
    assert (tmp_path / "t.csv").read_text() == pandas_csv_text(df)
    rows = tables.FAST_ROWS
    try:
        tables.FAST_ROWS = 1
        assert tables.csv_text(df) == pandas_csv_text(df)
        empty = df[["a", "none"]]
        assert fast(empty) == pandas_csv_text(empty)  # missing values only: empty cells
    finally:
        tables.FAST_ROWS = rows


def test_tables_it_does_not_take_go_to_pandas(tmp_path):
    df = pd.DataFrame({"a": np.arange(3.0), "b": pd.array([1, None, 3], dtype="Int64")})
    assert not fast_csv_possible(df)
    assert not fast_csv_possible(df[["a"]])  # one column: pandas quotes an empty cell
    assert not fast_csv_possible(df, "%.3f")
    write_csv(tmp_path / "t.csv", df, fast=True)
    assert (tmp_path / "t.csv").read_text() == pandas_csv_text(df)


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A snooped block written with the pandas writer, the vectorised one and as Parquet."""
    root = tmp_path_factory.mktemp("tables")
    block, _ = simulate_block(FlightPlan(strips=3, photos_per_strip=6, blunders=4,
                                         check_points=2, relief_m=30.0, seed=3))
    qc = snoop(block)
    rows = tables.FAST_ROWS
    try:
        tables.FAST_ROWS = 10**12
        write_results(root / "pandas", qc)
        tables.FAST_ROWS = 1
        write_results(root / "fast", qc)
        write_results(root / "parquet", qc, parquet=True)
    finally:
        tables.FAST_ROWS = rows
    return root, qc


def test_result_folder_byte_identical_to_the_pandas_writer(folders):
    root, _ = folders
    for name in ("observations.csv", "photos.csv", "points.csv"):
        assert (root / "fast" / name).read_bytes() == (root / "pandas" / name).read_bytes()


def test_parquet_round_trips_to_the_last_printed_digit(folders):
    root, qc = folders
    pq = root / "parquet"
    assert not (pq / "observations.csv").exists()
    stored = pd.read_parquet(pq / "observations.parquet")
    pd.testing.assert_frame_equal(stored, qc.table())  # the numbers as computed
    assert pandas_csv_text(stored) == (root / "pandas" / "observations.csv").read_text()
    manifest = json.loads((pq / "run.json").read_text())
    assert "observations.parquet" in manifest["files"]
    a = read_results(pq).obs
    b = read_observations(root / "pandas" / "observations.csv")
    assert list(a.columns) == list(b.columns)
    for c in a.columns:
        if a[c].dtype == float:
            x, y = a[c].to_numpy(), b[c].to_numpy()
            assert np.array_equal([f"{t:.10g}" for t in x], [f"{t:.10g}" for t in y]), c
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
