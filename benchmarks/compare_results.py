"""Numbers unchanged by a performance change (issue 40): run `baarda adjust` on the README's
demo (--snoop) and on BAL Ladybug-49 (--calibrate none, the benchmark's options), and compare
the result folders with a reference made before the change; and a simulated BAL problem of
100 cameras with f, k1, k2 free (bench_bal_scale.simulate, seed 1: cameras.csv and the
calibration's entries of summary.json).

    PYTHONPATH=$PWD python benchmarks/compare_results.py --save /tmp/before   # before
    PYTHONPATH=$PWD python benchmarks/compare_results.py --against /tmp/before  # after

The tables (observations.csv, photos.csv, points.csv) must be byte-identical; summary.json
must be equal after dropping what changes from run to run: the run's id, every "seconds"
and the durations written into the notes ("0.58 s").  Exit 0 when everything is identical,
1 otherwise (each difference printed).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LADYBUG = Path("/work/shared/data/bal/problem-49-7776-pre.txt.bz2")
JOBS = {
    "demo": [str(ROOT / "examples" / "demo"), "--snoop"],
    "ladybug49": [str(LADYBUG), "--calibrate", "none"],
    "bal100": [str(Path(tempfile.gettempdir()) / "baarda-compare-bal100.txt")],
}
TABLES = ("observations.csv", "photos.csv", "points.csv", "cameras.csv")
DURATION = re.compile(r"\d+(\.\d+)? s\b")


def stable(value):
    """summary.json without what changes from run to run."""
    if isinstance(value, dict):
        return {k: stable(v) for k, v in value.items() if k not in ("run", "seconds")}
    if isinstance(value, list):
        return [stable(v) for v in value]
    if isinstance(value, str):
        return DURATION.sub("<duration> s", value)
    return value


def run(job: str, out: Path) -> None:
    if job == "bal100" and not Path(JOBS[job][0]).exists():
        sys.path.insert(0, str(ROOT / "benchmarks"))
        from bench_bal_scale import simulate, write

        write(simulate(100), Path(JOBS[job][0]))
    cmd = [sys.executable, "-m", "baarda", "adjust", *JOBS[job], "-o", str(out), "-q"]
    rc = subprocess.run(cmd, cwd=ROOT).returncode
    if rc not in (0, 3):  # 3: not converged is a result too
        raise SystemExit(f"{' '.join(cmd)}: exit {rc}")


def differences(ref: Path, new: Path) -> list[str]:
    out = []
    for name in TABLES:
        a, b = ref / name, new / name
        if a.exists() != b.exists():
            out.append(f"{name}: present in only one folder")
        elif a.exists() and a.read_bytes() != b.read_bytes():
            out.append(f"{name}: bytes differ")
    sa = stable(json.loads((ref / "summary.json").read_text()))
    sb = stable(json.loads((new / "summary.json").read_text()))
    if sa != sb:
        keys = sorted(k for k in set(sa) | set(sb) if sa.get(k) != sb.get(k))
        out.append(f"summary.json: differs in {', '.join(keys)}")
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--save", type=Path, help="write the reference folders here")
    g.add_argument("--against", type=Path, help="compare with the reference folders here")
    p.add_argument("--jobs", nargs="+", choices=sorted(JOBS), default=sorted(JOBS))
    args = p.parse_args()
    if args.save:
        for job in args.jobs:
            run(job, args.save / job)
            print(f"{job}: reference written to {args.save / job}")
        return 0
    bad = 0
    with tempfile.TemporaryDirectory(prefix="baarda-compare-") as tmp:
        for job in args.jobs:
            run(job, Path(tmp) / job)
            diff = differences(args.against / job, Path(tmp) / job)
            print(f"{job}: " + ("identical" if not diff else "; ".join(diff)))
            bad += bool(diff)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
