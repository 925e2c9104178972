"""The result folder of `baarda online --bundle`: the result folder of the block at the end,
as `baarda adjust` writes it for the same observations (output/bundle_results.py), with the
test of every component at the moment it was taken in (replay.csv, or online.csv for
measurements from the command's input; online/replay.py COLUMNS)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from baarda.output.bundle_results import write_results
from baarda.output.run_folder import RunFolder
from baarda.output.tables import write_csv
from baarda.quality.assessment import Assessment


def write_online(run: RunFolder, assessment: Assessment | None, tests: pd.DataFrame,
                 name: str = "replay.csv", parquet: bool = False) -> list[Path]:
    """The block's result folder (when it could be adjusted) and the table of tests."""
    paths = write_results(run, assessment, parquet=parquet) if assessment is not None else []
    write_csv(run.file(name), tests, excel_safe=run.excel_safe)
    return paths + [run.final / name]
