"""A truncated input is never read as a smaller block (issue 41).

Every file of every data set in ../shared/data is cut at several byte offsets (inside a
number, at a line end, inside an XML element or JSON value, before the last line, to
nothing) and its data set read again with `baarda.read`: the answer is a ProjectError that
names the cut file, or a block equal to the intact input's (a file the reader does not
need), never a different block.  The files a read opens are recorded by an audit hook: a
file the intact read never opens cannot change the block and is cut once only.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

import baarda
from baarda.block.crs import LocalFrame
from baarda.errors import ProjectError

# ../shared/data beside the checkout (a worktree one level deeper looks one further up)
SHARED = next((p for p in (Path(__file__).resolve().parents[k] / "shared" / "data"
                           for k in (3, 4)) if p.is_dir()),
              Path(__file__).resolve().parents[3] / "shared" / "data")
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not SHARED.is_dir(),
                                 reason=f"the shared data sets are not found at {SHARED}")]

# data sets kept in the repository (tests/data) rather than in ../shared/data
TESTS_DATA = Path(__file__).resolve().parents[1] / "data"
LOCAL = {"metashape_sxb": TESTS_DATA / "metashape_sxb",
         "metashape_cameras_spec": TESTS_DATA / "metashape_cameras_spec"}


def source(dataset: str) -> Path:
    return LOCAL.get(dataset, SHARED / dataset)


# data set folder -> the inputs read from it (relative paths; "." the folder itself)
INPUTS = {
    "aicon_jaicov_closerange": ["."],
    "bal": ["problem-49-7776-pre.txt.bz2", "problem-21-11315-pre.txt.bz2",
            "problem-16-22106-pre.txt.bz2"],
    "colmap_maupertuis": ["."],
    "dbat_camcal_closerange": ["dbat_script/camcaldemo.xml",
                               "photomodeler_export/camcal-pmexport.txt"],
    "dbat_sxb_aerial": ["dbat_script/sxb.xml",
                        "photomodeler_export/wsmart-no-orient-pmexport.txt"],
    "metashape_cameras_spec": ["cameras.xml"],
    "metashape_sxb": ["sxb.psz"],
    "micmac_ign_ultracam_aerial": ["."],
    "opensfm_berlin": ["."],
}

# data sets of this repository's tests/data (the others are in ../shared/data)
INPUTS.update({"patb_demo": ["."], "bingo_pix4d": ["."]})
LOCAL.update({"patb_demo": TESTS_DATA / "patb_demo", "bingo_pix4d": TESTS_DATA / "bingo_pix4d"})

# files whose format cannot show a cut exactly at a line end (no count; docs/formats.md
# "Where a cut cannot show"): data set -> file name patterns.  Every other cut of them is
# still refused.
UNSEEN_AT_LINE_END = {
    "aicon_jaicov_closerange": ("*.phc", "*.obc", "*.scale"),
    "dbat_camcal_closerange": ("markpts.txt", "camcal-fixed.txt"),
    "dbat_sxb_aerial": ("markpts.txt", "smartpts.txt", "sxb-control.txt"),
    "micmac_ign_ultracam_aerial": ("*liaisons*.mes", "*.MES", "*.APP"),
    "opensfm_berlin": ("tracks*.csv",),
}
LINE_END_CUTS = ("line end", "before the last line")
DOCS = Path(__file__).resolve().parents[2] / "docs" / "formats.md"

_OPENED: set[str] | None = None


def _audit(event: str, args: tuple) -> None:
    if _OPENED is not None and event == "open" and isinstance(args[0], (str, bytes, Path)):
        _OPENED.add(os.path.realpath(os.fsdecode(args[0])))


sys.addaudithook(_audit)


def read_recording(path: Path):
    """baarda.read(path) and the real paths of the files it opened."""
    global _OPENED
    _OPENED = set()
    try:
        return baarda.read(path), _OPENED
    finally:
        _OPENED = None


def _digit_pair(data: bytes, start: int, stop: int, step: int = 1) -> int | None:
    """A position between two digits, searching from start towards stop."""
    for i in range(start, stop, step):
        if 0 < i < len(data) and data[i - 1:i].isdigit() and data[i:i + 1].isdigit():
            return i
    return None


def cut_offsets(data: bytes) -> dict[str, int]:
    """Where to cut a file: name -> byte offset (the cut keeps data[:offset])."""
    n = len(data)
    out = {"empty": 0}
    mid = n // 2
    nl = data.rfind(b"\n", 0, mid)
    if nl > 0:
        out["line end"] = nl + 1
    stripped = data.rstrip()
    last = stripped.rfind(b"\n")
    if last > 0:
        out["before the last line"] = last + 1
    d = _digit_pair(data, mid, n)
    if d is not None:
        out["inside a number"] = d
    d = _digit_pair(stripped, len(stripped) - 1, max(last, 0), -1)
    if d is not None:
        out["inside the last number"] = d
    lt = data.find(b"<", n // 3)
    if lt > 0:
        out["inside an element"] = lt + 2
    q = data.find(b'"', n // 3)
    if q > 0 and lt < 0:
        out["inside a value"] = q + 2
    return {k: v for k, v in out.items() if v < n}


def _equal(a, b) -> bool:
    if isinstance(a, LocalFrame) or isinstance(b, LocalFrame):
        return (type(a) is type(b) and a.crs == b.crs
                and np.array_equal(a.origin_ecef, b.origin_ecef))
    if dataclasses.is_dataclass(a):
        return type(a) is type(b) and all(
            _equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape or a.dtype.kind != b.dtype.kind:
            return False
        if a.dtype.kind in "fc":
            return bool(np.array_equal(a, b, equal_nan=True))
        return bool(np.array_equal(a, b))
    if isinstance(a, (list, tuple)):
        return (type(a) is type(b) and len(a) == len(b)
                and all(_equal(x, y) for x, y in zip(a, b, strict=True)))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    return a == b


def _mirror(src: Path, dst: Path) -> None:
    """A copy of the data set folder (files copied, so that one can be cut in place)."""
    shutil.copytree(src, dst)


def check_truncations(dataset: str, tmp: Path) -> list[str]:
    """The cuts of the data set's files that were read as a block different from the
    intact input's, or refused without naming the cut file."""
    folder = tmp / dataset
    _mirror(source(dataset), folder)
    files = sorted(p for p in folder.rglob("*") if p.is_file())
    unseen = UNSEEN_AT_LINE_END.get(dataset, ())
    wrong = []
    reads = {rel: read_recording(folder / rel) for rel in INPUTS[dataset]}
    for f in files:
        data = f.read_bytes()
        offsets = cut_offsets(data)
        users = [rel for rel, (_, opened) in reads.items() if os.path.realpath(f) in opened]
        if not users:  # no read opens it: it cannot matter; cut twice, read once
            users, offsets = [INPUTS[dataset][0]], dict(list(offsets.items())[:2])
        for rel in users:
            path, intact = folder / rel, reads[rel][0]
            for what, at in offsets.items():
                f.write_bytes(data[:at])
                try:
                    block = baarda.read(path)
                except ProjectError as e:
                    # named as the path of the error, or in its message ("is images.txt cut
                    # short?" on the line that names an image it lost)
                    if Path(e.path).resolve() != f.resolve() and f.name not in e.detail:
                        wrong.append(f"{rel}: {f.relative_to(folder)} cut {what} (byte {at}):"
                                     f" refused naming {e.path}: {e}")
                else:
                    cannot_show = (what in LINE_END_CUTS or (what == "empty" and
                                                             f.suffix == ".scale"))
                    if cannot_show and any(f.match(g) for g in unseen):
                        continue
                    if not _equal(block, intact):
                        wrong.append(f"{rel}: {f.relative_to(folder)} cut {what} (byte {at} "
                                     f"of {len(data)}): read as a different block "
                                     f"({len(block.photos)} photos, {len(block.image)} "
                                     f"image points; intact {len(intact.photos)}, "
                                     f"{len(intact.image)})")
                finally:
                    f.write_bytes(data)
    return wrong


