"""Issue 33: the on-line bundle's time per added image point and per added photo on the
1000-photo 5 x 5 block, against a batch re-adjustment per addition in the same run.

    PYTHONPATH=$PWD python benchmarks/bench_online.py [--points 200] [--photos 40]
        [--batch 5] [--out benchmarks/results/online_1000.json]

Block: FlightPlan(strips=20, photos_per_strip=50, forward_overlap=0.6, side_overlap=0.6,
pattern=5, relief_m=100, seed=1) (as bench_bundle.py).

* image points: the on-line bundle starts from the block without `--points` image points
  (third and later rays of their points, on photos with 20 or more points, chosen at
  random), which are then added one at a time;
* photos: it starts from the block without its last `--photos` photos in strip order, which
  are then added one at a time with all their image points;
* batch: for `--batch` of those additions, the batch re-adjustment of the block with it,
  as `baarda adjust` does it (the problem set up, Gauss-Newton from the previous solution,
  the statistics of every observation).

Prints the medians (and 90th percentiles) in ms and writes the raw times as JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

import numpy as np

from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.bundle_quality import assess
from baarda.online.bundle import OnlineBundle
from baarda.online.replay import strip_order
from baarda.simulate.aerial import FlightPlan, simulate_block


def block_1000():
    plan = FlightPlan(strips=20, photos_per_strip=50, forward_overlap=0.6, side_overlap=0.6,
                      pattern=5, relief_m=100, seed=1)
    return simulate_block(plan)[0]


def batch_time(ob: OnlineBundle) -> float:
    """One batch re-adjustment of what is in the on-line block now, warm-started."""
    eo, xyz = ob.estimates()
    t0 = time.perf_counter()
    block, maps = ob.m.state_block(np.where(np.isfinite(eo), eo, 0.0), xyz)
    problem = BundleProblem(block)
    result = problem.fit(start=(eo[maps.photos], xyz[maps.points[problem.elim_ids]]))
    assess(result)
    return time.perf_counter() - t0


def run_points(block, n: int, n_batch: int, rng) -> dict:
    im = block.image
    rays = np.bincount(im.point, minlength=len(block.points))
    per_photo = np.bincount(im.photo, minlength=len(block.photos))
    seen = np.zeros(len(block.points), int)
    order = np.argsort(im.photo, kind="stable")
    late = np.zeros(len(im), bool)
    for r in order:  # the third and later rays of each point
        seen[im.point[r]] += 1
        late[r] = seen[im.point[r]] >= 3
    cand = np.flatnonzero(late & (per_photo[im.photo] >= 20) & (rays[im.point] >= 4))
    chosen = rng.choice(cand, size=n, replace=False)
    keep = np.ones(len(im), bool)
    keep[chosen] = False
    t0 = time.perf_counter()
    ob = OnlineBundle(block.select_image(keep))
    start = time.perf_counter() - t0
    ids, pids = block.photos.ids, block.points.ids
    times, refac, batch = [], 0, []
    for k, r in enumerate(chosen):
        a = ob.add_image_point(ids[im.photo[r]], pids[im.point[r]], *im.xy_mm[r])
        times.append(a.seconds)
        refac += a.refactorised
        if k < n_batch:
            batch.append(batch_time(ob))
    return {"start_s": start, "ms": [1e3 * t for t in times], "refactorised": refac,
            "batch_ms": [1e3 * t for t in batch]}


def run_photos(block, n: int, n_batch: int) -> dict:
    order = strip_order(block)
    last = order[-n:]
    im = block.image
    keep = ~np.isin(im.photo, last)
    t0 = time.perf_counter()
    ob = OnlineBundle(block.select_image(keep))
    start = time.perf_counter() - t0
    pids = block.points.ids
    times, refac, batch, tested = [], 0, [], []
    for k, i in enumerate(last):
        rows = np.flatnonzero(im.photo == i)
        a = ob.add_photo(block.photos.ids[i], {pids[im.point[r]]: tuple(im.xy_mm[r])
                                               for r in rows})
        times.append(a.seconds)
        tested.append(len(a.tested))
        refac += a.refactorised
        if k < n_batch:
            batch.append(batch_time(ob))
    return {"start_s": start, "ms": [1e3 * t for t in times], "refactorised": refac,
            "tested": tested, "batch_ms": [1e3 * t for t in batch]}


def _line(name: str, rec: dict) -> str:
    ms = rec["ms"]
    p90 = float(np.percentile(ms, 90))
    b = statistics.median(rec["batch_ms"]) if rec["batch_ms"] else float("nan")
    return (f"{name:<12} median {statistics.median(ms):7.1f} ms (90 %: {p90:7.1f}, mean "
            f"{statistics.mean(ms):7.1f}; {rec['refactorised']} of {len(ms)} factored the "
            f"block again); batch re-adjustment per addition {b:7.1f} ms: "
            f"{b / statistics.median(ms):.0f} x")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=200)
    ap.add_argument("--photos", type=int, default=40)
    ap.add_argument("--batch", type=int, default=5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    block = block_1000()
    OnlineBundle(block.select_image(block.image.photo < 30))  # compile / load the kernels
    load = os.getloadavg()
    rec = {"load_before": load, "points": run_points(block, args.points, args.batch, rng),
           "photos": run_photos(block, args.photos, args.batch), "load_after": os.getloadavg()}
    print(f"1000 photos, 5 x 5 points ({len(block.image)} image points); load average "
          f"{load[0]:.1f} before, {rec['load_after'][0]:.1f} after")
    print(_line("image point", rec["points"]))
    print(_line("photo", rec["photos"]))
    if args.out:
        args.out.write_text(json.dumps(rec, indent=1))


if __name__ == "__main__":
    main()
