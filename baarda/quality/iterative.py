"""Iterative data snooping: reject the largest significant |w|, re-adjust, repeat.

Rejected components stay in the observation vector as predicted residuals and are tested
at every iteration; one that is no longer significant comes back (once).  Rejection by
component or by group (both coordinates of an image point).

Every re-adjustment is checked: when removing a component leaves the block undetermined
(a datum defect, a point or photo without enough observations) or makes the adjustment
diverge, that removal is not taken: the component stays in, the log says so ("kept") and
why, and snooping goes on from the last sound adjustment with the next candidate.  A run
that reaches its step limit says how many components are still significant.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from baarda.errors import GeometryError
from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.quality.adjusted_model import AdjustedModel
from baarda.quality.statistics import QualityResult, analyse, with_separability


@dataclass(frozen=True)
class SnoopingStep:
    """One decision: `value` of the test `statistic` ("w", "tau"; or the method that rejected
    before snooping, e.g. "Danish method", iteration 0) of the component that decided;
    mdb in the model's units (image mm, control m)."""

    iteration: int
    sigma0: float
    action: str  # "reject", "restore", or "kept" (its removal was refused: `reason`)
    rows: list[int]
    labels: list[str]
    value: float
    mdb: float
    statistic: str = "w"
    reason: str = ""  # why a removal (or restoration) was not taken

    @property
    def w(self) -> float:  # the name of the value before tau and robust starts were logged
        return self.value

    def to_dict(self) -> dict:
        return {"iteration": self.iteration, "sigma0": self.sigma0, "action": self.action,
                "observations": self.labels, "statistic": self.statistic,
                "value": self.value, "mdb": self.mdb,
                **({"reason": self.reason} if self.reason else {})}

    def line(self) -> str:
        by = (f"{self.statistic} = {self.value:.2f}" if self.statistic in ("w", "tau") else
              f"by the {self.statistic} (w = {self.value:.2f})")
        return (f"  {self.iteration:3d} {self.action:7s} {'; '.join(self.labels)}  {by}  "
                f"sigma0 {self.sigma0:.3f}" + (f": {self.reason}" if self.reason else ""))


