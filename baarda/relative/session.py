"""On-line strip bridging, model by model, with the QC of each model while it is "on the
instrument" (Kratky and El-Hakim 1983).

    s = OnlineSession(focal=152.0, sigma_x=5.0)
    qc = s.add_model("1-2", {"1": (x1, y1, x2, y2), ...})   # left and right image mm
    print(qc.remeasure)                                     # point with the largest |w|
    qc = s.remeasure("3", x1, y1, x2, y2)                   # QC again
    s.accept()                                              # coordinates join the strip
    qc = s.add_model("2-3", {...})   # scale transfer through the tie points of model 1-2

The first model is oriented with 5 unknowns at the base `base` (default: the mean x-parallax,
so that model coordinates are at photo scale, Z ~ -c); every later model with 6, its left photo
being the right photo of the preceding model and its tie points (by default every point that
the preceding model determined) constraining the scale.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from baarda.options import DEFAULT_QTIE, DEFAULT_QYY, DEFAULT_TESTS, TestOptions
from baarda.quality.dense_model import block_diagonal
from baarda.quality.variance_components import VarianceEstimation, challenge, iterate
from baarda.relative.model_qc import ModelQC, assess_model
from baarda.relative.orientation import (
    VARIANCE_GROUPS,
    ModelSetup,
    Orientation,
    PhotoPose,
    orient,
    parallax_sigma,
)

Measurement = tuple[float, float, float, float]  # x', y', x'', y'' in mm
MAX_LEFT_OUT = 10  # observations left out of the strip's variance components, at most


@dataclass
class AcceptedModel:
    name: str
    qc: ModelQC

    @property
    def orientation(self) -> Orientation:
        return self.qc.orientation

    def coordinates(self) -> dict[str, np.ndarray]:
        o = self.orientation
        return {p: o.model_xyz[i] for i, p in enumerate(o.points)}


@dataclass
class _Pending:
    name: str
    points: dict[str, Measurement]
    ties: list[str] | None
    qc: ModelQC | None = None


class OnlineSession:
    """Strip bridging model by model.

    focal: principal distance c (mm); sigma_x: a-priori sigma of x'' (µm); qyy: q_yy / q_xx
    (Kratky: 2); qtie: cofactor of x'' at tie points / q_xx (Kratky: 1); tests: alpha0 and
    beta0 of the w-test; statistic: "w" (sigma0 a priori) or "tau"; base: b_x of the first
    model in model units (default: mean x-parallax); vce: estimate the variance components
    of the y-parallaxes (coplanarity) and of the x'' of the tie points (scale transfer) over
    the strip so far (the accepted models and the one on the instrument, Foerstner's
    iteration on them together) and orient and test the model with them: q_yy / q_xx and
    q_tie estimated; a group with too little redundancy keeps its a-priori weight.
    """

    def __init__(self, focal: float, sigma_x: float = 10.0, qyy: float = DEFAULT_QYY,
                 tests: TestOptions = DEFAULT_TESTS, statistic: str = "w",
                 base: float | None = None, qtie: float = DEFAULT_QTIE, vce: bool = False):
        if not focal > 0 or not sigma_x > 0 or not qyy > 0 or not qtie > 0:
            raise ValueError("focal, sigma_x, qyy and qtie must be positive")
        self.focal, self.sigma_x, self.qyy = float(focal), float(sigma_x), float(qyy)
        self.qtie = float(qtie)
        self.tests, self.statistic = tests, statistic
        self.base = base
        self.vce = bool(vce)
        self.accepted: list[AcceptedModel] = []
        self.coordinates: dict[str, np.ndarray] = {}  # strip, first determination
        self._pending: _Pending | None = None

    # -- the model on the instrument -------------------------------------------------------
    @property
    def current(self) -> ModelQC | None:
        return None if self._pending is None else self._pending.qc

    def add_model(self, name: str, measurements: Mapping[str, Measurement],
                  ties: Iterable[str] | None = None) -> ModelQC:
        """Put a model on the instrument: orient it and return its QC.

        measurements: point id -> (x', y', x'', y'') in mm.  ties: the tie points (default:
        every point with coordinates from the preceding model); ignored for the first model.
        """
        if self._pending is not None:
            raise ValueError(f"model {self._pending.name} is still on the instrument: "
                             "accept() or discard() it first")
        if any(m.name == name for m in self.accepted):
            raise ValueError(f"model {name} was already accepted")
        pts = {str(k): _check(k, v) for k, v in measurements.items()}
        self._pending = _Pending(str(name), pts, None if ties is None else
                                 [str(t) for t in ties])
        try:
            return self._orient()
        except Exception:
            self._pending = None
            raise

    def remeasure(self, point: str, x1: float, y1: float, x2: float, y2: float) -> ModelQC:
        """Replace (or add) the measurement of one point of the current model; QC again."""
        p = self._need()
        old = p.points.get(str(point))
        p.points[str(point)] = _check(point, (x1, y1, x2, y2))
        try:
            return self._orient()
        except Exception:
            if old is None:
                del p.points[str(point)]
            else:
                p.points[str(point)] = old
            raise

    def drop(self, point: str) -> ModelQC:
        """Leave a point out of the current model; QC again."""
        p = self._need()
        if str(point) not in p.points:
            raise KeyError(f"point {point} is not in model {p.name}")
        before = dict(p.points)
        del p.points[str(point)]
        try:
            return self._orient()
        except Exception:
            p.points = before
            raise

    def accept(self) -> AcceptedModel:
        """Accept the current model: its points join the strip coordinates."""
        p = self._need()
        assert p.qc is not None  # oriented by add_model
        acc = AcceptedModel(p.name, p.qc)
        self.accepted.append(acc)
        for pid, xyz in acc.coordinates().items():
            self.coordinates.setdefault(pid, xyz)
        self._pending = None
        return acc

    def discard(self) -> None:
        self._need()
        self._pending = None

    # -- internals ---------------------------------------------------------------------------
    def _need(self) -> _Pending:
        if self._pending is None:
            raise ValueError("no model is on the instrument (add_model first)")
        return self._pending

    def _orient(self) -> ModelQC:
        p = self._pending
        assert p is not None  # add_model or remeasure set it
        ids = list(p.points)
        arr = np.array([p.points[i] for i in ids], float).reshape(-1, 4)
        left_xy, right_xy = arr[:, :2], arr[:, 2:]
        if not self.accepted:
            base = self.base if self.base is not None else float(np.mean(left_xy[:, 0]
                                                                         - right_xy[:, 0]))
            if not base > 0:
                raise ValueError(f"model {p.name}: the base must be positive (mean x-parallax "
                                 f"{base:.3f} mm)")
            setup = ModelSetup(self.focal, PhotoPose(np.zeros(3), np.eye(3)), base,
                               sigma_x=self.sigma_x, qyy=self.qyy, qtie=self.qtie)
            g0 = None
        else:
            prev = self.accepted[-1].orientation
            known = self.accepted[-1].coordinates()
            if p.ties is None:
                ties = [i for i in ids if i in known]
            else:
                missing = [t for t in p.ties if t not in known or t not in p.points]
                if missing:
                    raise ValueError(f"model {p.name}: tie point(s) {', '.join(missing)} not "
                                     f"measured in this model and in model {prev.name}")
                ties = p.ties
            ti = np.array([ids.index(t) for t in ties], int)
            setup = ModelSetup(self.focal, prev.right, prev.base, ti,
                               np.array([known[t] for t in ties]).reshape(-1, 3), scale=True,
                               sigma_x=self.sigma_x, qyy=self.qyy, qtie=self.qtie)
            g0 = prev.params.copy()
            g0[0] = 1.0
        o = orient(p.name, ids, left_xy, right_xy, setup, g0)
        if not self.vce:
            p.qc = assess_model(o, self.tests, self.statistic)
            return p.qc
        est, left_out = self.variance_components(o)
        fy, fx = (est.group_factor.get(VARIANCE_GROUPS[c], 1.0) for c in ("y", "x"))
        if fy != 1.0 or fx != 1.0:
            setup = replace(setup, qyy=setup.qyy * fy, qtie=setup.qtie * fx)
            o = orient(p.name, ids, left_xy, right_xy, setup, o.params)
        p.qc = replace(assess_model(o, self.tests, self.statistic),
                       variance_components=est.components(), variance_left_out=left_out)
        return p.qc

    def variance_components(self, current: Orientation | None = None
                            ) -> tuple[VarianceEstimation, tuple[str, ...]]:
        """Foerstner's iterated estimate of the groups y-parallax (coplanarity) and x'' at
        the tie points (scale transfer) from the accepted models and `current`, every one
        with the a-priori sigmas, as one block-diagonal adjustment (the models are
        adjusted independently); groups with r < 5 are reported, not estimated.  An
        observation significant against its group estimated without it (a gross error
        would inflate the estimate and hide behind it: quality.variance_components.
        challenge) is left out of the estimate; returns (the estimate, their labels)."""
        models = [m.orientation for m in self.accepted] + ([current] if current else [])
        if not models:
            raise ValueError("no model to estimate variance components from")
        strip = block_diagonal([o.dense_model(parallax_sigma(
            o.obs_component, self.sigma_x, self.qyy, self.qtie)) for o in models])
        active = strip.active.copy()
        est = iterate(strip.refit(active), pool=False)
        left_out = []
        for _ in range(MAX_LEFT_OUT):
            i = challenge(est.model, est.plan, self.tests, self.statistic,
                          known=est.cofactors)
            if i is None:
                break
            active[i] = False
            left_out.append(f"{strip.point[i]} {strip.component[i]}'' (model {strip.frame[i]})")
            est = iterate(strip.refit(active), pool=False)
        return est, tuple(left_out)


def _check(pid, values) -> Measurement:
    try:
        v = tuple(float(x) for x in values)
    except (TypeError, ValueError) as e:
        raise ValueError(f"point {pid}: measurements must be four numbers x' y' x'' y'' "
                         "(mm)") from e
    if len(v) != 4 or not all(np.isfinite(v)):
        raise ValueError(f"point {pid}: measurements must be four finite numbers x' y' x'' "
                         "y'' (mm)")
    return v
