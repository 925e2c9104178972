"""Bundle data snooping after screening, with the same separability rule as stage 2.

baarda.bundle.bundle_quality.snoop rejects one component at a time.  Here every rejection is then
examined in the adjustment with that component put back: the observations whose w-tests it
cannot be told from (|rho| >= rho_max, quality.statistics.w_correlation) are removed with it,
since the error may be in any of them (two rays of a point, two control heights that one
condition checks).  Image observations are removed as whole image points (x and y), control
observations by coordinate.  The block is then adjusted and snooped again, until nothing is
rejected.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import cast

import numpy as np

from baarda.block.photo_block import Block, GroundPoints
from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.bundle_quality import snoop
from baarda.options import TestOptions
from baarda.quality.assessment import Assessment
from baarda.quality.iterative import label
from baarda.quality.statistics import w_correlation
from baarda.screening.log import Entry, ScreeningLog

STAGE = 4


def partners(qc: Assessment, i: int, rho_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Active components whose w-tests cannot be told from that of rejected component i.

    Adjusts again with i put back (the other rejections stay) and returns (indices, rho).
    """
    act = qc.quality.active.copy()
    act[i] = True
    model = qc.model.refit(act)
    rho = w_correlation(model, i)
    idx = np.flatnonzero(model.active & (np.abs(rho) >= rho_max))
    idx = idx[idx != i]
    return idx, rho[idx]


def without(block: Block, rows: set[int], control: set[tuple[int, int]]) -> Block:
    """The block without image rows `rows` and control coordinates (point, axis)."""
    keep = np.ones(len(block.image), bool)
    keep[list(rows)] = False
    out = block.select_image(keep)
    if control:
        pts = block.points
        sig, role, xyz = pts.sigma.copy(), pts.role.copy(), pts.xyz.copy()
        for p, k in control:
            sig[p, k] = np.nan
        gone = (role == "control") & ~np.isfinite(sig).any(axis=1)
        role[gone], xyz[gone] = "tie", np.nan
        out = replace(out, points=GroundPoints(list(pts.ids), xyz, sig, role))
    return out


def snoop_separable(block: Block, log: ScreeningLog | None = None, *,
                    tests: TestOptions | None = None,
                    rho_max: float = 0.9, statistic: str = "w", max_passes: int = 6,
                    progress: Callable[[str], None] | None = None
                    ) -> tuple[Assessment, Block, ScreeningLog]:
    """Snoop `block`; returns the final snooping (nothing left to reject), the block without
    the removed observations, and the log of the removals (stage 4, 'bundle snooping')."""
    log = log if log is not None else ScreeningLog()
    say = progress or (lambda m: None)
    index = np.arange(len(block.image))  # current rows -> rows of `block`
    rows: set[int] = set()
    ctrl: set[tuple[int, int]] = set()
    current = block
    for npass in range(1, max_passes + 1):
        qc = snoop(BundleProblem(current), tests, statistic=statistic)
        m, q = cast(BundleModel, qc.model), qc.quality
        rejected = np.flatnonzero(~q.active)
        if not len(rejected) or npass == max_passes:
            if len(rejected):
                log.note(STAGE, f"pass {npass}", "stopped: still rejecting after "
                         f"{max_passes} passes")
            return qc, current, log
        ctx = f"bundle, pass {npass}"
        say(f"bundle snooping pass {npass}: {len(rejected)} rejected")
        for i in rejected:
            others, rho = partners(qc, int(i), rho_max)
            together = "" if not len(others) else (
                f"; not separable from {len(others)} other observation(s), removed with it")
            for j, r in [(int(i), 1.0), *zip(others.tolist(), rho.tolist(), strict=True)]:
                _remove(current, m, j, index, rows, ctrl, log, ctx,
                        float(q.w[i]) if j == i else float("nan"), float(q.k_w),
                        ("rejected by data snooping" + together) if j == i else
                        f"not separable from {label(m, int(i))} (rho = {r:.2f})")
        keep = ~np.isin(np.arange(len(block.image)), list(rows))
        index = np.flatnonzero(keep)
        current = without(block, rows, ctrl)
    return qc, current, log  # pragma: no cover


def _remove(block: Block, m: BundleModel, j: int, index: np.ndarray, rows: set[int],
            ctrl: set[tuple[int, int]], log: ScreeningLog, ctx: str, w: float, crit: float,
            reason: str) -> None:
    if m.kind[j] == "image":
        row = int(index[m.image_row[j]])
        if row in rows:
            return
        rows.add(row)
        log.add(Entry(STAGE, ctx, "image", str(m.point[j]), str(m.frame[j]),
                      statistic="w" if np.isfinite(w) else "", value=w, critical=crit,
                      reason=f"{m.component[j]}: {reason}"))
    else:
        key = (int(m.control_index[j]), "XYZ".index(m.component[j]))
        if key in ctrl:
            return
        ctrl.add(key)
        log.add(Entry(STAGE, ctx, "control", str(m.point[j]),
                      statistic="w" if np.isfinite(w) else "", value=w, critical=crit,
                      reason=f"{m.component[j]}: {reason}"))