@dataclass(frozen=True)
class SnoopingRun:
    model: AdjustedModel
    quality: QualityResult
    active: np.ndarray
    log: list[SnoopingStep] = field(default_factory=list)
    converged: bool = True
    statistic: str = "w"
    remaining: int = 0  # components still significant when the step limit stopped it

    @property
    def rejected(self) -> np.ndarray:
        return ~self.active

    @property
    def refused(self) -> list[SnoopingStep]:
        """The removals (and restorations) that were not taken, with their reasons."""
        return [s for s in self.log if s.action == "kept"]

    @property
    def incomplete(self) -> str:
        """'' when snooping ended by itself, else what is left, in words."""
        if self.converged:
            return ""
        steps = sum(s.iteration > 0 and s.action != "kept" for s in self.log)
        return (f"snooping incomplete: {self.remaining} component(s) still significant when "
                f"it stopped at its limit of {steps} step(s); the last adjustment is reported")

    def summary_lines(self) -> list[str]:
        """The snooping log for people: one line per step."""
        before = [s for s in self.log if s.iteration == 0]
        steps = sum(s.iteration > 0 and s.action != "kept" for s in self.log)
        kept = len(self.refused)
        test = ("Baarda's w (sigma0 a priori)" if self.statistic == "w" else
                f"Pope's tau (sigma0 a posteriori), critical |tau| {self.quality.k_tau:.3f}")
        lines = [self.incomplete.upper()] if self.incomplete else []
        lines += [f"data snooping with {test}: " + (
            f"{len(before)} rejected by the {before[0].statistic} first, " if before else "")
            + f"{steps} step(s), {int(np.sum(~self.active))} rejected in the end"
            + (f"; {kept} removal(s) refused (the adjustment without them would fail)"
               if kept else "")]
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
    kept_why: dict[int, str] = {}
    log: list[SnoopingStep] = []
    for it in range(1, max_iterations + 1):
        q = analyse(model, tests, separability=False)
        stat = q.w if statistic == "w" else q.tau
        crit = q.k_w if statistic == "w" else q.k_tau
        mag = np.abs(np.nan_to_num(stat))
        if it == 1 and started_by:
            log += [SnoopingStep(0, q.sigma0_hat, "reject", [int(i)], [label(model, int(i))],
                                 float(q.w[i]), float(q.mdb[i]), started_by)
                    for i in started]
        q.notes.extend(f"{label(model, i)}: |{statistic}| = {mag[i]:.2f} is significant but it "
                       f"cannot be tested by removing it: {kept_why[int(i)]}"
                       for i in np.flatnonzero(needed & (mag > crit)))
        cand = np.flatnonzero(active & ~needed & q.controlled & (mag > crit))
        while len(cand):
            i = int(cand[np.argmax(mag[cand])])
            rows = [i]
            if by_group and model.group[i] >= 0:
                rows = list(np.flatnonzero(model.group == model.group[i]))
            trial = active.copy()
            trial[rows] = False
            new, why = _refit(model, trial)
            step = SnoopingStep(it, q.sigma0_hat, "kept" if why else "reject", rows,
                                [label(model, r) for r in rows], float(stat[i]),
                                float(q.mdb[i]), statistic, why)
            log.append(step)
            if why:
                # without it the block is undetermined or the adjustment fails: keep those
                # components, say so, and go on with the next candidate
                needed[rows] = True
                kept_why.update((int(r), why) for r in rows)
                say(f"snooping {it}: {step.labels[0]} kept: {why}")
                cand = cand[~np.isin(cand, rows)]
                continue
            say(f"snooping {it}: sigma0 {q.sigma0_hat:.3f}, reject {step.labels[0]}"
                f"{' (+ group)' if len(rows) > 1 else ''}: {statistic} = {stat[i]:.2f}")
            active, model = trial, new
            break
        else:
            back = np.flatnonzero(~active & q.controlled & (mag < crit))
            back = np.array([b for b in back if int(b) not in restored], dtype=int)
            if not len(back):
                return SnoopingRun(model, with_separability(model, q), active, log, True,
                                   statistic)
            i = int(back[np.argmin(mag[back])])
            rows = [i]
            if by_group and model.group[i] >= 0:
                rows = [r for r in np.flatnonzero(model.group == model.group[i])
                        if not active[r]]
                if np.any(mag[rows] >= crit):
                    rows = [i]
            trial = active.copy()
            trial[rows] = True
            restored.update(int(r) for r in rows)
            new, why = _refit(model, trial)
            log.append(SnoopingStep(it, q.sigma0_hat, "kept" if why else "restore", rows,
                                    [label(model, r) for r in rows], float(stat[i]),
                                    float(q.mdb[i]), statistic,
                                    f"not restored: {why}" if why else ""))
            if why:
                say(f"snooping {it}: {label(model, i)} not restored: {why}")
                continue
            say(f"snooping {it}: restore {label(model, i)}: {statistic} = {stat[i]:.2f}")
            active, model = trial, new
    q = analyse(model, tests)
    stat = q.w if statistic == "w" else q.tau
    crit = q.k_w if statistic == "w" else q.k_tau
    left = active & ~needed & q.controlled & (np.abs(np.nan_to_num(stat)) > crit)
    return SnoopingRun(model, q, active, log, False, statistic, int(np.sum(left)))


def _refit(model: AdjustedModel, active: np.ndarray) -> tuple[AdjustedModel | None, str]:
    """(the model adjusted again with `active`, ''), or (None, why it cannot be): the block
    would be undetermined, or the adjustment does not converge."""
    try:
        new = model.refit(active, model.factors)
    except GeometryError as err:
        return None, f"without it {err}"
    if not new.converged:
        return None, ("the adjustment without it does not converge ("
                      f"{new.convergence_note})")
    return new, ""
