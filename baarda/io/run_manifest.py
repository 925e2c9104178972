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


def read_json(path: Path) -> object:
    """The JSON document of a file; ProjectError naming the file (and line) when it is not
    UTF-8 JSON, or nests too deeply to be one of baarda's."""
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as e:
        raise ProjectError(str(path), f"cannot be read ({e.strerror or e})") from None
    except UnicodeDecodeError as e:
        raise ProjectError(str(path), f"not UTF-8 text: byte 0x{e.object[e.start]:02x} at "
                           f"offset {e.start} (a file that baarda did not write, or was "
                           "edited)") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise ProjectError(str(path), f"not valid JSON: {e.msg}", e.lineno) from None
    except RecursionError:
        raise ProjectError(str(path), "not a file of baarda: JSON nested too deeply") from None


def written_excel_safe(folder: Path) -> bool:
    """Whether the run in `folder` wrote its tables with --excel-safe (its run.json says
    "excel_safe": true); False where there is no readable run.json."""
    p = folder / MANIFEST
    try:
        data = p.read_bytes() if p.is_file() else b""
        if b'"excel_safe"' not in data:
            return False
        doc = json.loads(data)
    except (OSError, ValueError, RecursionError):
        return False
    return isinstance(doc, dict) and doc.get("excel_safe") is True


def read_manifest(path: Path) -> dict:
    """run.json checked: an object with 'run' (text) and 'files' (an object of name ->
    {bytes, sha256}); ProjectError naming what is wrong."""
    manifest = read_json(path)
    if not isinstance(manifest, dict):
        raise ProjectError(str(path), f"not a run manifest of baarda: a JSON "
                           f"{type(manifest).__name__}, not an object")
    for key, kind in (("run", str), ("files", dict)):
        if key not in manifest:
            raise ProjectError(str(path), f"not a run manifest of baarda: no '{key}'")
        if not isinstance(manifest[key], kind):
            what = {str: "text", dict: "an object of file name -> size and checksum"}[kind]
            raise ProjectError(str(path), f"'{key}' must be {what}, not "
                               f"{type(manifest[key]).__name__}")
    for name, record in manifest["files"].items():
        if not (isinstance(record, dict) and isinstance(record.get("bytes"), int)
                and isinstance(record.get("sha256"), str)):
            raise ProjectError(str(path), f"'files' entry '{name}' must be an object with "
                               "'bytes' (an integer) and 'sha256' (text)")
    return manifest


def verify_run(folder: str | Path, names: Iterable[str]) -> str | None:
    """Check that the files `names` of a result folder belong to the run its run.json
    lists (same size and SHA-256); the run id, or None for a folder written before run.json
    existed.  A file that is missing, changed or not of the run is a ProjectError."""
    folder = Path(folder)
    mp = folder / MANIFEST
    if not mp.is_file():
        return None
    manifest = read_manifest(mp)
    run, files = manifest["run"], manifest["files"]
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
