"""Reading a native project with millions of image points (issue 19), after the imports.

    PYTHONPATH=. python benchmarks/bench_read.py [--points 2000000]

Writes a synthetic project (one camera, 20,000 photos, 500,000 points, N image points as
the writer writes them) into a temporary folder and times `read_project`: the fast reader
(pyarrow) and, for comparison, the line-by-line reader that every non-plain file and every
error message goes through.  Not a test.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from baarda.io import table
from baarda.io.project import read_project


def write_project(folder: Path, n: int, photos: int = 20000, points: int = 500000) -> None:
    rng = np.random.default_rng(0)
    (folder / "project.toml").write_text('name = "big"\nangle_unit = "gon"\n')
    (folder / "cameras.csv").write_text("camera,focal_mm,x0_mm,y0_mm\nc,153.0,0.0,0.0\n")
    rows = [f"P{i:05d},c,{i // 100},{i * 10.0},{i * 5.0},1500.0,0,0,0" for i in range(photos)]
    (folder / "photos.csv").write_text("photo,camera,strip,X0,Y0,Z0,omega,phi,kappa\n"
                                       + "\n".join(rows) + "\n")
    rows = [f"T{j:06d},{j * 1.0},{j * 2.0},100.0,control" for j in range(0, points, 5000)]
    (folder / "ground_points.csv").write_text("point,X,Y,Z,role\n" + "\n".join(rows) + "\n")
    # distinct (photo, point) pairs: n different keys drawn from photos x points
    key = rng.choice(photos * points, size=n, replace=False)
    ph, pt = np.divmod(key, points)
    x, y = rng.uniform(-115, 115, n), rng.uniform(-115, 115, n)
    with open(folder / "image_points.csv", "w") as f:
        f.write("photo,point,x_mm,y_mm,sigma_um\n")
        f.write("\n".join(f"P{a:05d},T{b:06d},{c!r},{d!r},5" for a, b, c, d in
                          zip(ph.tolist(), pt.tolist(), x.tolist(), y.tolist(), strict=True)))
        f.write("\n")


def timed(folder: Path, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        block = read_project(folder)
        best = min(best, time.perf_counter() - t0)
    assert len(block.image) > 0
    return best


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=2_000_000, help="image points")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        write_project(folder, args.points)
        size = (folder / "image_points.csv").stat().st_size / 1e6
        fast = timed(folder, args.repeat)
        plain = table.plain
        table.plain = lambda data: False  # every file line by line
        try:
            slow = timed(folder, 1)
        finally:
            table.plain = plain
    print(f"read_project, {args.points} image points ({size:.0f} MB image_points.csv): "
          f"fast reader {fast:.2f} s (best of {args.repeat}), line-by-line reader {slow:.2f} s")


if __name__ == "__main__":
    main()
