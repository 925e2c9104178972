"""Advice for a planned block: its weak places and what would fix them (Gruen 1980, sect. 4).

Gruen's concluding remarks: reliability is decided by the number of rays of a point and the
image-point distribution per photo rather than by the control; aim at four-fold coverage of
every point (60 % forward and 60 % side overlap, or 20 % side overlap with cross strips),
stabilise perimeter photos with additional tie and pass points, measure in stereo mode and
use twin control.  `what_if` recomputes a flight plan with each remedy.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from baarda.planning.design import ControlLayout, design_block
from baarda.planning.design_reliability import PlanResult, analyse_design
from baarda.simulate.aerial import FlightPlan

WEAK = 0.5  # Gruen: sqrt(qvv) of about 0.5 regarded as sufficient


@dataclass
class Advice:
    topic: str
    finding: str
    remedy: str
    where: list[str] = field(default_factory=list)

    def text(self, max_where: int = 12) -> str:
        w = ""
        if self.where:
            more = len(self.where) - max_where
            w = "\n    where: " + ", ".join(self.where[:max_where]) + (
                f" (+{more} more)" if more > 0 else "")
        return f"* {self.topic}: {self.finding}\n    remedy: {self.remedy}{w}"


def _fmt(x: float) -> str:
    return f"{x:.2f}"


def advise(plan: PlanResult, flight: FlightPlan | None = None, weak: float = WEAK) -> list[Advice]:
    """The weak places of a planned block, each with a remedy."""
    out: list[Advice] = []
    obs = plan.image()
    photos = plan.photos
    sq = obs["sqrt_qvv"].to_numpy()
    side = None if flight is None else flight.side_overlap

    half = photos[photos["half_coverage"]]
    if len(half):
        on_half = obs["photo"].isin(half["photo"])
        out.append(Advice(
            "perimeter photos with part coverage",
            f"{len(half)} photo(s) have their points on only part of the format "
            f"(median {int(np.median(half['points']))} points against "
            f"{int(np.median(photos.loc[~photos['half_coverage'], 'points']))} on the "
            "others); their observations average sqrt(qvv) "
            f"{_fmt(sq[on_half].mean())} against {_fmt(sq[~on_half].mean())} elsewhere, "
            f"lowest {_fmt(np.nanmin(half['min_sqrt_qvv']))}",
            "stabilise them with additional tie and pass points on the uncovered part of the "
            "format (e.g. points beyond the first and last nadir point, or one more photo at "
            "each strip end)", list(half["photo"])))

    zero = obs[(obs["redundancy"] < 1e-3)]
    if len(zero):
        out.append(Advice(
            "uncontrolled observations",
            f"{len(zero)} image coordinate(s) have redundancy number 0 "
            f"({', '.join(sorted(zero['class'].unique()))}: e.g. x of 2-ray points, whose "
            "only check is the y-parallax): a blunder in them cannot be detected and goes "
            "straight into the point",
            "give these points more rays (side overlap of 60 % or cross strips) or do not use "
            "them for results", sorted(zero["point"].unique())))

    two = obs[obs["rays"] == 2]
    if len(two):
        pts = sorted(two["point"].unique())
        models = sorted({f"{a}/{b}" for a, b in _models_of(plan, pts)})
        remedy = ("fly 60 % side overlap" if side is not None and side < 0.5 else
                  "add cross strips or extend the block by one strip on each side")
        out.append(Advice(
            "2-ray points",
            f"{len(pts)} point(s) have only two rays (R2(y) mean "
            f"{_fmt(two[two['component'] == 'y']['sqrt_qvv'].mean())}, R2(x) = 0); they lie "
            f"in {len(models)} model(s) covered by one strip only (corner and edge models)",
            f"{remedy} so that every point to be determined has at least four-fold coverage; "
            "otherwise use the edge zones for tie points only", pts))

    weak_obs = obs[(sq < weak) & (obs["redundancy"] >= 1e-3)]
    if len(weak_obs):
        by = weak_obs.groupby(["class", "component"]).size()
        parts = ", ".join(f"{c}({k}) {n}" for (c, k), n in by.items())
        ctl = weak_obs["class"].str.startswith("C").any()
        out.append(Advice(
            "weakly controlled observations",
            f"{len(weak_obs)} of {len(obs)} image coordinates have sqrt(qvv) below {weak} "
            f"(MDB above {weak_obs['mdb'].min():.0f} µm): {parts}",
            "more rays per point (overlap), more points on the photos concerned"
            + ("; twin control for the control points" if ctl else ""),
            sorted(weak_obs["photo"].unique())))

    if not obs["inner"].any():
        out.append(Advice(
            "monocomparator mode",
            "no point is measured twice on a photo (no twin rays)",
            "measure in stereo mode: every point of adjacent models twice; the inner (twin) "
            "rays reach sqrt(qvv) of about 0.85-0.90 and stereo measurement also prevents "
            "many blunders"))

    ctl = obs[obs["class"].str.startswith("CRO")]
    if len(ctl) and not _has_twins(plan):
        out.append(Advice(
            "single control",
            f"the outer rays of the control points average sqrt(qvv) "
            f"{_fmt(ctl['sqrt_qvv'].mean())} (lowest {_fmt(ctl['sqrt_qvv'].min())})",
            "twin control (pairs of control points close together) raises them by about "
            "17 % (Gruen) at little extra field work and guards against lost points",
            sorted(ctl["point"].unique())))

    ext = obs[np.isfinite(obs["external_max"])].nlargest(5, "external_max")
    if len(ext):
        pts = plan.points
        sig = float(np.sqrt(np.mean(pts[["sigma_X", "sigma_Y", "sigma_Z"]].to_numpy() ** 2) * 3))
        out.append(Advice(
            "largest effect of undetectable blunders",
            f"an undetected blunder of MDB size moves a ground point by up to "
            f"{ext['external_max'].iloc[0]:.3f} m (RMS expected point precision "
            f"{sig:.3f} m)",
            "these observations need more checking rays (see above)",
            [f"{r.photo}/{r.point}/{r.component}" for r in ext.itertuples()]))
    return out


def _models_of(plan: PlanResult, points: list[str]):
    im = plan.block.image
    idx = plan.block.point_index
    ids = plan.block.photos.ids
    sel = np.isin(im.point, [idx[p] for p in points])
    pairs = set()
    for j in np.unique(im.point[sel]):
        ph = sorted({ids[k] for k in im.photo[im.point == j]})
        pairs.add((ph[0], ph[-1]))
    return pairs


def _has_twins(plan: PlanResult) -> bool:
    from baarda.planning.reliability_tables import design_key

    return design_key(plan.block).control == "twin"


def what_if(flight: FlightPlan, layout: ControlLayout) -> pd.DataFrame:
    """The flight plan as planned and with each remedy: reliability summary per variant."""
    variants = [("as planned", flight, layout)]
    if not layout.twin:
        variants.append(("twin control", flight, replace(layout, twin=True)))
    if flight.pattern < 5:
        variants.append(("5x5 points per photo", replace(flight, pattern=5), layout))
    if flight.side_overlap < 0.55:  # same area: more strips
        strips = int(np.ceil((flight.strips - 1) * (1 - flight.side_overlap) / 0.4)) + 1
        variants.append(("60 % side overlap", replace(flight, side_overlap=0.6,
                                                       strips=strips), layout))
    if not flight.stereo:
        variants.append(("stereo mode", replace(flight, stereo=True), layout))
    rows = []
    for name, f, lay in variants:
        res = analyse_design(design_block(f, lay))
        obs = res.image()
        ok = obs["redundancy"] >= 1e-3
        rows.append({"variant": name, "photos": len(res.block.photos),
                     "image_obs": len(obs), "mean_sqrt_qvv": obs["sqrt_qvv"].mean(),
                     "share_below_0.5": float(np.mean(obs["sqrt_qvv"] < WEAK)),
                     "uncontrolled": int((~ok).sum()),
                     "max_mdb_um": float(obs.loc[ok, "mdb"].max()),
                     "max_external_m": float(obs.loc[ok, "external_max"].max()),
                     "rms_sigma_Z_m": float(np.sqrt(np.mean(res.points["sigma_Z"] ** 2)))})
    return pd.DataFrame(rows)
