"""Writing the screening log: screening_log.csv (one row per decision) and screening.txt."""

from __future__ import annotations

from pathlib import Path

from baarda.output.atomic import write_text
from baarda.output.tables import csv_text
from baarda.screening.log import ScreeningLog


def write_screening_log(folder: str | Path, log: ScreeningLog) -> list[Path]:
    """screening_log.csv (one row per decision) and screening.txt (for people)."""
    folder = Path(folder)
    paths = [folder / "screening_log.csv", folder / "screening.txt"]
    write_text(paths[0], csv_text(log.table(), "%.6g"))
    write_text(paths[1], log.summary() + "\n")
    return paths
