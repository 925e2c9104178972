"""A finished block measured again on-line: photo by photo in strip order, every measurement
tested the moment it is taken in (`baarda online --bundle --replay PROJECT`).

The replay starts from the block's control and approximate orientations (GNSS and IMU rows
wait for their photos) and adds each photo with all its image points.  `remove="none"`
keeps every observation, so that the result is the adjustment of the whole block, as
`baarda adjust` gives it; `remove="worst"` acts as an operator who re-measures: after each
step, while an observation is rejected, the one with the largest |w| is taken out (an image
point with both coordinates) - unless the test cannot tell it from another ray of its
point (`OnlineBundle.inseparable`: the two rays of a two-ray point, the x of three rays
along one strip).  Then the point is set aside until its next ray, which may tell which ray
is wrong (`OnlineBundle.set_aside`); a point still set aside when the block is complete
stays out of it (re-measure it).  The replay study (docs/online.md) runs it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from baarda.block.photo_block import Block
from baarda.kinds import GNSS
from baarda.online.answers import UNITS, Answer
from baarda.online.bundle import MAX_ROWS, OnlineBundle
from baarda.options import TestOptions

COLUMNS = ("step", "kind", "photo", "point", "component", "w", "mdb", "unit", "redundancy",
           "verdict", "ms", "row", "before", "cause")
MAX_REMOVALS = 10  # re-measurements after one step, at most


def tests_table(answers) -> pd.DataFrame:
    """replay.csv (COLUMNS): one row per tested component of each answer (row "test": the
    step, what it is, w, MDB (in the kind's unit: µm for image coordinates, m for control
    and GNSS), r, the verdict and the step's time in ms), then one per verdict the step
    changed (row "change": the verdict before it, the new one with w, MDB and r after the
    step); cause: the step (its action and what it took in or out)."""
    rows = []
    for a in answers:
        cause = f"{a.action}: {a.what}"
        for t in a.tested:
            f, unit = UNITS.get(t.kind, (1.0, ""))
            rows.append((a.step, t.kind, t.photo, t.point, t.component, t.w, t.mdb * f,
                         unit, t.redundancy, t.verdict, 1e3 * a.seconds, "test", "", cause))
        for c in a.changed:
            f, unit = UNITS.get(c.kind, (1.0, ""))
            rows.append((a.step, c.kind, c.photo, c.point, c.component, c.w, c.mdb * f,
                         unit, c.redundancy, c.after, 1e3 * a.seconds, "change", c.before,
                         cause))
    return pd.DataFrame(rows, columns=list(COLUMNS))


def image_values(block: Block) -> dict[tuple[str, str], tuple[float, float]]:
    """{(photo, point): (x, y) mm} of every image point of a block (what `remeasure` of a
    simulation gives back: the block without its blunders)."""
    im, ids, pids = block.image, block.photos.ids, block.points.ids
    return {(ids[p], pids[q]): (float(x), float(y))
            for p, q, (x, y) in zip(im.photo, im.point, im.xy_mm, strict=True)}


def strip_order(block: Block) -> list[int]:
    """The photos in strip order: strips in the order they first appear, photos in the
    block's order within each."""
    strips = [str(s) for s in block.photos.strip]
    first = {s: n for n, s in reversed(list(enumerate(strips)))}
    return sorted(range(len(strips)), key=lambda i: (first[strips[i]], i))


@dataclass(frozen=True)
class Replay:
    """The answers of every step, the on-line bundle at the end, what was taken out
    (remove="worst": (step, kind, photo, point, component, w) of each removal, in order),
    and the points set aside and never taken in again (out of the final block), each with
    the components the test could not tell apart when it was set aside: ((point, ((kind,
    photo, point, component), ...)), ...)."""

    answers: tuple[Answer, ...]
    online: OnlineBundle
    removed: tuple[tuple, ...]
    seconds: float
    aside: tuple[tuple[str, tuple], ...] = ()
    remeasured: tuple[tuple, ...] = ()  # (step, kind, photo, point, component, w)
    # of those, the components measured again only with a rejected ray the test cannot
    # tell them from (not rejected themselves): (kind, photo, point, component)
    remeasured_along: tuple[tuple, ...] = ()

    def table(self) -> pd.DataFrame:
        """replay.csv (tests_table)."""
        return tests_table(self.answers)

    def summary_lines(self) -> list[str]:
        tested = sum(len(a.tested) for a in self.answers)
        rej = sum(t.verdict == "reject" for a in self.answers for t in a.tested)
        sus = sum(t.verdict == "suspect" for a in self.answers for t in a.tested)
        adds = [a.seconds for a in self.answers if a.action == "add" and a.tested]
        out = [f"replay: {len(self.answers)} steps, {tested} components tested, {rej} "
               f"rejected and {sus} not checked (suspect) when they were taken in; "
               f"{self.seconds:.2f} s" + (f", median {1e3 * float(np.median(adds)):.1f} ms "
                                           "per photo" if adds else "")]
        if self.remeasured:
            out.append(f"{len(self.remeasured)} rejected image point component(s) measured "
                       "again")
        if self.removed:
            out.append(f"{len(self.removed)} observation(s) taken out as rejected")
        if self.aside:
            out.append(f"{len(self.aside)} point(s) set aside and not taken in again (the "
                       "test cannot tell which of their rays is wrong: re-measure them): "
                       + ", ".join(p for p, _ in self.aside[:10])
                       + (" ..." if len(self.aside) > 10 else ""))
        return out


def replay(block: Block, tests: TestOptions | None = None, *, remove: str = "none",
           max_rows: int = MAX_ROWS, progress: Callable[[Answer], None] | None = None,
           remeasure: Callable[[str, str], tuple[float, float]] | None = None) -> Replay:
    """Replay a finished block (in its local frame, with approximations) photo by photo.

    remeasure (with remove="worst"): the operator's new measurement (x, y mm) of an image
    point (photo, point), e.g. a simulation's value without its blunder.  A rejected image
    point is then measured again (taken out and added with the new value, and tested),
    with the rays the test cannot tell it from, instead of being taken out or set aside; one
    rejected again after its re-measurement is kept: measured twice the same, it is
    confirmed (a false alarm, or an error the test puts on it from elsewhere)."""
    if remove not in ("none", "worst"):
        raise ValueError("remove: 'none' or 'worst'")
    if remeasure is not None and remove != "worst":
        raise ValueError("remeasure: with remove='worst'")
    t0 = time.perf_counter()
    im = block.image
    start = block.select_image(np.zeros(len(im), bool))
    ob = OnlineBundle(start, tests, max_rows=max_rows)
    answers: list[Answer] = []
    removed: list[tuple] = []
    aside: dict[str, tuple] = {}  # point set aside -> the components the test cannot tell
    again = _Again(remeasure, {(block.photos.ids[im.photo[r]], block.points.ids[im.point[r]]):
                               float(np.sqrt(np.mean(im.sigma_xy[r] ** 2)) * 1e3)
                               for r in range(len(im))}) if remeasure else None
    ids = block.points.ids
    for i in strip_order(block):
        rows = np.flatnonzero(im.photo == i)
        sig = im.sigma_xy
        pts = {ids[im.point[r]]: (float(im.xy_mm[r, 0]), float(im.xy_mm[r, 1]),
                                  float(np.sqrt(np.mean(sig[r] ** 2)) * 1e3)) for r in rows}
        a = ob.add_photo(block.photos.ids[i], pts)
        answers.append(a)
        if progress:
            progress(a)
        if remove == "worst":
            for b in _remeasure(ob, a, removed, aside, again):
                answers.append(b)
                if progress:
                    progress(b)
    still = tuple((p, keys) for p, keys in aside.items() if ob.waiting(p))
    return Replay(tuple(answers), ob, tuple(removed), time.perf_counter() - t0, still,
                  tuple(again.done) if again else (),
                  tuple(sorted(again.along)) if again else ())


@dataclass
class _Again:
    """The re-measurements of a replay: the operator's callback, each image point's sigma
    (µm), and what was measured again: (step, kind, photo, point, component, w)."""

    measure: Callable[[str, str], tuple[float, float]]
    sigma_um: dict
    done: list = field(default_factory=list)
    points: set = field(default_factory=set)  # (photo, point) of `done`
    along: set = field(default_factory=set)  # keys measured again only as a twin

    def measured(self, photo: str, point: str) -> bool:
        return (photo, point) in self.points


def _remeasure(ob: OnlineBundle, a: Answer, removed: list, aside: dict,
               again: _Again | None = None) -> list[Answer]:
    """Take out the worst rejected observation while there is one (the step's tested
    components and the verdicts it changed; an image point with both coordinates, both
    recorded where both are rejected); set its point aside instead where the test cannot
    tell it from another of the point's rays (aside: point -> those components)."""
    from baarda.errors import GeometryError

    out = []
    bad = {(t.kind, t.photo, t.point, t.component): t.w for t in a.tested
           if t.verdict == "reject"}
    _update(bad, a.changed)
    for _ in range(MAX_REMOVALS):
        bad = {k: v for k, v in bad.items() if ob.is_in(k[0], k[1], k[2])}
        if not bad:
            break
        key = max(bad, key=lambda k: abs(bad[k]))
        kind, photo, point, comp = key
        w = bad.pop(key)
        try:
            twins = [k for k, _ in ob.inseparable(*key) if k[0] == "image" and k[1] != photo] \
                if kind == "image" else []
            if again is not None and kind == "image":
                if again.measured(photo, point):
                    continue  # measured twice, the same: the operator keeps it (confirmed)
                along = {t for t in twins if t not in bad}  # not rejected themselves
                for k, wk in [(key, w)] + [(t, bad.pop(t, w)) for t in twins]:
                    done = _measure_again(ob, a.step, k, wk, again, bad)
                    if done and k in along:
                        again.along.add(k)
                    out += done
                continue
            if twins:
                b = ob.set_aside(point)
                aside[point] = (key, *twins)
                what = f"{b.what} (rejected: {comp} on photo {photo}, w {w:.2f}; the test " \
                    f"cannot tell it from {', '.join(f'{k[3]} on photo {k[1]}' for k in twins)})"
            else:
                if kind == "image":
                    b = ob.remove_image_point(photo, point)
                elif kind == "control":
                    b = ob.remove_control(point)
                elif kind == GNSS.name:
                    b = ob.remove_gnss(photo)
                else:
                    continue
                removed.append((a.step, kind, photo, point, comp, w))
                other = (kind, photo, point, "y" if comp == "x" else "x")
                if kind == "image" and other in bad:  # rejected too, and out with it
                    removed.append((a.step, *other, bad.pop(other)))
                what = f"{b.what} (rejected: w {w:.2f})"
        except GeometryError:  # the block would not be determined without it
            continue
        _update(bad, b.changed)
        out.append(replace(b, what=what))
    return out


def _measure_again(ob: OnlineBundle, step: int, key: tuple, w: float, again: _Again,
                   bad: dict) -> list[Answer]:
    """Image point `key` taken out and measured again (again.measure), its test and the
    verdicts the two steps changed folded into `bad`."""
    _, photo, point, comp = key
    if again.measured(photo, point) or not ob.is_in("image", photo, point):
        return []
    b = ob.remove_image_point(photo, point)
    _update(bad, b.changed)
    x, y = again.measure(photo, point)
    c = ob.add_image_point(photo, point, x, y, again.sigma_um[(photo, point)])
    again.done.append((step, "image", photo, point, comp, w))
    again.points.add((photo, point))
    for t in c.tested:
        k = (t.kind, t.photo, t.point, t.component)
        if t.verdict == "reject":
            bad[k] = t.w
        else:
            bad.pop(k, None)
    _update(bad, c.changed)
    return [replace(b, what=f"{b.what} (rejected: w {w:.2f}; measured again)"), c]


def _update(bad: dict, changed) -> None:
    for c in changed:
        key = (c.kind, c.photo, c.point, c.component)
        if c.after == "reject":
            bad[key] = c.w
        else:
            bad.pop(key, None)
