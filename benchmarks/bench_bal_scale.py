"""BAL scale (issue 32): simulated BAL problems with a camera per photo, f, k1, k2 free.

    PYTHONPATH=$PWD python benchmarks/bench_bal_scale.py 100 256 1000 [--repeat N]

For each number of cameras: a BAL file is simulated (`simulate`, written as plain text), then
each engine runs on it in its own process, one after the other (interleaved when repeated):

* baarda: read the file, prepare (free network), adjust, and the statistics of every
  observation (`baarda.assess`: r, w, MDB, external reliability of every component);
* pycolmap: read the file, build the Reconstruction, bundle adjustment refining f and the
  extra parameters (k1, k2) of every camera (COLMAP's RADIAL model; the settings of
  bench_bal.py), trivial loss, two-camera gauge.

Printed per engine: the wall time and peak resident memory of the whole process, and the
time of each phase (baarda: read, prepare, adjust, assess; pycolmap: read and build, solve),
final costs 0.5 sum(r^2) in px^2 and their relative difference.

The scene: cameras on rings of 25 (radius 10 m, one ring every 10 m of height, staggered),
each looking outward with a small random tilt; points scattered between radius 25 and 45 m
all round and over the tower's height; an observation where a point projects into the
800 x 600 px image.  Focal lengths about 1000 px (+- 3 %), k1 about -0.05, k2 about 0.01
per camera; image noise 0.5 px; the file's values are the truth perturbed (positions
0.05 m, angles 1 mrad, points 0.05 m, f 0.5 %), so both engines start from the same values.
Points seen fewer than twice are left out.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from pycolmap_bal_user import adjust, adjuster_options, reconstruction, rodrigues

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RING = 25  # cameras per ring
RING_RADIUS, RING_STEP = 10.0, 10.0  # m
HALF_W, HALF_H = 400.0, 300.0  # px


def _rotation_vector(r: np.ndarray) -> np.ndarray:
    """Rodrigues vectors of rotation matrices (n, 3, 3) (angles below pi)."""
    cos = np.clip((np.trace(r, axis1=1, axis2=2) - 1) / 2, -1, 1)
    theta = np.arccos(cos)
    w = np.stack([r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]], 1)
    s = np.where(theta > 1e-12, theta / (2 * np.sin(np.maximum(theta, 1e-12))), 0.5)
    return w * s[:, None]


def _project(cams: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """BAL's projection of every point on one camera: (xy (n, 2) px, depth -P.z)."""
    pc = pts @ rodrigues(cams[None, :3])[0].T + cams[3:6]
    q = -pc[:, :2] / pc[:, 2:3]
    n2 = np.sum(q**2, axis=1)
    return (cams[6] * (1 + cams[7] * n2 + cams[8] * n2**2))[:, None] * q, -pc[:, 2]


