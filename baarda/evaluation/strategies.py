"""The detection strategies a study compares (evaluation/study.py): each run on a blundered
block, each saying what it rejected in the end, in order (an Outcome).

`snoop` (iterative w-test), `tau` (Pope's tau), `by-point`, `grouped`, `robust` (Danish
method, then snooping): data snooping in its variants (quality/iterative.py); `screen`
(sequential screening, then snooping), `modified` (Gruen's modified snooping, one pass),
`threshold` (iteratively reject the largest |v| / sigma above THRESHOLD: no redundancy
numbers), `online` (the on-line replay whose operator takes out what is rejected, or sets
its point aside, online/replay.py), `online-remeasure` (the same operator measures a
rejected image point again and gets its value without the blunder: nothing good is lost).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from baarda.block.photo_block import Block
from baarda.bundle.bundle_model import BundleModel
from baarda.options import TestOptions
from baarda.pipeline import adjust, snoop

STRATEGIES = ("snoop", "tau", "by-point", "grouped", "robust", "screen", "modified",
              "threshold", "online", "online-remeasure")
DEFAULT_STRATEGIES = ("snoop", "tau", "by-point", "robust")
THRESHOLD = 3.0  # |v| / sigma a priori of the `threshold` strategy

Key = tuple[str, str, str, str]  # kind, photo, point, component



def component_keys(model) -> list[Key]:
    """(kind, photo, point, component) of every component of a model."""
    return [(str(k), str(f), str(p), str(c)) for k, f, p, c in zip(
        model.kind, model.frame, model.point, model.component, strict=True)]


@dataclass(frozen=True)
class Outcome:
    """What a strategy did: the keys it rejected in the end (alone or with a group rejected
    or set aside as a whole), in order; those of its first rejection (a group's together);
    sigma0 at the end; `strict`: those rejected by their own test (not only as a member of
    a group: `grouped`'s partners, the on-line points set aside, the rays measured again
    with a rejected one), None: every one."""

    rejected: list[Key]
    first: set[Key]
    sigma0: float
    entry: dict | None = None  # the on-line strategy: each component's verdict when taken in
    strict: set[Key] | None = None

    @property
    def located_strictly(self) -> set[Key]:
        return set(self.rejected) if self.strict is None else self.strict & set(self.rejected)


def _snooping_order(a) -> Outcome:
    """Keys finally rejected by a snooping run, in the order of their last rejection (a
    group's members with it), the first rejection's keys, and the final sigma0."""
    keys = component_keys(a.model)
    rejected = set(np.flatnonzero(~a.quality.active).tolist())
    order: dict[int, int] = {}
    steps = a.run.log if a.run is not None else []
    first: set[Key] = set()
    own: set[int] = set()  # rejected by their own test (a group's partners are not)
    for n, step in enumerate(steps):
        if step.action == "reject":
            rows = list(step.rows) + (list(step.partners) if step.grouped else [])
            own.update(step.rows)
            for r in rows:
                order[r] = n
            if not first:
                first = {keys[r] for r in rows}
    ranked = sorted(rejected, key=lambda r: (order.get(r, -1), r))
    return Outcome([keys[r] for r in ranked], first, float(a.adjustment.sigma0),
                   strict={keys[r] for r in rejected & own})


def _outcome(keys: list[Key], sigma0: float) -> Outcome:
    return Outcome(keys, set(keys[:1]), sigma0)


def _threshold(block: Block) -> Outcome:
    res = adjust(block)
    model = BundleModel(res)
    active = np.ones(model.n, bool)
    out = []
    for _ in range(200):
        z = np.where(active, np.abs(model.residuals) / model.sigma_apriori, -np.inf)
        i = int(np.argmax(z))
        if z[i] <= THRESHOLD:
            break
        active[i] = False
        out.append(i)
        res = res.refit(active)
        model = BundleModel(res)
    keys = component_keys(model)
    return _outcome([keys[i] for i in out], float(res.sigma0))


def _screen(block: Block, tests: TestOptions) -> Outcome:
    """Screening, then snooping that removes what it rejects from the block
    (pipeline.screen): what the final block lacks of the original, in the original's order,
    then what the final assessment marks rejected."""
    from baarda.options import ScreeningOptions
    from baarda.pipeline import screen

    res, a = screen(block, ScreeningOptions(tests=tests), snoop=True)
    orig, final = res.original, a.adjustment.block
    fi, fp = final.image, final.points
    kept = set(zip((final.photos.ids[i] for i in fi.photo),
                   (fp.ids[j] for j in fi.point), strict=True))
    im, pts = orig.image, orig.points
    out: list[Key] = []
    for row in range(len(im)):
        ph, pt = orig.photos.ids[im.photo[row]], pts.ids[im.point[row]]
        if (ph, pt) not in kept:
            out += [("image", ph, pt, "x"), ("image", ph, pt, "y")]
    fctrl = {fp.ids[j]: fp.controlled[j] for j in range(len(fp))}
    for j in np.flatnonzero(pts.controlled.any(axis=1)):
        now = fctrl.get(pts.ids[j], np.zeros(3, bool))
        out += [("control", "", pts.ids[j], c) for k, c in enumerate("XYZ")
                if pts.controlled[j, k] and not now[k]]
    snooped = _snooping_order(a)
    seen = set(out)
    return _outcome(out + [k for k in snooped.rejected if k not in seen], snooped.sigma0)


def _modified(block: Block, tests: TestOptions) -> Outcome:
    from baarda.planning.modified_snoop import modified_snoop

    res = adjust(block)
    ms = modified_snoop(res, tests=tests)
    keys = component_keys(ms.model)
    rej = np.flatnonzero(ms.result.rejected)
    order = rej[np.argsort(-np.abs(ms.result.statistic_value[rej]), kind="stable")]
    return _outcome([keys[i] for i in order], float(res.sigma0))


def _online(block: Block, tests: TestOptions, clean: Block | None = None) -> Outcome:
    """The on-line replay with re-measurement (online/replay.py): the rejected components
    measured again (with `clean`: their value there) and taken out, in order (the first
    action's first), then those of the points set aside and never taken in again that the
    test could not tell apart; sigma0 of the block at the end, and the verdict of every
    component at the step it was taken in."""
    from baarda.online.replay import image_values, replay

    again: Callable[[str, str], tuple[float, float]] | None = None
    if clean is not None:  # the operator measures again and gets the value without blunder
        value = image_values(clean)

        def again(photo: str, point: str) -> tuple[float, float]:
            return value[(photo, point)]
    rp = replay(block, tests, remove="worst", remeasure=again)
    keys = [(kind, photo, point, comp) for _, kind, photo, point, comp, _ in rp.remeasured]
    keys += [(kind, photo, point, comp) for _, kind, photo, point, comp, _ in rp.removed]
    strict = set(keys) - set(rp.remeasured_along)  # not the rays measured again with one
    # the first action: one image point (its rejected components) or one control point
    acts = list(rp.remeasured) + list(rp.removed)
    first = {k for k, r in zip(keys, acts, strict=True) if r[:4] == acts[0][:4]}
    for _, group in rp.aside:  # set aside and never taken in again: flagged, all of them
        keys += list(group)
    entry: dict[Key, str] = {}
    for a in rp.answers:
        for t in a.tested:
            entry.setdefault((t.kind, t.photo, t.point, t.component), t.verdict)
    sigma0 = float(rp.online.result().adjustment.sigma0) if rp.online.started else np.nan
    return Outcome(keys, first, sigma0, entry, strict)


def run_strategy(name: str, block: Block, tests: TestOptions,
                 clean: Block | None = None) -> Outcome:
    """What one strategy rejected on a block (Outcome); clean: the block without its
    blunders (what `online-remeasure` measures again)."""
    if name == "online":
        return _online(block, tests)
    if name == "online-remeasure":
        if clean is None:
            raise ValueError("online-remeasure needs the block without its blunders")
        return _online(block, tests, clean)
    if name == "snoop":
        return _snooping_order(snoop(block, tests))
    if name == "tau":
        return _snooping_order(snoop(block, tests, statistic="tau"))
    if name == "by-point":
        return _snooping_order(snoop(block, tests, by_point=True))
    if name == "grouped":
        return _snooping_order(snoop(block, tests, inseparable="group"))
    if name == "robust":
        return _snooping_order(snoop(block, tests, robust=True))
    if name == "screen":
        return _screen(block, tests)
    if name == "modified":
        return _modified(block, tests)
    if name == "threshold":
        return _threshold(block)
    raise ValueError(f"unknown strategy '{name}'")
