"""The screening chain: photo pairs, strip formation, control; then the cleaned block.

    result = screen(block)                 # ScreeningResult: .block (cleaned), .log
    qc = screen_and_snoop(block)[1]        # bundle adjustment and data snooping after it
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from baarda.block.photo_block import Block, GroundPoints
from baarda.options import ScreeningOptions, TestOptions
from baarda.quality.assessment import Assessment
from baarda.screening.control import ControlCheck, screen_control
from baarda.screening.log import Entry, ScreeningLog
from baarda.screening.pairs import PairTest, screen_pairs
from baarda.screening.separable import snoop_separable
from baarda.screening.strips import Strip, screen_strips


@dataclass(frozen=True)
class ScreeningResult:
    block: Block  # the cleaned block
    original: Block
    image_keep: np.ndarray  # (m,) rows of original.image kept
    control_removed: list[int]  # point indices whose control was removed
    log: ScreeningLog
    pairs: list[PairTest] = field(default_factory=list)
    strips: list[Strip] = field(default_factory=list)
    control: list[ControlCheck] = field(default_factory=list)

    def summary(self) -> str:
        return self.log.summary()


def _one_ray(block: Block, keep: np.ndarray, log: ScreeningLog,
             control_removed: set[int]) -> None:
    """Remove the last ray of points that screening left with one (it cannot be used)."""
    im, pts = block.image, block.points
    rays = np.bincount(im.point[keep], minlength=len(pts))
    full = np.all(pts.controlled, axis=1)
    full[list(control_removed)] = False
    orphans = (rays == 1) & ~full & (np.bincount(im.point, minlength=len(pts)) > 1)
    for row in np.flatnonzero(keep & orphans[im.point]):
        keep[row] = False
        log.add(Entry(0, "after screening", "image", pts.ids[im.point[row]],
                      block.photos.ids[im.photo[row]],
                      reason="the other rays of the point were removed: one ray cannot be "
                             "intersected"))


def cleaned_block(block: Block, keep: np.ndarray, control_removed: set[int] | list[int]) -> Block:
    """The block without the removed image points; removed control becomes a tie point."""
    out = block.select_image(np.asarray(keep, bool))
    pts = block.points
    ctrl = sorted(control_removed)
    if ctrl:
        role, xyz, sig = pts.role.copy(), pts.xyz.copy(), pts.sigma.copy()
        role[ctrl] = "tie"
        xyz[ctrl] = np.nan
        sig[ctrl] = np.nan
        out = replace(out, points=GroundPoints(list(pts.ids), xyz, sig, role))
    out.notes.append(f"screened: {int(np.sum(~np.asarray(keep)))} image point(s) and "
                     f"{len(ctrl)} control point(s) removed")
    return out


def screen(block: Block, options: ScreeningOptions | None = None,
           progress: Callable[[str], None] | None = None) -> ScreeningResult:
    """Run the screening stages on `block` (not modified); returns the cleaned block and log."""
    opt = options or ScreeningOptions()
    say = progress or (lambda m: None)
    tests = opt.resolved_tests(block.settings)
    log = ScreeningLog()
    keep = np.ones(len(block.image), bool)
    pairs: list[PairTest] = []
    strips: list[Strip] = []
    checks: list[ControlCheck] = []
    bad: set[int] = set()
    if 1 in opt.stages:
        keep, pairs = screen_pairs(block, keep, log, kind=opt.pair_transform,
                                   statistic=opt.pair_statistic,
                                   tests=TestOptions(opt.pair_alpha0, tests.beta0),
                                   min_redundancy=opt.pair_min_redundancy,
                                   tolerance_mm=opt.pair_tolerance_mm)
        say(f"stage 1: {len(pairs)} photo pairs, {len(log.removed('image', 1))} image "
            "point(s) removed")
    if 2 in opt.stages or 3 in opt.stages:
        keep2, strips = screen_strips(block, keep, log, tests=tests,
                                      rho_max=opt.rho_max)
        if 2 in opt.stages:
            keep = keep2
            say(f"stage 2: {len(strips)} strip(s) formed, "
                f"{len(log.removed('image', 2))} image point(s) removed")
        else:  # strips formed only for the control check: their decisions are not kept
            log.entries = [e for e in log.entries if e.stage != 2]
    if 3 in opt.stages:
        bad, checks = screen_control(block, strips, log, tests=tests)
        say(f"stage 3: {len(checks)} strip(s) checked, {len(bad)} control point(s) removed")
    _one_ray(block, keep, log, bad)
    return ScreeningResult(cleaned_block(block, keep, bad), block, keep, sorted(bad), log,
                           pairs, strips, checks)


def screen_and_snoop(block: Block, options: ScreeningOptions | None = None, *,
                     statistic: str = "w", progress: Callable[[str], None] | None = None
                     ) -> tuple[ScreeningResult, Assessment]:
    """Screening, then bundle adjustment with data snooping of the cleaned block.

    The snooping removes what it rejects together with the observations it cannot tell from
    it (screening/separable.py); its removals are added to the log (stage 4).  The returned
    ScreeningResult's block is the block after both.
    """
    res = screen(block, options, progress)
    opt = options or ScreeningOptions()
    tests = opt.resolved_tests(block.settings)
    qc, final, _ = snoop_separable(res.block, res.log, tests=tests, rho_max=opt.rho_max,
                                   statistic=statistic, progress=progress)
    return replace(res, block=final), qc
