"""Result folders edited by tests: `resign` makes run.json list the edited files again (the
report reads only folders whose files are the run's own)."""

import json
from pathlib import Path

from baarda.io.run_manifest import MANIFEST, file_record


def resign(folder: Path) -> None:
    """run.json of `folder` with the size and checksum of every file it lists as they are now
    (a test that edits a result file on purpose)."""
    mp = Path(folder) / MANIFEST
    manifest = json.loads(mp.read_text(encoding="utf-8"))
    manifest["files"] = {name: file_record(Path(folder) / name) for name in manifest["files"]
                         if (Path(folder) / name).is_file()}
    mp.write_text(json.dumps(manifest, indent=2), encoding="utf-8")