def simulate(n_cameras: int, seed: int = 1) -> dict:
    """A BAL problem (module docstring): cameras (n, 9), points, observations, as the
    file holds them (perturbed start values)."""
    rng = np.random.default_rng(seed)
    rings = -(-n_cameras // RING)
    k = np.arange(n_cameras)
    ring = k // RING
    az = 2 * np.pi * ((k % RING) + 0.5 * (ring % 2)) / RING + rng.normal(0, 0.02, n_cameras)
    centre = np.column_stack([RING_RADIUS * np.cos(az), RING_RADIUS * np.sin(az),
                              RING_STEP * ring + rng.normal(0, 0.3, n_cameras)])
    look = np.column_stack([np.cos(az), np.sin(az), rng.normal(0, 0.05, n_cameras)])
    look /= np.linalg.norm(look, axis=1)[:, None]
    z = -look  # BAL: the camera looks along -z
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x, axis=1)[:, None]
    r = np.stack([x, np.cross(z, x), z], axis=1)  # world -> camera
    cams = np.zeros((n_cameras, 9))
    cams[:, :3] = _rotation_vector(r)
    cams[:, 3:6] = -np.einsum("nij,nj->ni", r, centre)
    cams[:, 6] = 1000.0 * (1 + rng.normal(0, 0.03, n_cameras))
    cams[:, 7] = -0.05 + rng.normal(0, 0.01, n_cameras)
    cams[:, 8] = 0.01 + rng.normal(0, 0.003, n_cameras)
    height = RING_STEP * rings
    n_points = int(260 * n_cameras)
    rad = rng.uniform(25, 45, n_points)
    ang = rng.uniform(0, 2 * np.pi, n_points)
    pts = np.column_stack([rad * np.cos(ang), rad * np.sin(ang),
                           np.sort(rng.uniform(-8, height - 2, n_points))])
    obs_c, obs_p, obs_xy = [], [], []
    for i in range(n_cameras):
        lo, hi = np.searchsorted(pts[:, 2], [centre[i, 2] - 40, centre[i, 2] + 40])
        near = np.arange(lo, hi)
        xy, depth = _project(cams[i], pts[near])
        ok = (depth > 1) & (np.abs(xy[:, 0]) < HALF_W) & (np.abs(xy[:, 1]) < HALF_H)
        obs_c.append(np.full(int(ok.sum()), i))
        obs_p.append(near[ok])
        obs_xy.append(xy[ok])
    cam, pt, xy = np.concatenate(obs_c), np.concatenate(obs_p), np.concatenate(obs_xy)
    rays = np.bincount(pt, minlength=n_points)
    used = rays >= 2
    keep = used[pt]
    new = np.cumsum(used) - 1
    cam, pt, xy = cam[keep], new[pt[keep]], xy[keep]
    pts = pts[used]
    xy = xy + rng.normal(0, 0.5, xy.shape)
    start = cams.copy()
    start[:, :3] += rng.normal(0, 1e-3, (n_cameras, 3))
    start[:, 3:6] += rng.normal(0, 0.05, (n_cameras, 3))
    start[:, 6] *= 1 + rng.normal(0, 0.005, n_cameras)
    return {"cameras": start, "points": pts + rng.normal(0, 0.05, pts.shape), "camera": cam,
            "point": pt, "xy": xy}


def write(problem: dict, path: Path) -> None:
    """The problem as a BAL text file."""
    cams, pts = problem["cameras"], problem["points"]
    with open(path, "w", encoding="ascii") as fh:
        fh.write(f"{len(cams)} {len(pts)} {len(problem['xy'])}\n")
        rows = np.column_stack([problem["camera"], problem["point"], problem["xy"]])
        np.savetxt(fh, rows, fmt=["%d", "%d", "%.17g", "%.17g"])
        np.savetxt(fh, cams.reshape(-1, 1), fmt="%.17g")
        np.savetxt(fh, pts.reshape(-1, 1), fmt="%.17g")


# ---------------------------------------------------------------- workers (processes)
def worker_baarda(path: str, out: str, damping: str = "gn") -> None:
    t0 = time.perf_counter()
    import baarda
    from baarda.pipeline import prepare

    t_imp = time.perf_counter()
    block = baarda.read(path)
    t_read = time.perf_counter()
    problem = prepare(block, solve=damping)
    t_prep = time.perf_counter()
    res = problem.fit()
    t_adj = time.perf_counter()
    qc = baarda.assess(res)
    r = qc.quality.redundancy_number
    t_ass = time.perf_counter()
    Path(out).write_text(json.dumps({
        "import_s": t_imp - t0, "read_s": t_read - t_imp, "prepare_s": t_prep - t_read,
        "adjust_s": t_adj - t_prep, "assess_s": t_ass - t_adj, "iterations": res.iterations,
        "converged": bool(res.converged), "cost": 0.5 * res.vtpv,
        "observations": int(res.n_observations), "unknowns": int(res.n_unknowns),
        "sum_r": float(np.nansum(r)), "redundancy": int(res.redundancy),
        "max_abs_w": float(np.nanmax(np.abs(qc.quality.w))),
        "photo_block": int(problem.system.b), "damping": damping,
        "message": res.notes[-1] if not res.converged and res.notes else ""}))


def worker_pycolmap(path: str, out: str, damping: str = "") -> None:
    t0 = time.perf_counter()
    with open(path, encoding="ascii") as fh:
        nc, npt, nobs = (int(v) for v in fh.readline().split())
        obs = np.loadtxt(fh, max_rows=nobs)
        rest = np.loadtxt(fh).ravel()
    cams, pts = rest[: 9 * nc].reshape(nc, 9), rest[9 * nc:].reshape(npt, 3)
    cam_idx, pt_idx, xy = obs[:, 0].astype(int), obs[:, 1].astype(int), obs[:, 2:]
    opts = adjuster_options(True, 200)
    so = opts.ceres.solver_options
    rec = reconstruction(cams, pts, cam_idx, pt_idx, xy)
    t_read = time.perf_counter()
    summary = adjust(rec, opts)
    t_solve = time.perf_counter()
    cs = summary.ceres_summary
    Path(out).write_text(json.dumps({
        "read_s": t_read - t0, "solve_s": t_solve - t_read, "cost": cs.final_cost,
        "initial_cost": cs.initial_cost,
        "iterations": cs.num_successful_steps + cs.num_unsuccessful_steps,
        "termination": str(cs.termination_type), "threads": so.num_threads,
        "linear_solver": str(so.linear_solver_type)}))


