"""Writing the screening log: screening_log.csv (one row per decision) and screening.txt."""

from __future__ import annotations

from pathlib import Path

from baarda.output.atomic import write_text
from baarda.output.run_folder import RunFolder, staged
from baarda.output.tables import csv_text
from baarda.screening.log import ScreeningLog


def write_screening_log(folder: str | Path | RunFolder, log: ScreeningLog) -> list[Path]:
    """screening_log.csv (one row per decision) and screening.txt (for people); the final
    paths."""
    with staged(folder) as run:
        write_text(run.file("screening_log.csv"), csv_text(log.table(), "%.6g"))
        write_text(run.file("screening.txt"), log.summary() + "\n")
        return [run.final / "screening_log.csv", run.final / "screening.txt"]
