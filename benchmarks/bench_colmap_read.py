"""Reading a large COLMAP sparse model (issue 19), after the imports.

    PYTHONPATH=. python benchmarks/bench_colmap_read.py [--images 2000 --points 200000 --track 5]

Writes a synthetic model (one PINHOLE camera; every point seen in `track` images, so
points x track observations; 10 keypoints without a 3D point per image) as text and as
binary files into a temporary folder and times `read_colmap` of each (best of --repeat,
after one untimed read that loads numba's kernels), `colmap_to_block`, and, for
comparison, the text files read by the line-by-line reference reader that every error
message goes through.  Not a test.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from baarda.io import colmap_text
from baarda.io.colmap import ColmapCamera, ColmapImages, ColmapModel, ColmapPoints, read_colmap
from baarda.io.colmap_block import colmap_to_block
from baarda.output.format_files import write_colmap


def synthetic_model(n_images: int, n_points: int, track: int, extra: int = 10,
                    seed: int = 0) -> ColmapModel:
    """Point j is seen in `track` distinct images (a random start plus fixed steps); the
    keypoints of an image are its points in point order, then `extra` without a point."""
    rng = np.random.default_rng(seed)
    step = rng.choice(n_images, size=track, replace=False)  # distinct images per point
    image = ((rng.integers(n_images, size=n_points)[:, None] + step) % n_images).ravel()
    point = np.repeat(np.arange(n_points), track)
    order = np.lexsort((point, image))
    seen = np.bincount(image, minlength=n_images)
    first = np.concatenate([[0], np.cumsum(seen)])  # first element of each image (sorted)
    offsets = np.concatenate([[0], np.cumsum(seen + extra)])
    slot = np.arange(len(order)) - first[image[order]]
    idx = np.empty(len(point), np.int64)
    idx[order] = slot
    pids = np.full(offsets[-1], -1, np.int64)
    pids[offsets[image[order]] + slot] = point[order] + 1
    images = ColmapImages(np.arange(1, n_images + 1), np.tile([1.0, 0, 0, 0], (n_images, 1)),
                          np.zeros((n_images, 3)), np.ones(n_images, np.int64),
                          [f"img{i}.jpg" for i in range(n_images)], offsets,
                          rng.uniform(0, 4000, (offsets[-1], 2)), pids)
    points = ColmapPoints(np.arange(1, n_points + 1), rng.normal(size=(n_points, 3)),
                          np.tile(np.array([1, 2, 3], np.uint8), (n_points, 1)),
                          np.full(n_points, 0.5), track * np.arange(n_points + 1), image + 1,
                          idx)
    camera = ColmapCamera("PINHOLE", 6000, 4000, np.array([5000.0, 5000, 3000, 2000]))
    return ColmapModel({1: camera}, images, points)


def best(func, repeat: int) -> tuple[float, object]:
    t, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = func()
        t = min(t, time.perf_counter() - t0)
    return t, out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--images", type=int, default=2000)
    ap.add_argument("--points", type=int, default=200_000)
    ap.add_argument("--track", type=int, default=5, help="observations per point")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    model = synthetic_model(args.images, args.points, args.track)
    with tempfile.TemporaryDirectory() as tmp:
        txt, bin_ = Path(tmp) / "txt", Path(tmp) / "bin"
        write_colmap(model, txt)
        write_colmap(model, bin_, binary=True)
        mb = {f: sum(p.stat().st_size for p in f.iterdir()) / 1e6 for f in (txt, bin_)}
        read_colmap(bin_)
        read_colmap(txt)  # numba's kernels loaded (or compiled) before the timing
        t_txt, _ = best(lambda: read_colmap(txt), args.repeat)
        t_bin, m = best(lambda: read_colmap(bin_), args.repeat)
        t_block, block = best(lambda: colmap_to_block(m), args.repeat)
        fast = colmap_text._images_fast, colmap_text._points_fast
        colmap_text._images_fast = colmap_text._points_fast = lambda *a: None
        try:
            t_lines, _ = best(lambda: read_colmap(txt), 1)
        finally:
            colmap_text._images_fast, colmap_text._points_fast = fast
    print(f"COLMAP model: {args.images} images, {args.points} points, "
          f"{len(m.points.image_ids)} observations, {len(m.images.xys)} keypoints "
          f"(text {mb[txt]:.0f} MB, binary {mb[bin_]:.0f} MB); best of {args.repeat}")
    print(f"read_colmap text   {t_txt:.3f} s   (line-by-line reader {t_lines:.2f} s)")
    print(f"read_colmap binary {t_bin:.3f} s")
    print(f"colmap_to_block    {t_block:.3f} s   ({len(block.image)} image points)")


if __name__ == "__main__":
    main()
