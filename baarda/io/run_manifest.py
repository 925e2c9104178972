"""run.json of a result folder, read: the run id and the size and SHA-256 of every file the
run wrote (output/run_folder.py writes it), so that a reader takes only files of one run."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from pathlib import Path

from baarda.errors import ProjectError

MANIFEST = "run.json"


def file_record(path: Path) -> dict:
    """Size and SHA-256 of a file (read in 1 MB blocks)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return {"bytes": path.stat().st_size, "sha256": h.hexdigest()}


def verify_run(folder: str | Path, names: Iterable[str]) -> str | None:
    """Check that the files `names` of a result folder belong to the run its run.json
    lists (same size and SHA-256); the run id, or None for a folder written before run.json
    existed.  A file that is missing, changed or not of the run is a ProjectError."""
    folder = Path(folder)
    mp = folder / MANIFEST
    if not mp.is_file():
        return None
    try:
        manifest = json.loads(mp.read_text(encoding="utf-8"))
        run, files = manifest["run"], manifest["files"]
    except (json.JSONDecodeError, KeyError, TypeError, UnicodeDecodeError):
        raise ProjectError(str(mp), "not a run manifest of baarda (broken JSON or missing "
                           "'run'/'files')") from None
    for name in names:
        p = folder / name
        if not p.is_file():
            continue
        if name not in files:
            raise ProjectError(str(p), f"does not belong to run {run} of this folder "
                               f"({MANIFEST} does not list it): the folder mixes runs")
        if file_record(p) != files[name]:
            raise ProjectError(str(p), f"is not the file that run {run} wrote (size or "
                               "checksum differ): the folder mixes runs or was edited")
    return run
