"""What the on-line bundle answers to each measurement: the test of every component it took
in, the observations whose verdict changed, the verdict (docs/online.md).

Verdicts of a component, from its w-test in the block with it (Baarda's w, sigma0 a priori,
critical value k of the B-method at alpha0):

* reject  - |w| > k: re-measure it;
* suspect - its redundancy number is below R_MIN (quality/statistics.py): no other
  observation checks it, an error in it would pass unseen (measure another ray);
* accept  - |w| <= k.

An addition's verdict is the worst of its components' (reject, suspect, accept); "held"
when nothing was tested (a point's first ray, a photo that the block does not determine yet).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass

import numpy as np

from baarda.kinds import CONTROL, GNSS, IMAGE, IMU, kind_of
from baarda.quality.statistics import R_MIN

MAX_LINES = 60  # an answer's text lists at most this many components (else the rejected)
# the answers' units (baarda/kinds.py; IMU always in mrad)
UNITS = {k.name: k.shown() for k in (IMAGE, CONTROL, GNSS, IMU)}


def verdict(w: float, r: float, k_w: float) -> str:
    """The verdict of one component (module docstring)."""
    if not r >= R_MIN or not math.isfinite(w):
        return "suspect"
    return "reject" if abs(w) > k_w else "accept"


def verdicts(w: np.ndarray, r: np.ndarray, k_w: float) -> np.ndarray:
    """verdict() of arrays."""
    ok = (r >= R_MIN) & np.isfinite(w)
    return np.where(~ok, "suspect", np.where(np.abs(np.nan_to_num(w)) > k_w, "reject",
                                             "accept")).astype(object)


def rejected(tested, changed=()) -> list[ComponentTest | Change]:
    """The rejected among `tested` and the changes to reject in `changed`, one per
    component (kind, photo, point, component), largest |w| first (Answer.remeasure)."""
    out: dict[tuple, ComponentTest | Change] = {
        (c.kind, c.photo, c.point, c.component): c for c in changed if c.after == "reject"}
    out.update({(t.kind, t.photo, t.point, t.component): t for t in tested
                if t.verdict == "reject"})
    return sorted(out.values(), key=lambda t: -abs(t.w))


def worst(values) -> str:
    vs = list(values)
    for v in ("reject", "suspect", "accept"):
        if v in vs:
            return v
    return "held"


@dataclass(frozen=True)
class ComponentTest:
    """The test of one component in the block with it (units: mm / m / rad inside; `unit`
    and `scale` say how it is shown).  predicted: observed - predicted before it was taken
    in, sigma_predicted its standard deviation (sigma^2 + q_ll)^0.5 (NaN in a first
    adjustment); residual v = adjusted - observed after, redundancy r, w, mdb after."""

    kind: str
    photo: str
    point: str
    component: str
    predicted: float
    sigma_predicted: float
    residual: float
    sigma_residual: float
    redundancy: float
    w: float
    mdb: float
    verdict: str

    @property
    def label(self) -> str:
        if self.kind == "image":
            return f"image {self.component} of point {self.point} on photo {self.photo}"
        if self.kind == "control":
            return f"control {self.component} of point {self.point}"
        return f"{kind_of(self.kind).words} {self.component} of photo {self.photo}"


@dataclass(frozen=True)
class Change:
    """An observation whose verdict the step changed (w, r and MDB after it)."""

    kind: str
    photo: str
    point: str
    component: str
    before: str
    after: str
    w: float
    redundancy: float = float("nan")  # r after the step
    mdb: float = float("nan")  # MDB after the step (the kind's unit: mm, m, rad)


@dataclass(frozen=True)
class Answer:
    """The answer to one step: an addition (tested, held), a removal, or the first
    adjustment of the block (everything measured until it could be adjusted, tested in it).
    seconds: the time of the step; refactorised: whether the step factored the normal
    equations again (its changes then cover every observation)."""

    step: int
    action: str
    what: str
    tested: tuple[ComponentTest, ...] = ()
    held: tuple[str, ...] = ()
    changed: tuple[Change, ...] = ()
    seconds: float = 0.0
    refactorised: bool = False
    k_w: float = float("nan")
    note: str = ""
    # what the test cannot tell from the first to re-measure: (kind, photo, point, component)
    twins: tuple[tuple[str, str, str, str], ...] = ()

    @property
    def verdict(self) -> str:
        return worst(t.verdict for t in self.tested)

    def remeasure(self) -> list[ComponentTest | Change]:
        """What the step says is most likely wrong, largest |w| first: its rejected
        components and the observations whose verdict it changed to reject (an observation
        taken in before may be the one the new ray shows wrong); one entry per component
        (its test, where the step tested it)."""
        return rejected(self.tested, self.changed)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["verdict"] = self.verdict
        return _finite(d)

    def json(self) -> str:
        return json.dumps(self.to_dict(), ensure_ascii=False)

    def text(self) -> str:
        """The answer in ANAPLOT's manner: the table of the tested components (RED-N, PRED
        with its sigma, PARX = -v, EXPD = sigma_v, SIGF = |w|, MDB), the changed verdicts and
        the point to re-measure."""
        head = f"STEP {self.step}: {self.what}"
        if self.note:
            head += f" ({self.note})"
        lines = [head]
        if self.held:
            lines.append("  held: " + "; ".join(self.held))
        shown = list(self.tested)
        if len(shown) > MAX_LINES:  # a first adjustment: the rejected ones only
            shown = [t for t in shown if t.verdict == "reject"][:MAX_LINES]
            n_acc = sum(t.verdict == "accept" for t in self.tested)
            n_sus = sum(t.verdict == "suspect" for t in self.tested)
            lines.append(f"  {len(self.tested)} components tested: {n_acc} accepted, {n_sus} "
                         f"not checked, {len(self.tested) - n_acc - n_sus} rejected"
                         + (" (listed)" if shown else ""))
        if shown:
            lines.append("  POINT      PHOTO    OBS   RED-N      PRED      +-     PARX     EXPD"
                         "    SIGF       MDB")
            for t in shown:
                f, unit = UNITS.get(t.kind, (1.0, ""))
                star = " *" if t.verdict == "reject" else (" ?" if t.verdict == "suspect"
                                                            else "")
                lines.append(
                    f"  {t.point or '-':<10} {t.photo or '-':<8} {t.component:<4} "
                    f"{t.redundancy:6.3f} {_num(t.predicted * f):>9} "
                    f"{_num(t.sigma_predicted * f):>7} {_num(-t.residual * f):>8} "
                    f"{_num(t.sigma_residual * f):>8} {_num(abs(t.w), 2):>7} "
                    f"{_num(t.mdb * f):>9} {unit}{star}")
        for c in self.changed:
            lines.append(f"  verdict changed: {_name(c)} {c.before} -> {c.after} (w {c.w:.2f})")
        rem = self.remeasure()
        if rem:
            t = rem[0]
            what = {"image": f"POINT {t.point} ON PHOTO {t.photo}",
                    "control": f"CONTROL POINT {t.point}",
                    GNSS.name: f"THE GNSS POSITION OF PHOTO {t.photo}",
                    IMU.name: f"THE IMU ATTITUDE OF PHOTO {t.photo}"}[t.kind]
            lines.append(f"  REMEASURE {what} ({t.component}: SIGF {abs(t.w):.2f} > "
                         f"{self.k_w:.2f})" + (
                             "; the test cannot tell it from " + ", ".join(
                                 _name(Change(*u, "", "", 0.0)) for u in self.twins)
                             if self.twins else ""))
            if t.kind == "image" and any(u[0] == "image" and u[1] != t.photo
                                         for u in self.twins):
                lines.append(f"  or set point {t.point} aside until its next ray tells which "
                             f"ray is wrong: aside {t.point}")
        elif self.tested:
            unchecked = [t for t in self.tested if t.verdict == "suspect"]
            lines.append(f"  {self.verdict.upper()}" + (
                f": {len(unchecked)} component(s) not checked by any other observation "
                "(redundancy below 0.001)" if unchecked else ""))
        return "\n".join(lines)


def _name(c) -> str:
    if c.kind == "image":
        return f"{c.point}/{c.photo} {c.component}"
    return f"{c.kind} {c.point or c.photo} {c.component}"


def _num(x: float, digits: int = 1) -> str:
    return "-" if not math.isfinite(x) else f"{x:.{digits}f}"


def _finite(x):
    """JSON without NaN or infinity (null instead)."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    return x
