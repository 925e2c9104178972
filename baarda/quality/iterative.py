"""Iterative data snooping: reject the largest significant |w|, re-adjust, repeat.

Rejected components stay in the observation vector as predicted residuals and are tested
at every iteration; one that is no longer significant comes back (once).  Rejection by
component or by group (both coordinates of an image point).

Identification (Teunissen's DIA): before a rejection the candidate's w-test is correlated
with every other (one column of Qvv); the active tested components with |rho| >=
RHO_INSEPARABLE (0.99) cannot be told from it, and the step is logged "identified up to
{i, j}".  `inseparable` chooses the action: "flag" (default) rejects the largest |w| as
Baarda's rule does and flags the others as not separable; "group" rejects the whole group
when the adjustment without it is still determined (the adapted solution is then free of
the error whichever of them holds it; its members are not restored one by one: their
predicted residuals cannot tell them apart either), else falls back to "flag".  A component
rejected before a group that the group's rejection leaves unchecked (restored, its
redundancy number would be below R_MIN: the group held what tested it) is never restored:
its small |w| then says nothing, and the error it was rejected for would come back
unchecked (issue 44).  A rejection
that leaves another active component uncontrolled (its r drops below R_MIN) names it in its
step.

Every re-adjustment is checked: when removing a component leaves the block undetermined
(a datum defect, a point or photo without enough observations) or makes the adjustment
diverge, that removal is not taken: the component stays in, the log says so ("kept") and
why, and snooping goes on from the last sound adjustment with the next candidate.  A run
that reaches its step limit says how many components are still significant.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from baarda.errors import GeometryError
from baarda.kinds import kind_of
from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.quality.adjusted_model import AdjustedModel
from baarda.quality.separability import RHO_INSEPARABLE
from baarda.quality.statistics import (
    R_MIN,
    QualityResult,
    analyse,
    qvv_columns,
    with_separability,
)


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
    # identification: the components whose w-tests cannot be told from the decisive one
    # (|rho| >= RHO_INSEPARABLE), their correlations, and what was done with them
    partners: tuple[int, ...] = ()
    partner_labels: tuple[str, ...] = ()
    partner_rho: tuple[float, ...] = ()
    grouped: bool = False  # the partners were rejected too (inseparable="group")
    # active components this rejection left uncontrolled (r < R_MIN), in words
    uncontrolled: tuple[int, ...] = ()
    uncontrolled_words: tuple[str, ...] = ()

    @property
    def w(self) -> float:  # the name of the value before tau and robust starts were logged
        return self.value

    @property
    def group(self) -> list[str]:
        """The inseparable group: the decisive component(s) and their partners."""
        return [*self.labels, *(x for x in self.partner_labels if x not in self.labels)]

    def to_dict(self) -> dict:
        return {"iteration": self.iteration, "sigma0": self.sigma0, "action": self.action,
                "observations": self.labels, "statistic": self.statistic,
                "value": self.value, "mdb": self.mdb,
                **({"reason": self.reason} if self.reason else {}),
                **({"identified_up_to": self.group,
                    "rho": list(self.partner_rho),
                    "not_separable": [] if self.grouped else list(self.partner_labels)}
                   if self.partners else {}),
                **({"uncontrolled": list(self.uncontrolled_words)}
                   if self.uncontrolled else {})}

    def identification(self) -> str:
        """The inseparable group and what was done, in words ("" when there is none)."""
        if not self.partners:
            return ""
        rho = ", ".join(f"{r:+.4f}" for r in self.partner_rho)
        what = ("all rejected (the error may be in any of them)" if self.grouped else
                f"{'; '.join(self.partner_labels)} flagged: not separable (rho {rho}), the "
                "error may be there instead")
        return f"identified up to {{{', '.join(self.group)}}}: {what}"

    def line(self) -> str:
        by = (f"{self.statistic} = {self.value:.2f}" if self.statistic in ("w", "tau") else
              f"by the {self.statistic} (w = {self.value:.2f})")
        out = (f"  {self.iteration:3d} {self.action:7s} {'; '.join(self.labels)}  {by}  "
               f"sigma0 {self.sigma0:.3f}" + (f": {self.reason}" if self.reason else ""))
        if self.partners and self.action == "reject":
            out += "\n        " + self.identification()
        for words in self.uncontrolled_words:
            out += f"\n        {words}"
        return out


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
        groups = [s for s in self.log if s.partners and s.action == "reject"]
        if groups:
            lines.append(f"{len(groups)} rejection(s) identified only up to an inseparable "
                         "group (the error may be in the flagged partner: remeasure, or "
                         "--inseparable group)" if any(not s.grouped for s in groups) else
                         f"{len(groups)} inseparable group(s) rejected as a whole")
        return lines


def label(model: AdjustedModel, i: int | np.integer) -> str:
    parts, kind = [str(model.kind[i])], kind_of(model.kind[i])
    if model.frame[i]:
        parts.append(f"photo {model.frame[i]}" if kind.on_photo else str(model.frame[i]))
    if model.point[i] or kind.named_point:
        parts.append(f"point {model.point[i]}")
    parts.append(str(model.component[i]))
    return " ".join(parts)


INSEPARABLE = ("flag", "group")


def labels(model: AdjustedModel, rows: np.ndarray) -> list[str]:
    """label() of many rows at once (the same words, without a call per row)."""
    joined = joined_labels(model, rows)
    if joined is not None:
        return joined.to_pylist()
    rows = np.asarray(rows, np.int64)
    kind, frame, point, comp = (np.asarray(getattr(model, a), dtype=object)[rows].tolist()
                                for a in ("kind", "frame", "point", "component"))
    out = []
    for k, f, p, c in zip(kind, frame, point, comp, strict=True):
        kind = kind_of(k)
        fw = (f" photo {f}" if kind.on_photo else f" {f}") if f else ""
        pw = f" point {p}" if p or kind.named_point else ""
        out.append(f"{k}{fw}{pw} {c}")
    return out


def joined_labels(model: AdjustedModel, rows: np.ndarray, keep: np.ndarray | None = None):
    """`labels` as a pyarrow string array (chunked), joined in C: the partners of a million
    rows in a fraction of the time, without a Python string each; rows where `keep` is
    False get "".  None where a part is not text: then only `labels` says the words, row
    by row."""
    import pyarrow as pa
    import pyarrow.compute as pc

    rows = np.asarray(rows, np.int64)
    parts = [np.asarray(getattr(model, a), dtype=object)
             for a in ("kind", "frame", "point", "component")]
    out = []
    for r0 in range(0, len(rows), LABEL_ROWS):  # the parts of a chunk at a time
        at = rows[r0: r0 + LABEL_ROWS]
        chunk = _joined(*(a[at] for a in parts))
        if chunk is None:
            return None
        if keep is not None:
            chunk = pc.if_else(pa.array(keep[r0: r0 + LABEL_ROWS]), chunk, "")
        out.append(chunk)
    return pa.chunked_array(out, pa.string())


LABEL_ROWS = 1 << 16  # labels joined at a time (the parts of a chunk held, not the whole)


def _joined(*parts: np.ndarray):
    """`joined_labels` of the rows whose kind, frame, point and component are `parts`."""
    import pyarrow as pa
    import pyarrow.compute as pc

    try:
        k, f, p, c = (pa.array(a, pa.string()) for a in parts)
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        return None
    if any(a.null_count for a in (k, f, p, c)):
        return None
    codes = pc.dictionary_encode(k)
    kinds = [kind_of(name) for name in codes.dictionary.to_pylist()]
    at = codes.indices.to_numpy(zero_copy_only=False)
    on_photo = pa.array(np.array([x.on_photo for x in kinds], bool)[at])
    named = pa.array(np.array([x.named_point for x in kinds], bool)[at])
    fw = pc.if_else(pc.not_equal(f, ""), pc.binary_join_element_wise(
        pc.if_else(on_photo, " photo ", " "), f, ""), "")
    pw = pc.if_else(pc.or_(pc.not_equal(p, ""), named),
                    pc.binary_join_element_wise(" point ", p, ""), "")
    return pc.binary_join_element_wise(k, fw, pw, " ", c, "")


def iterative_snooping(model: AdjustedModel, tests: TestOptions = DEFAULT_TESTS, *,
                       active: np.ndarray | None = None, statistic: str = "w",
                       by_group: bool = False, max_iterations: int = 200,
                       started_by: str = "", inseparable: str = "flag",
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
    if inseparable not in INSEPARABLE:
        raise ValueError(f"inseparable must be one of {', '.join(INSEPARABLE)}")
    say = progress or (lambda m: None)
    active = np.array(model.active if active is None else active, bool)
    started = np.flatnonzero(model.active & ~active)
    if not np.array_equal(active, model.active):
        model = model.refit(active, model.factors)
    restored: set[int] = set()
    needed = np.zeros(len(active), bool)  # cannot be rejected: the block needs them
    kept_why: dict[int, str] = {}
    log: list[SnoopingStep] = []
    before: np.ndarray | None = None  # what was controlled before the last rejection
    out_before_group: np.ndarray | None = None  # rejected before the last group rejection
    for it in range(1, max_iterations + 1):
        q = analyse(model, tests, separability=False)
        if before is not None and log and log[-1].action == "reject":
            lost = np.flatnonzero(before & active & ~q.controlled)
            if len(lost):
                log[-1] = replace(log[-1], uncontrolled=tuple(int(x) for x in lost),
                                  uncontrolled_words=tuple(no_longer_checked(model, lost)))
        before = q.controlled.copy()
        if out_before_group is not None:  # what the group took the control of stays out
            held = np.flatnonzero(out_before_group & ~active & (q.redundancy_number < R_MIN))
            restored.update(int(r) for r in held)
            if len(held):
                last = next(n for n in range(len(log) - 1, -1, -1) if log[n].grouped)
                log[last] = replace(log[last], uncontrolled_words=log[last].uncontrolled_words
                                    + tuple(f"{label(model, int(r))} stays rejected: nothing "
                                            "checks it without the group" for r in held))
            out_before_group = None
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
                rows = [int(r) for r in np.flatnonzero(model.group == model.group[i])]
            found, corr = inseparable_partners(model, q, i, active & ~needed)
            keep = ~np.isin(found, rows)
            part = [int(j) for j in found[keep]]
            rho = [float(r) for r in corr[keep]]
            trial = active.copy()
            trial[rows] = False
            new, why = None, ""
            grouped = False
            if part and inseparable == "group":
                both = trial.copy()
                both[part] = False
                new, why = _refit(model, both)
                grouped = not why
                if grouped:
                    trial = both
            if not grouped:
                new, why = _refit(model, trial)
            step = SnoopingStep(it, q.sigma0_hat, "kept" if why else "reject", rows,
                                [label(model, r) for r in rows], float(stat[i]),
                                float(q.mdb[i]), statistic, why, tuple(part),
                                tuple(label(model, j) for j in part), tuple(rho), grouped)
            if grouped:
                rows = rows + part
                restored.update(int(r) for r in rows)  # a group is not taken apart again
            log.append(step)
            if why:
                # without it the block is undetermined or the adjustment fails: keep those
                # components, say so, and go on with the next candidate
                needed[rows] = True
                kept_why.update((int(r), why) for r in rows)
                say(f"snooping {it}: {step.labels[0]} kept: {why}")
                cand = cand[~np.isin(cand, rows)]
                continue
            if grouped:
                out_before_group = ~active
            say(f"snooping {it}: sigma0 {q.sigma0_hat:.3f}, reject {step.labels[0]}"
                f"{' (+ group)' if len(rows) > 1 else ''}: {statistic} = {stat[i]:.2f}"
                + (f"; {step.identification()}" if part else ""))
            assert new is not None  # refitted (no `why`)
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
                rows = [int(r) for r in np.flatnonzero(model.group == model.group[i])
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
            assert new is not None  # refitted (no `why`)
            active, model = trial, new
    q = analyse(model, tests)
    stat = q.w if statistic == "w" else q.tau
    crit = q.k_w if statistic == "w" else q.k_tau
    left = active & ~needed & q.controlled & (np.abs(np.nan_to_num(stat)) > crit)
    return SnoopingRun(model, q, active, log, False, statistic, int(np.sum(left)))


def inseparable_partners(model: AdjustedModel, q: QualityResult, i: int,
                         among: np.ndarray, threshold: float = RHO_INSEPARABLE
                         ) -> tuple[np.ndarray, np.ndarray]:
    """(indices, rho) of the active tested components in `among` whose w-tests are
    correlated with that of active component i by |rho| >= threshold (one column of Qvv by
    Gruen's identity-matrix observation: every component, near or far)."""
    col = qvv_columns(model, np.array([i]))[:, 0]
    ok = among & model.active & q.controlled & (q.qvv > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(ok, col / np.sqrt(q.qvv * q.qvv[i]), 0.0)
    rho[i] = 0.0
    idx = np.flatnonzero(np.abs(rho) >= threshold)
    return idx, rho[idx]


def no_longer_checked(model: AdjustedModel, rows) -> list[str]:
    """'the remaining y of point P on photo Q can no longer be checked' for each row."""
    out = []
    for r in rows:
        where = (f" on {model.frame_kind} {model.frame[r]}" if model.frame[r] else "")
        what = f"{model.component[r]} of point {model.point[r]}" if model.point[r] else \
            label(model, int(r))
        out.append(f"the remaining {what}{where} can no longer be checked (r < 0.001)")
    return out


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
