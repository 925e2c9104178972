"""Issue 33: `baarda online --bundle --watch` on a real COLMAP mapper run.

pycolmap synthesizes a scene (one camera, FRAMES images, POINTS points, tracks of TRACK
images; keypoints with Gaussian noise of NOISE px) into a COLMAP database, one keypoint of
the last image gets a blunder of BLUNDER px (below the mapper's 4 px filter, so that the
mapper keeps it), and COLMAP's incremental mapper (pycolmap.incremental_mapping) builds the
reconstruction, writing a snapshot every FREQ registered images.  Then the on-line bundle
takes the snapshots in as `baarda online --bundle --watch SNAPSHOTS --once` does
(baarda.online.watch.watch, image sigma NOISE px), and the last state is compared with
`baarda adjust` of the last snapshot.

    PYTHONPATH=$PWD python benchmarks/watch_colmap_mapper.py [--frames 12] [--points 400]
        [--track -1] [--freq 2] [--noise 0.5] [--blunder 3.5] [--keep DIR]

Prints the mapper's time (the peer, in the same run), the watch's time per snapshot, the
snapshot in which the blunder's image arrived and the one where it was rejected, and sigma0
and redundancy of the last state against `baarda adjust`.  Needs pycolmap (not a
dependency of baarda).
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np


def build(root: Path, frames: int, points: int, track: int, noise: float, blunder: float,
          freq: int) -> tuple[str, float]:
    """The database, the blunder and the mapper's snapshots under root; (the blundered
    image's name, the mapper's seconds)."""
    import pycolmap

    db_path = root / "database.db"
    db = pycolmap.Database.open(db_path)
    o = pycolmap.SyntheticDatasetOptions()
    o.num_rigs, o.num_cameras_per_rig, o.num_frames_per_rig = 1, 1, frames
    o.num_points3D, o.track_length = points, track
    o.camera_model_id = pycolmap.CameraModelId.SIMPLE_PINHOLE
    o.camera_params = [1280.0, 512.0, 384.0]
    truth = pycolmap.synthesize_dataset(o, db)
    n = pycolmap.SyntheticNoiseOptions()
    n.point2D_stddev = noise
    pycolmap.synthesize_noise(n, truth, db)
    last = max(truth.images)
    name = truth.images[last].name
    kp = db.read_keypoints(last)
    k = next(i for i, p in enumerate(truth.images[last].points2D) if p.has_point3D())
    kp[k, 0] += blunder
    db.update_keypoints(last, kp)
    db.close()
    snaps = root / "snapshots"
    snaps.mkdir()
    io = pycolmap.IncrementalPipelineOptions()
    io.snapshot_path, io.snapshot_frames_freq = str(snaps), freq
    io.ba_refine_focal_length = io.ba_refine_principal_point = False
    io.ba_refine_extra_params = False
    out = root / "sparse"
    out.mkdir()
    t0 = time.perf_counter()
    pycolmap.incremental_mapping(db_path, root, out, options=io)
    return name, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--points", type=int, default=400)
    ap.add_argument("--track", type=int, default=-1, help="images per point (-1: all)")
    ap.add_argument("--freq", type=int, default=2, help="images between snapshots")
    ap.add_argument("--noise", type=float, default=0.5, help="keypoint noise, px")
    ap.add_argument("--blunder", type=float, default=3.5, help="px, on the last image")
    ap.add_argument("--keep", type=Path, help="build here and keep it")
    a = ap.parse_args()
    import baarda
    from baarda.online.watch import watch

    root = a.keep or Path(tempfile.mkdtemp(prefix="mapper"))
    if a.keep:
        shutil.rmtree(root, ignore_errors=True)
        root.mkdir(parents=True)
    name, mapper_s = build(root, a.frames, a.points, a.track, a.noise, a.blunder, a.freq)
    photo = Path(name).stem
    snaps = sorted((root / "snapshots").iterdir(), key=lambda p: int(p.name))
    print(f"COLMAP incremental mapper: {a.frames} images, {a.points} points, tracks "
          f"{'all' if a.track < 0 else a.track}, noise {a.noise} px, {len(snaps)} snapshots "
          f"(one every {a.freq} images): {mapper_s:.2f} s")

    def read(p):
        return baarda.read(p, sigma_px=a.noise)

    seen: dict = {}
    t0 = time.perf_counter()

    def progress(snapshot, ans):
        seen.setdefault(snapshot, []).append(ans)

    w = watch(root / "snapshots", read=read, once=True, progress=progress)
    watch_s = time.perf_counter() - t0
    arrived = rejected = None
    for snap, answers in seen.items():
        for ans in answers:
            for t in ans.tested:
                if t.photo == photo and arrived is None:
                    arrived = snap
            hit = any(t.photo == photo and t.verdict == "reject" for t in ans.tested) or \
                any(c.photo == photo and c.after == "reject" for c in ans.changed)
            if hit and rejected is None:
                rejected = snap
    per = {s: sum(x.seconds for x in v) for s, v in seen.items()}
    print(f"baarda --watch: {len(seen)} snapshots, {sum(len(v) for v in seen.values())} "
          f"steps in {watch_s:.2f} s (with reading; ratio to the mapper "
          f"{watch_s / mapper_s:.2f}); per snapshot " + ", ".join(
              f"{1e3 * s:.0f} ms" for s in per.values()))
    print(f"the {a.blunder} px blunder on image {photo}: its image arrived in snapshot "
          f"{arrived}, rejected in {rejected}")
    res = w.online.result()
    ref = baarda.assess(baarda.adjust(read(snaps[-1])))
    print(f"last state: sigma0 {res.adjustment.sigma0:.6f}, redundancy "
          f"{res.adjustment.redundancy}; baarda adjust of the last snapshot: sigma0 "
          f"{ref.adjustment.sigma0:.6f}, redundancy {ref.adjustment.redundancy}; relative "
          f"difference {abs(res.adjustment.sigma0 / ref.adjustment.sigma0 - 1):.1e}")
    if not a.keep:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()