def _spawn(engine: str, path: Path, out: Path, damping: str = "gn") -> dict:
    """One engine in its own process: its record with the process' wall s and peak MB."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in [env.get("PYTHONPATH")] if p])
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, __file__, "--worker", engine, str(path), str(out),
                             damping], env=env, cwd=ROOT)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        return {"failed": os.waitstatus_to_exitcode(status), "wall_s": wall,
                "peak_mb": usage.ru_maxrss / 1024}
    rec = json.loads(out.read_text())
    rec.update(wall_s=wall, peak_mb=usage.ru_maxrss / 1024)
    return rec


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cameras", type=int, nargs="*", default=[100, 256, 1000])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--engines", nargs="*", default=["baarda", "pycolmap"])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--damping", choices=["gn", "lm"], default="gn",
                    help="baarda's solver: Gauss-Newton with step halving (the default) or "
                         "Levenberg-Marquardt")
    ap.add_argument("--folder", type=Path, default=None, help="keep the files here")
    args = ap.parse_args(argv)
    folder = args.folder or Path(tempfile.mkdtemp(prefix="bal-scale-"))
    folder.mkdir(parents=True, exist_ok=True)
    load = " ".join(Path("/proc/loadavg").read_text().split()[:3])
    lines = []
    for n in args.cameras:
        path = folder / f"problem-{n}-sim.txt"
        if not path.exists():
            p = simulate(n, args.seed)
            write(p, path)
            print(f"{path.name}: {n} cameras, {len(p['points'])} points, {len(p['xy'])} "
                  f"observations", file=sys.stderr, flush=True)
        runs: dict[str, list[dict]] = {e: [] for e in args.engines}
        for _ in range(args.repeat):
            for engine in args.engines:
                rec = _spawn(engine, path, folder / f"{engine}-{n}.json", args.damping)
                print(f"  {engine} {n}: {json.dumps(rec)}", file=sys.stderr, flush=True)
                runs[engine].append(rec)
        lines.append((n, runs))
    print(f"\n{os.cpu_count()} CPUs, load average {load} before; median of {args.repeat}")
    print("| cameras | observations | engine | process s | peak MB | phases s | iterations "
          "| cost | rel. diff |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n, runs in lines:
        costs = {e: r[-1].get("cost") for e, r in runs.items() if r and "cost" in r[-1]}
        for engine, rs in runs.items():
            ok = [r for r in rs if "failed" not in r]
            if not ok:
                print(f"| {n} | | {engine} | failed ({rs[-1]}) | | | | | |")
                continue
            med = {k: statistics.median(r[k] for r in ok) for k in ok[0]
                   if isinstance(ok[0][k], float)}
            if engine == "baarda":
                ph = (f"read {med['read_s']:.2f}, prepare {med['prepare_s']:.2f}, adjust "
                      f"{med['adjust_s']:.2f}, assess {med['assess_s']:.2f}")
                obs = ok[0]["observations"]
            else:
                ph = f"read {med['read_s']:.2f}, solve {med['solve_s']:.2f}"
                obs = ""
            rel = ""
            if len(costs) == 2:
                a, b = costs.values()
                rel = f"{abs(a - b) / b:.1e}"
            its = f"{ok[0]['iterations']}" + ("" if ok[-1].get("converged", True) else
                                               " (NOT converged)")
            print(f"| {n} | {obs} | {engine} | {med['wall_s']:.2f} | {med['peak_mb']:.0f} | "
                  f"{ph} | {its} | {ok[-1]['cost']:.10g} | {rel} |")
    return 0


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        {"baarda": worker_baarda, "pycolmap": worker_pycolmap}[sys.argv[2]](*sys.argv[3:6])
        sys.exit(0)
    sys.exit(main())
