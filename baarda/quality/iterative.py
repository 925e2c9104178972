"""Iterative data snooping: reject the largest significant |w|, re-adjust, repeat.

Rejected components stay in the observation vector as predicted residuals and are tested
at every iteration; one that is no longer significant comes back (once).  Rejection by
component or by group (both coordinates of an image point).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from baarda.errors import GeometryError
from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.quality.adjusted_model import AdjustedModel
from baarda.quality.statistics import QualityResult, analyse


@dataclass(frozen=True)
class SnoopingStep:
    """One decision: `value` of the test `statistic` ("w", "tau"; or the method that rejected
    before snooping, e.g. "Danish method", iteration 0) of the component that decided;
    mdb in the model's units (image mm, control m)."""

    iteration: int
    sigma0: float
    action: str  # "reject" or "restore"
    rows: list[int]
    labels: list[str]
    value: float
    mdb: float
    statistic: str = "w"

    @property
    def w(self) -> float:  # the name of the value before tau and robust starts were logged
        return self.value

    def to_dict(self) -> dict:
        return {"iteration": self.iteration, "sigma0": self.sigma0, "action": self.action,
                "observations": self.labels, "statistic": self.statistic,
                "value": self.value, "mdb": self.mdb}

    def line(self) -> str:
        by = (f"{self.statistic} = {self.value:.2f}" if self.statistic in ("w", "tau") else
              f"by the {self.statistic} (w = {self.value:.2f})")
        return (f"  {self.iteration:3d} {self.action:7s} {'; '.join(self.labels)}  {by}  "
                f"sigma0 {self.sigma0:.3f}")


@dataclass(frozen=True)
class SnoopingRun:
    model: AdjustedModel
    quality: QualityResult
    active: np.ndarray
    log: list[SnoopingStep] = field(default_factory=list)
    converged: bool = True
    statistic: str = "w"

    @property
    def rejected(self) -> np.ndarray:
        return ~self.active

    def summary_lines(self) -> list[str]:
        """The snooping log for people: one line per step."""
        before = [s for s in self.log if s.iteration == 0]
        steps = len(self.log) - len(before)
        test = ("Baarda's w (sigma0 a priori)" if self.statistic == "w" else
                f"Pope's tau (sigma0 a posteriori), critical |tau| {self.quality.k_tau:.3f}")
        lines = [f"data snooping with {test}: " + (
            f"{len(before)} rejected by the {before[0].statistic} first, " if before else "")
            + f"{steps} step(s), {int(np.sum(~self.active))} rejected in the end"]
        lines += [s.line() for s in self.log]
        return lines


def label(model: AdjustedModel, i: int) -> str:
    parts = [str(model.kind[i])]
    if model.frame[i]:
        parts.append(f"photo {model.frame[i]}" if model.kind[i] in ("image", "gnss", "imu")
                     else str(model.frame[i]))
    if model.point[i] or model.kind[i] not in ("gnss", "imu"):
        parts.append(f"point {model.point[i]}")
    parts.append(str(model.component[i]))
    return " ".join(parts)


def iterative_snooping(model: AdjustedModel, tests: TestOptions = DEFAULT_TESTS, *,
                       active: np.ndarray | None = None, statistic: str = "w",
                       by_group: bool = False, max_iterations: int = 200,
                       started_by: str = "",
                       progress: Callable[[str], None] | None = None) -> SnoopingRun:
    """Run Baarda's iterative data snooping with the w-test ("w") or Pope's tau ("tau").

    Starts from `model` (adjusted again first when `active`, the components to start with,
    differs from its own) and re-adjusts it by `model.refit` after every rejection or
    restoration; `model` itself is not changed.  `started_by`: what switched off the
    components that `active` leaves out (e.g. "Danish method"): they are then logged as
    rejections of step 0 with their w in the first adjustment.
    """
    if statistic not in ("w", "tau"):
        raise ValueError("statistic must be 'w' or 'tau'")
    say = progress or (lambda m: None)
    active = np.array(model.active if active is None else active, bool)
    started = np.flatnonzero(model.active & ~active)
    if not np.array_equal(active, model.active):
        model = model.refit(active, model.factors)
    restored: set[int] = set()
    needed = np.zeros(len(active), bool)  # cannot be rejected: the block needs them
    log: list[SnoopingStep] = []
    for it in range(1, max_iterations + 1):
        q = analyse(model, tests)
        stat = q.w if statistic == "w" else q.tau
        crit = q.k_w if statistic == "w" else q.k_tau
        mag = np.abs(np.nan_to_num(stat))
        if it == 1 and started_by:
            log += [SnoopingStep(0, q.sigma0_hat, "reject", [int(i)], [label(model, int(i))],
                                 float(q.w[i]), float(q.mdb[i]), started_by)
                    for i in started]
        q.notes.extend(f"{label(model, i)}: |{statistic}| = {mag[i]:.2f} is significant but it "
                       "cannot be rejected: the block would be undetermined without it"
                       for i in np.flatnonzero(needed & (mag > crit)))
        cand = np.flatnonzero(active & ~needed & q.controlled & (mag > crit))
        while len(cand):
            i = int(cand[np.argmax(mag[cand])])
            rows = [i]
            if by_group and model.group[i] >= 0:
                rows = list(np.flatnonzero(model.group == model.group[i]))
            trial = active.copy()
            trial[rows] = False
            try:
                new = model.refit(trial, model.factors)
            except GeometryError as err:
                # without it the block is undetermined (datum, a point or a photo): keep
                # those components, say so, and go on with the next candidate
                needed[rows] = True
                say(f"snooping {it}: {label(model, i)} kept: without it {err}")
                q.notes.append(f"{label(model, i)}: |{statistic}| = {mag[i]:.2f} is "
                               "significant but it cannot be rejected: the block would be "
                               "undetermined without it")
                cand = cand[~np.isin(cand, rows)]
                continue
            step = SnoopingStep(it, q.sigma0_hat, "reject", rows,
                                [label(model, r) for r in rows], float(stat[i]),
                                float(q.mdb[i]), statistic)
            log.append(step)
            say(f"snooping {it}: sigma0 {q.sigma0_hat:.3f}, reject {step.labels[0]}"
                f"{' (+ group)' if len(rows) > 1 else ''}: {statistic} = {stat[i]:.2f}")
            active, model = trial, new
            break
        else:
            back = np.flatnonzero(~active & q.controlled & (mag < crit))
            back = np.array([b for b in back if int(b) not in restored], dtype=int)
            if not len(back):
                return SnoopingRun(model, q, active, log, True, statistic)
            i = int(back[np.argmin(mag[back])])
            rows = [i]
            if by_group and model.group[i] >= 0:
                rows = [r for r in np.flatnonzero(model.group == model.group[i])
                        if not active[r]]
                if np.any(mag[rows] >= crit):
                    rows = [i]
            active = active.copy()
            active[rows] = True
            restored.update(int(r) for r in rows)
            log.append(SnoopingStep(it, q.sigma0_hat, "restore", rows,
                                    [label(model, r) for r in rows], float(stat[i]),
                                    float(q.mdb[i]), statistic))
            say(f"snooping {it}: restore {label(model, i)}: {statistic} = {stat[i]:.2f}")
            model = model.refit(active, model.factors)
    q = analyse(model, tests)
    return SnoopingRun(model, q, active, log, False, statistic)
