"""The Lugnani & Mitishita experiment: three strategies against many blunders.

1. residual analysis only: adjust, remove the observation with the largest normalised
   residual if it exceeds K_RMS times the RMS of the normalised residuals, re-adjust, repeat
   (as the paper's "removal of high residual observations, detected by the program");
2. data snooping only: baarda's iterative data snooping (w-test, alpha0 = 0.001, one
   component at a time: `baarda adjust --snoop`);
   2b. the chain's snooping alone: what the snooping rejects is removed together with the
   observations it cannot be told from (|rho| >= 0.9), without the screening stages;
3. screening (photo pairs, strip formation, control), then the chain's snooping
   (`baarda adjust --screen --snoop`).

For each: the blunders found (properly) and the good points removed (improperly), and the
discrepancies of the adjusted points from the truth (the paper's Tables 2-5).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from baarda.block.photo_block import Block, GroundPoints
from baarda.bundle.bundle_result import BundleResult
from baarda.errors import GeometryError
from baarda.pipeline import adjust, snoop
from baarda.screening.chain import ScreeningResult, screen_and_snoop
from baarda.screening.log import ScreeningLog
from baarda.screening.separable import snoop_separable

K_RMS = 3.0  # residual analysis: reject |v|/sigma > K_RMS * RMS(v/sigma)

try:  # run as a script or imported by the tests
    from lugnani_block import CONTROL_BLUNDERS, IMAGE_BLUNDERS, PAPER_IDS, build
except ImportError:  # pragma: no cover
    from examples.lugnani.lugnani_block import CONTROL_BLUNDERS, IMAGE_BLUNDERS, PAPER_IDS, build


@dataclass
class Outcome:
    """What a strategy removed and where the adjusted points ended up."""

    name: str
    removed_image: set[tuple[str, str]]  # (photo, point)
    removed_control: set[str]  # points whose control (any coordinate) was removed
    result: BundleResult | None
    runs: int = 1
    screening: ScreeningResult | None = None
    notes: list[str] = field(default_factory=list)


def _without(block: Block, rows: set[tuple[str, str]], control: set[str]) -> Block:
    im, ids = block.image, block.points.ids
    keep = np.array([(block.photos.ids[f], ids[p]) not in rows
                     for f, p in zip(im.photo, im.point, strict=True)])
    out = block.select_image(keep)
    if control:
        idx = [block.point_index[p] for p in control]
        pts = block.points
        role, xyz, sig = pts.role.copy(), pts.xyz.copy(), pts.sigma.copy()
        role[idx], xyz[idx], sig[idx] = "tie", np.nan, np.nan
        out = replace(out, points=GroundPoints(list(ids), xyz, sig, role))
    return out


def residual_analysis(block: Block, k: float = K_RMS, max_runs: int = 200) -> Outcome:
    """Strategy 1: remove the largest normalised residual above k * RMS, one per run."""
    rows: set[tuple[str, str]] = set()
    ctrl: set[str] = set()
    res = None
    for run in range(1, max_runs + 1):
        blk = _without(block, rows, ctrl)
        try:
            res = adjust(blk)
        except GeometryError as e:
            return Outcome("residual analysis", rows, ctrl, None, run, notes=[str(e)])
        zi = res.image_residuals / blk.image.sigma_mm[res.problem.obs][:, None]
        zc = res.control_residuals / blk.points.sigma[res.problem.control]
        z = np.concatenate([zi.ravel(), zc[np.isfinite(zc)]])
        rms = np.sqrt(np.mean(z**2))
        gi = np.max(np.abs(zi), axis=1)
        gc = np.nanmax(np.abs(np.where(np.isfinite(zc), zc, np.nan)), axis=1, initial=0.0)
        if max(gi.max(initial=0.0), gc.max(initial=0.0)) <= k * rms:
            return Outcome("residual analysis", rows, ctrl, res, run)
        if gi.max(initial=0.0) >= gc.max(initial=0.0):
            r = res.problem.obs[int(np.argmax(gi))]
            rows.add((blk.photos.ids[blk.image.photo[r]], blk.points.ids[blk.image.point[r]]))
        else:
            ctrl.add(blk.points.ids[res.problem.control[int(np.argmax(gc))]])
    return Outcome("residual analysis", rows, ctrl, res, max_runs, notes=["no convergence"])


def _removals(log: ScreeningLog) -> tuple[set, set]:
    return log.removed_image(), log.removed_control()


def snooping_only(block: Block) -> Outcome:
    """Strategy 2: baarda's iterative data snooping (baarda adjust --snoop), one component
    at a time; a rejected coordinate counts as its image point removed."""
    qc = snoop(block)
    m = qc.model
    rej = ~qc.quality.active
    rows = {(str(m.frame[i]), str(m.point[i])) for i in np.flatnonzero(rej & (m.kind == "image"))}
    ctrl = {str(m.point[i]) for i in np.flatnonzero(rej & (m.kind == "control"))}
    return Outcome("data snooping", rows, ctrl, qc.adjustment)


def separable_snooping(block: Block) -> Outcome:
    """Strategy 2b: the chain's bundle snooping alone (what it rejects removed together with
    what it cannot be told from: screening.snooping), without the screening stages."""
    qc, _, log = snoop_separable(block)
    rows, ctrl = _removals(log)
    return Outcome("separable snooping", rows, ctrl, qc.adjustment)


def screening_then_snooping(block: Block) -> Outcome:
    """Strategy 3: the screening chain, then the same data snooping."""
    sr, qc = screen_and_snoop(block)
    rows, ctrl = _removals(sr.log)
    return Outcome("screening+snooping", rows, ctrl, qc.adjustment, screening=sr)


def noise_only(seed: int = 1) -> Outcome:
    block, _ = build(seed, blunders=False)
    return Outcome("noise only", set(), set(), adjust(block))


@dataclass
class Score:
    found: list[str]  # blunders found: "point/photo" or "point (control)"
    missed: list[str]
    improper_points: list[str]  # good points removed (no blunder on any of its rays)
    improper_observations: int  # good image points (photo, point) or control points removed
    rms: np.ndarray  # (3,) RMS of adjusted - true over the adjusted points, m
    max: np.ndarray  # (3,) largest |adjusted - true|
    discrepancy: dict[str, np.ndarray]  # point -> adjusted - true
    normalised: np.ndarray  # (3,) RMS of (adjusted - true) / its standard deviation


def score(outcome: Outcome, truth: dict) -> Score:
    found, missed = [], []
    bad_rows = {(f, p) for p, f, _, _ in IMAGE_BLUNDERS}
    bad_points = {p for p, _, _, _ in IMAGE_BLUNDERS} | {p for p, *_ in CONTROL_BLUNDERS}
    for p, f, _, _ in IMAGE_BLUNDERS:
        (found if (f, p) in outcome.removed_image else missed).append(f"{p}/{f}")
    for p, *_ in CONTROL_BLUNDERS:
        (found if p in outcome.removed_control else missed).append(f"{p} (control)")
    good_rows = {r for r in outcome.removed_image if r not in bad_rows}
    good_ctrl = {p for p in outcome.removed_control if p not in bad_points}
    improper = sorted({p for _, p in good_rows if p not in bad_points} | good_ctrl)
    disc, norm = {}, []
    if outcome.result is not None:
        res = outcome.result
        xyz = res.points_xyz()
        std = np.full_like(xyz, np.nan)
        std[res.problem.point_ids] = res.xyz_std
        for j, p in enumerate(res.block.points.ids):
            if np.all(np.isfinite(xyz[j])):
                disc[p] = xyz[j] - truth["points"][p]
                norm.append(disc[p] / std[j])
    d = np.array(list(disc.values())) if disc else np.full((1, 3), np.nan)
    z = np.array(norm) if norm else np.full((1, 3), np.nan)
    return Score(found, missed, improper, len(good_rows) + len(good_ctrl),
                 np.sqrt(np.mean(d**2, axis=0)), np.max(np.abs(d), axis=0), disc,
                 np.sqrt(np.mean(z**2, axis=0)))


def same_observations(seed: int, final: Block) -> Outcome:
    """The noise-only block with exactly the observations that `final` kept: the accuracy
    the cleaned block can reach at best (the removed observations are missing from it)."""
    clean, _ = build(seed, blunders=False)
    im = clean.image
    kept = {(final.photos.ids[f], final.points.ids[p])
            for f, p in zip(final.image.photo, final.image.point, strict=True)}
    keep = np.array([(clean.photos.ids[f], clean.points.ids[p]) in kept
                     for f, p in zip(im.photo, im.point, strict=True)])
    out = clean.select_image(keep)
    pts = final.points
    xyz = np.where(np.isfinite(pts.sigma), clean.points.xyz, np.nan)
    out = replace(out, points=GroundPoints(list(pts.ids), xyz, pts.sigma.copy(),
                                           pts.role.copy()))
    return Outcome("same obs, no errors", set(), set(), adjust(out))


def run(seed: int = 1) -> dict[str, tuple[Outcome, Score]]:
    """All strategies on the block of `seed`; keyed by strategy name."""
    block, truth = build(seed)
    out = {}
    for oc in (noise_only(seed), residual_analysis(block), snooping_only(block),
               separable_snooping(block), screening_then_snooping(block)):
        out[oc.name] = (oc, score(oc, truth))
    final = out["screening+snooping"][0].result.block
    ref = same_observations(seed, final)
    out[ref.name] = (ref, score(ref, truth))
    return out


PAPER = {  # Lugnani & Mitishita: Tables 2-5 (their block, their program)
    "residual analysis": {"found": 2, "improper": 9, "max": (1.128, 1.627, 20.494)},
    "screening+snooping": {"found": 10, "improper": 2, "max": (0.174, 0.100, 0.298)},
}


def table(results: dict[str, tuple[Outcome, Score]], sample: int = 10) -> str:
    """The side-by-side comparison printed by the script (and kept in README.md)."""
    names = list(results)
    w = 20
    lines = ["strategy".ljust(26) + "".join(n[:w - 1].rjust(w) for n in names)]

    def row(label, vals):
        lines.append(label.ljust(26) + "".join(str(v).rjust(w) for v in vals))

    sc = [results[n][1] for n in names]
    oc = [results[n][0] for n in names]
    ref = ("noise only", "same obs, no errors")
    row("blunders found (of 10)", [len(s.found) if o.name not in ref else "-"
                                   for s, o in zip(sc, oc, strict=True)])
    row("good points removed", [len(s.improper_points) if o.name not in ref else "-"
                                for s, o in zip(sc, oc, strict=True)])
    row("good observations removed", [s.improper_observations if o.name not in ref else "-"
                                      for s, o in zip(sc, oc, strict=True)])
    row("adjustment runs", [o.runs for o in oc])
    for k, c in enumerate("XYZ"):
        row(f"RMS d{c} (m)", [f"{s.rms[k]:.3f}" for s in sc])
    for k, c in enumerate("XYZ"):
        row(f"max |d{c}| (m)", [f"{s.max[k]:.3f}" for s in sc])
    row("RMS d/sigma X, Y, Z", [" ".join(f"{v:.1f}" for v in s.normalised) for s in sc])
    lines.append("")
    lines.append("missed: " + "; ".join(f"{o.name}: {', '.join(s.missed) or 'none'}"
                                        for o, s in zip(oc, sc, strict=True)
                                        if o.name not in ref))
    lines.append("good points removed: " + "; ".join(
        f"{o.name}: {', '.join(s.improper_points) or 'none'}" for o, s in zip(oc, sc, strict=True)
        if o.name not in ref))
    # sample of discrepancies (the paper's Tables 3 and 5): the worst points of strategy 1
    ra = results.get("residual analysis", (None, sc[0]))[1].discrepancy
    worst = sorted(ra, key=lambda p: -np.linalg.norm(ra[p]))[:sample]
    w2 = 22
    lines += ["", f"discrepancies adjusted - true (m), the {sample} worst points of residual "
              "analysis:", "point".ljust(8) + "".join(n[:w2 - 2].rjust(w2) for n in names)]
    for p in sorted(worst):
        cells = []
        for s in sc:
            d = s.discrepancy.get(p)
            cells.append("removed" if d is None else " ".join(f"{x:6.2f}" for x in d))
        lines.append(f"{p:8s}" + "".join(c.rjust(w2) for c in cells))
    return "\n".join(lines)


def paper_table() -> str:
    return "\n".join([
        "Lugnani & Mitishita (their block):  residual analysis   screening + bundle",
        f"blunders found (of 10)             {PAPER['residual analysis']['found']:>17d}"
        f"   {PAPER['screening+snooping']['found']:>18d}",
        f"good points removed                {PAPER['residual analysis']['improper']:>17d}"
        f"   {PAPER['screening+snooping']['improper']:>18d}",
        "max |d| of the sample X, Y, Z (m)  " + " ".join(
            f"{v:5.2f}" for v in PAPER["residual analysis"]["max"]) + "   " + " ".join(
            f"{v:5.3f}" for v in PAPER["screening+snooping"]["max"]),
        "paper point numbers -> ours: " + ", ".join(f"{v}->{k}" for k, v in PAPER_IDS.items()),
    ])


def many(seeds: range) -> str:
    """The strategies over many simulated blocks (noise, jitter and tilts differ by seed)."""
    rows: dict[str, list] = {}
    for seed in seeds:
        res = run(seed)
        noise = res["noise only"][1].rms
        for name, (_, sc) in res.items():
            rows.setdefault(name, []).append((len(sc.found), len(sc.improper_points),
                                              sc.rms / noise, sc.max[2], sc.normalised))
    lines = [f"{len(seeds)} blocks (seeds {seeds.start}-{seeds.stop - 1})",
             "strategy              all 10 found  mean found  good points removed (0/1/2+)"
             "  RMS Z / noise-only (median, max)  max |dZ| median (m)  RMS d/sigma Z median"]
    for name, r in rows.items():
        found = np.array([x[0] for x in r])
        good = np.array([x[1] for x in r])
        ratio = np.array([x[2][2] for x in r])
        mz = np.array([x[3] for x in r])
        nz = np.array([x[4][2] for x in r])
        ref = name in ("noise only", "same obs, no errors")
        split = f"{np.sum(good == 0)}/{np.sum(good == 1)}/{np.sum(good >= 2)}"
        lines.append(f"{name:22s}{'-' if ref else int(np.sum(found == 10)):>12}"
                     f"{'-' if ref else f'{found.mean():.1f}':>12}"
                     f"{'-' if ref else split:>31}"
                     f"{np.nanmedian(ratio):>20.2f}{np.nanmax(ratio):>14.2f}"
                     f"{np.nanmedian(mz):>21.2f}{np.nanmedian(nz):>23.2f}"
                     + (f"  ({int(np.sum(np.isnan(mz)))} failed)" if np.isnan(mz).any() else ""))
    return "\n".join(lines)


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seed", nargs="?", type=int, default=1, help="the block to print (1)")
    ap.add_argument("--seeds", type=int, default=0,
                    help="also summarise blocks 1..N (about 4 s each)")
    args = ap.parse_args()
    res = run(args.seed)
    print(table(res))
    print()
    print(paper_table())
    print()
    print(res["screening+snooping"][0].screening.summary())
    if args.seeds:
        print()
        print(many(range(1, args.seeds + 1)))