@pytest.mark.parametrize("dataset", sorted(INPUTS))
def test_a_cut_file_is_refused_or_does_not_matter(dataset, tmp_path):
    if not source(dataset).is_dir():
        pytest.skip(f"{source(dataset)} not found")
    wrong = check_truncations(dataset, tmp_path)
    assert not wrong, "\n".join(wrong)


def test_the_cuts_that_cannot_show_are_documented():
    text = " ".join(DOCS.read_text(encoding="utf-8").split())
    section = text[text.index("**Where a cut cannot show.**"):]
    section = section[:section.index("##")]
    for pattern in {g for gs in UNSEEN_AT_LINE_END.values() for g in gs}:
        assert pattern.lstrip("*") in section, f"{pattern} is not named in docs/formats.md"


def test_the_ign_image_list_cut_after_525_bytes_is_refused(tmp_path):
    """The acceptance case: ImAerien.xml cut after 525 of its 1,138 bytes was read as a
    7-photo block with exit 0."""
    folder = tmp_path / "ign"
    _mirror(SHARED / "micmac_ign_ultracam_aerial", folder)
    f = folder / "ImAerien.xml"
    data = f.read_bytes()
    assert len(data) == 1138
    f.write_bytes(data[:525])
    with pytest.raises(ProjectError) as e:
        baarda.read(folder)
    assert Path(e.value.path) == f and re.search(r"line \d+", str(e.value))
