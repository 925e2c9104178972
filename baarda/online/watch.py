"""A reconstruction that grows on disk, watched: each new snapshot's new images tested against
the block before it (`baarda online --bundle --watch DIR`).

DIR is either one model rewritten in place (a COLMAP sparse folder, a native project: any
input `baarda.pipeline.read` reads; a new snapshot whenever its files change) or a folder of
snapshot subfolders, read in the order of their names (COLMAP's incremental mapper writes
DIR/00000001, DIR/00000002, ...).  Plain polling of the files' sizes and modification times.

The first snapshot is the first adjustment (every observation tested in it); for each later
one, matched to the block by photo and point ids:

* image points it no longer has (COLMAP's retriangulation and filtering) are taken out, all
  at once (`OnlineBundle.remove_image_points`), and so are those whose coordinates changed;
* new image points of photos the block has are added photo by photo, then its new photos
  with all their points (`OnlineBundle.add_photo`: each photo tested before it is taken in),
  their approximate orientations brought from the snapshot's frame into the block's by the
  similarity of their common projection centres and points (a reconstruction's frame may
  move between snapshots), resected when fewer than three are common.

A snapshot that cannot be read (being written) is tried again at the next poll; after
`retries` polls with its files unchanged, its reader's error (naming the file) is raised.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from baarda.block.photo_block import Block
from baarda.block.rotation import angles_from_matrix, rotation_matrix, similarity
from baarda.errors import GeometryError, ProjectError
from baarda.online.answers import Answer
from baarda.online.bundle import MAX_ROWS, OnlineBundle
from baarda.online.replay import COLUMNS, tests_table
from baarda.options import TestOptions

INTERVAL = 2.0  # s between polls
RETRIES = 3  # polls an unreadable snapshot with unchanged files is tried
MOVED_MM = 1e-9  # an image point moved by more than this (mm) is measured again
WATCH_COLUMNS = ("snapshot", *COLUMNS)


@dataclass(frozen=True)
class Snapshot:
    """A state of the reconstruction: its name, folder and the (file, size, mtime ns) of its
    files."""

    name: str
    path: Path
    stamp: tuple


def _stamp(path: Path) -> tuple:
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    out = []
    for p in files:
        try:
            st = p.stat()
        except OSError:  # removed while looked at: the next poll sees
            continue
        out.append((str(p.relative_to(path)) if path.is_dir() else p.name, st.st_size,
                    st.st_mtime_ns))
    return tuple(out)


def _order(p: Path) -> tuple:
    return (0, int(p.name), p.name) if p.name.isdigit() else (1, 0, p.name)


def snapshots(folder: str | Path) -> list[Snapshot]:
    """The snapshots in `folder` now: its subfolders in the order of their names (numbers
    first, by value), or the folder itself (one model rewritten in place) when it has none
    that hold files."""
    from baarda.io.formats import detect

    folder = Path(folder)
    if not folder.is_dir():
        raise ProjectError(str(folder), "not a folder: --watch needs the folder in which the "
                           "reconstruction grows")
    try:
        detect(folder)
        in_place = True
    except ProjectError:
        in_place = False
    if not in_place:
        subs = sorted((p for p in folder.iterdir() if p.is_dir() and any(p.iterdir())),
                      key=_order)
        if subs:
            return [Snapshot(p.name, p, _stamp(p)) for p in subs]
    files = _stamp(folder)
    return [Snapshot(folder.name, folder, files)] if files else []


@dataclass
class Watch:
    """The on-line bundle of a reconstruction that grows on disk (module docstring).

    read: the reader of a snapshot (default baarda.pipeline.read); tests, max_rows: as
    OnlineBundle's; retries: polls an unreadable snapshot is tried with its files unchanged.
    `poll()` takes in every new snapshot; `rows` holds (snapshot, Answer) of every step."""

    folder: Path
    tests: TestOptions | Callable | None = None  # or f(settings) of the first snapshot
    read: Callable[[Path], Block] | None = None
    max_rows: int = MAX_ROWS
    retries: int = RETRIES
    progress: Callable[[str, Answer], None] | None = None
    online: OnlineBundle | None = None
    rows: list = field(default_factory=list)
    done: list = field(default_factory=list)  # names of the snapshots taken in
    notes: list = field(default_factory=list)
    _seen: dict = field(default_factory=dict)  # name -> stamp taken in
    _failed: dict = field(default_factory=dict)  # name -> (stamp, tries)
    _obs: dict = field(default_factory=dict)  # (photo, point) -> (x, y) mm in the block

    def __post_init__(self):
        self.folder = Path(self.folder)
        if self.read is None:
            from baarda.pipeline import read

            self.read = read

    # ---------------------------------------------------------------- polling
    def poll(self) -> int:
        """Take in every snapshot that is new (or, in place, rewritten) since the last poll;
        returns how many.  One that cannot be read is left for the next poll."""
        n = 0
        for snap in snapshots(self.folder):
            if self._seen.get(snap.name) == snap.stamp or (
                    snap.path != self.folder and snap.name in self._seen):
                continue
            block = self._read(snap)
            if block is None:
                break  # snapshots are taken in order: the later ones wait for it
            self._take(snap.name if snap.path != self.folder else
                       f"{snap.name}#{len(self.done) + 1}", block)
            self._seen[snap.name] = snap.stamp
            n += 1
        return n

    @property
    def waiting(self) -> list[str]:
        """Snapshots that could not be read yet."""
        return sorted(self._failed)

    def run(self, interval: float = INTERVAL, once: bool = False,
            sleep: Callable[[float], None] | None = None) -> None:
        """Poll every `interval` s until interrupted (KeyboardInterrupt propagates, the
        snapshots taken in so far complete); once: until every snapshot present is taken in
        (an unreadable one tried `retries` times, `interval` s apart)."""
        sleep = sleep or time.sleep
        while True:
            self.poll()
            if once and not self._failed:
                return
            sleep(interval)

    def _read(self, snap: Snapshot) -> Block | None:
        assert self.read is not None  # set by __post_init__
        try:
            block = self.read(snap.path)
        except (ProjectError, OSError, ValueError, UnicodeDecodeError) as e:
            before = self._failed.get(snap.name)
            tries = before[1] + 1 if before is not None and before[0] == snap.stamp else 1
            if tries >= self.retries:
                if isinstance(e, ProjectError):
                    raise
                raise ProjectError(str(snap.path), f"snapshot {snap.name} cannot be read "
                                   f"after {tries} tries: {e}") from None
            self._failed[snap.name] = (snap.stamp, tries)
            return None
        self._failed.pop(snap.name, None)
        return block

    # ---------------------------------------------------------------- one snapshot
    def _say(self, name: str, a: Answer) -> None:
        self.rows.append((name, a))
        if self.progress is not None:
            self.progress(name, a)

    def _take(self, name: str, block: Block) -> None:
        cur = _observations(block)
        if self.online is None:
            if callable(self.tests):
                self.tests = self.tests(block.settings)
            try:
                assert not callable(self.tests)  # resolved above
                ob = OnlineBundle(block, self.tests, max_rows=self.max_rows)
            except ValueError as e:
                raise ProjectError(name, str(e)) from None
            self.online = ob
            self._obs = cur
            if ob.first is not None:
                self._say(name, ob.first)
            elif ob.answers:
                self._say(name, ob.answers[-1])
            self.done.append(name)
            return
        ob = self.online
        gone = [k for k, xy in self._obs.items()
                if k not in cur or np.abs(np.subtract(cur[k][:2], xy[:2])).max() > MOVED_MM]
        if gone:
            try:
                self._say(name, ob.remove_image_points(gone))
                for k in gone:
                    del self._obs[k]
            except GeometryError as e:  # the block would fall apart without them: kept
                self.notes.append(f"snapshot {name}: {e}")
        new = [k for k in cur if k not in self._obs]
        by_photo: dict[str, dict] = {}
        for photo, point in new:
            by_photo.setdefault(photo, {})[point] = cur[(photo, point)]
        known = [p for p in by_photo if p in ob.m.photo_at]
        fresh = [p for p in block.photos.ids if p in by_photo and p not in ob.m.photo_at]
        eo = self._approximations(block, fresh)
        cams = block.cameras.ids
        at = {pid: i for i, pid in enumerate(block.photos.ids)}
        for photo in known + fresh:
            kw = {}
            if photo in eo:
                i = at[photo]
                cam = cams[int(block.photos.camera[i])]
                if cam not in ob.m.cameras.ids:
                    try:
                        k = int(block.photos.camera[i])
                        free = block.settings.calibration_free
                        self._say(name, ob.add_camera(block.cameras, k,
                                                      free[k] if free is not None else ()))
                    except ValueError as e:
                        raise ProjectError(name, f"photo {photo}: {e}") from None
                kw = {"camera": cam, "eo": eo[photo], "strip": block.photos.strip[i]}
            self._say(name, ob.add_photo(photo, by_photo[photo], **kw))
            self._obs.update({(photo, p): xy for p, xy in by_photo[photo].items()})
        self.done.append(name)

    def _approximations(self, block: Block, fresh: list[str]) -> dict:
        """Orientations of the snapshot's new photos in the block's frame: the snapshot's,
        moved by the similarity of the projection centres and points both have (None, to be
        resected, when fewer than three are common)."""
        if not fresh:
            return {}
        assert self.online is not None  # a snapshot was taken in
        eo_now, xyz_now = self.online.estimates()
        m = self.online.m
        src, dst = [], []
        for i, pid in enumerate(block.photos.ids):
            u = m.photo_at.get(pid)
            if u is not None and m.photo_in[u] and np.isfinite(block.photos.eo[i]).all():
                src.append(block.photos.eo[i, :3])
                dst.append(eo_now[u, :3])
        for j, pid in enumerate(block.points.ids):
            u = m.point_at.get(pid)
            if u is not None and np.isfinite(xyz_now[u]).all() and \
                    np.isfinite(block.points.xyz[j]).all():
                src.append(block.points.xyz[j])
                dst.append(xyz_now[u])
        out: dict[str, np.ndarray | None] = {}
        given = {pid: block.photos.eo[i] for i, pid in enumerate(block.photos.ids)}
        if len(src) < 3:
            return {p: None for p in fresh}
        s, r, t = similarity(np.array(src), np.array(dst))
        for p in fresh:
            e = given[p]
            if not np.isfinite(e).all():
                out[p] = None
                continue
            rot = r @ rotation_matrix(*e[3:])
            out[p] = np.concatenate([s * r @ e[:3] + t, angles_from_matrix(rot)])
        return out

    # ---------------------------------------------------------------- results
    def table(self) -> pd.DataFrame:
        """watch.csv: the snapshot, then replay.csv's columns (online/replay.py)."""
        parts = []
        for name, a in self.rows:
            t = tests_table([a])
            t.insert(0, "snapshot", name)
            parts.append(t)
        if not parts:
            return pd.DataFrame(columns=list(WATCH_COLUMNS))
        return pd.concat(parts, ignore_index=True)

    def summary_lines(self) -> list[str]:
        tested = sum(len(a.tested) for _, a in self.rows)
        rej = sum(t.verdict == "reject" for _, a in self.rows for t in a.tested)
        out = [f"watch: {len(self.done)} snapshot(s) taken in, {len(self.rows)} steps, "
               f"{tested} components tested, {rej} rejected when they were taken in"]
        if self._failed:
            out.append(f"not readable yet: {', '.join(sorted(self._failed))}")
        return out + self.notes


def _observations(block: Block) -> dict:
    """{(photo id, point id): (x, y, sigma µm)} of a snapshot's image points."""
    im = block.image
    ph, pt = block.photos.ids, block.points.ids
    sig = np.sqrt(np.mean(im.sigma_xy ** 2, axis=1)) * 1e3
    return {(ph[int(im.photo[r])], pt[int(im.point[r])]):
            (float(im.xy_mm[r, 0]), float(im.xy_mm[r, 1]), float(sig[r]))
            for r in range(len(im))}


def watch(folder: str | Path, tests: TestOptions | None = None, *,
          read: Callable[[Path], Block] | None = None, once: bool = False,
          interval: float = INTERVAL, max_rows: int = MAX_ROWS, retries: int = RETRIES,
          progress: Callable[[str, Answer], None] | None = None) -> Watch:
    """Watch `folder` (module docstring) until interrupted, or, `once`, until every snapshot
    in it is taken in; returns the Watch (its `online` bundle is the block now)."""
    w = Watch(Path(folder), tests, read, max_rows, retries, progress)
    w.run(interval, once)
    return w
