"""The operator's edits of a block and how they are applied (docs/review.md).

One edit a row of OUT/edits.csv: action, photo, point, component, x, y (mm), time.

* reject / restore: one component (x or y) of an image point leaves / rejoins the
  adjustment; it stays in the observation vector, predicted and tested (as data snooping
  leaves a rejected component: bundle/bundle_model.py);
* remeasure: an image point measured again at (x, y) mm;
* aside: a point's rays leave the block (it waits for another ray);
* undo: the last edit not undone is taken back.

`edited(block, edits)` is what `baarda adjust --edits` and `baarda review` both apply: the
block with the re-measurements and the points set aside, and the rejected components, which
`active_of` turns into the problem's active mask.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from baarda.block.photo_block import Block
from baarda.errors import ProjectError

ACTIONS = ("reject", "restore", "remeasure", "aside", "undo")
COLUMNS = ("action", "photo", "point", "component", "x", "y", "time")
Key = tuple[str, str, str]  # (photo, point, component) of an image coordinate


class UnknownId(ValueError):
    """An edit names a photo or point that is not in the block (or not measured there)."""


@dataclass(frozen=True)
class Edit:
    """One edit: action (ACTIONS), photo and point ids, component 'x' or 'y' (reject,
    restore), x, y the new position in mm (remeasure; NaN otherwise), time (ISO 8601)."""

    action: str
    photo: str = ""
    point: str = ""
    component: str = ""
    x: float = math.nan
    y: float = math.nan
    time: str = ""


def effective(edits: list[Edit]) -> list[Edit]:
    """The edits in force: every 'undo' takes back the last edit before it not undone."""
    out: list[Edit] = []
    for e in edits:
        if e.action == "undo":
            if out:
                out.pop()
        else:
            out.append(e)
    return out


def edited(block: Block, edits: list[Edit]) -> tuple[Block, set[Key]]:
    """(the block with the edits' re-measurements and points set aside, the rejected image
    components).  ValueError for an edit that cannot apply (an id not in the block, a
    component not x or y, a re-measurement without finite x, y)."""
    xy = block.image.xy_mm.copy()
    keep = np.ones(len(block.image), bool)
    rejected: set[Key] = set()
    for e in effective(edits):
        check(block, e)
        if e.action in ("reject", "restore"):
            (rejected.add if e.action == "reject" else rejected.discard)(
                (e.photo, e.point, e.component))
        elif e.action == "remeasure":
            xy[image_row(block, e.photo, e.point)] = (e.x, e.y)
        elif e.action == "aside":
            keep &= block.image.point != block.point_index[e.point]
    image = replace(block.image, xy_mm=xy).take(keep)
    return replace(block, image=image), rejected


def image_row(block: Block, photo: str, point: str) -> int:
    """The row of block.image of point `point` on photo `photo` (ValueError: not measured)."""
    i = block.photos.ids.index(photo) if photo in block.photos.ids else None
    j = block.point_index.get(point)
    if i is None or j is None:
        raise UnknownId(f"point {point} on photo {photo}: not in the block")
    rows = np.flatnonzero((block.image.photo == i) & (block.image.point == j))
    if not len(rows):
        raise UnknownId(f"point {point} is not measured on photo {photo}")
    return int(rows[0])


def check(block: Block, e: Edit) -> None:
    """ValueError naming what is wrong with an edit of this block."""
    if e.action not in ACTIONS:
        raise ValueError(f"unknown action {e.action!r}: one of {', '.join(ACTIONS)}")
    if e.action == "undo":
        return
    if e.action == "aside":
        if e.point not in block.point_index:
            raise UnknownId(f"point {e.point}: not in the block")
        return
    if not e.photo:
        raise ValueError(f"{e.action} edits an image point: give its photo and point (control "
                         "and GNSS observations are edited in the project's files)")
    image_row(block, e.photo, e.point)
    if e.action in ("reject", "restore") and e.component not in ("x", "y"):
        raise ValueError(f"component {e.component!r}: x or y")
    if e.action == "remeasure" and not (math.isfinite(e.x) and math.isfinite(e.y)):
        raise ValueError("remeasure needs finite x and y (mm)")


def active_of(problem, rejected: set[Key]) -> np.ndarray:
    """The active mask of a BundleProblem's observation vector with `rejected` off."""
    active = np.ones(len(problem.kind), bool)
    if rejected:
        img = np.asarray(problem.kind) == "image"
        keys = zip(problem.frame[img], problem.point[img], problem.component[img],
                   strict=True)
        active[np.flatnonzero(img)] = [k not in rejected for k in keys]
    return active


def write_edits(path: Path, edits: list[Edit]) -> None:
    """OUT/edits.csv, one row per edit (COLUMNS), written atomically."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for e in edits:
            w.writerow([e.action, e.photo, e.point, e.component,
                        "" if math.isnan(e.x) else repr(e.x),
                        "" if math.isnan(e.y) else repr(e.y), e.time])
    tmp.replace(path)


def read_edits(path: str | Path) -> list[Edit]:
    """The edits of an edits.csv (ProjectError naming file, line and field)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as e:
        raise ProjectError(str(path), f"cannot read: {e.strerror}") from None
    rows = list(csv.reader(text.splitlines()))
    if not rows or [c.strip() for c in rows[0]][:len(COLUMNS)] != list(COLUMNS):
        raise ProjectError(str(path), f"the header must be {','.join(COLUMNS)}", 1)
    out = []
    for n, row in enumerate(rows[1:], start=2):
        if not row or not "".join(row).strip():
            continue
        if len(row) < len(COLUMNS):
            raise ProjectError(str(path), f"{len(row)} fields, {len(COLUMNS)} expected", n)
        action = row[0].strip()
        if action not in ACTIONS:
            raise ProjectError(str(path), f"unknown action {action!r}: one of "
                               f"{', '.join(ACTIONS)}", n, "action")
        xy = []
        for field, s in (("x", row[4]), ("y", row[5])):
            try:
                xy.append(float(s) if s.strip() else math.nan)
            except ValueError:
                raise ProjectError(str(path), f"{s!r} is not a number", n, field) from None
        out.append(Edit(action, row[1].strip(), row[2].strip(), row[3].strip(), xy[0], xy[1],
                        row[6].strip()))
    return out
