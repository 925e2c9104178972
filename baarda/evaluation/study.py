"""A Monte Carlo study of blunder detection: trials of simulated blocks with planted
blunders, each run through every strategy.

A trial is a pure function of (options, trial number): its block is simulated with a seed
drawn from SeedSequence([seed, trial]), its blunders from a stream of the same sequence, so
a study gives the same rows whether its trials run in this process, in a process pool or on
a Dask cluster (only the `seconds` column, a time, differs).

Each trial:
1. simulates the block without blunders and adjusts it: the MDB of every component (it
   depends on the geometry and the a-priori sigmas only);
2. plants `blunders` errors of `size_mdb` times the observation's own MDB (uniform between
   the two bounds, random sign) on distinct components of the chosen kinds that other
   observations control;
3. adjusts the blundered block once: the w-test of every planted component before any
   rejection (`w_first`), and the number of components with a significant w-test;
4. runs every strategy on the blundered block and records what it rejected and in which
   order (a strategy whose rejections make the block singular, e.g. a point left with one
   ray, is recorded as failed with the message, nothing located).

A planted blunder is *located strictly* (`strict`) when that very component is rejected by
its own test; *located* when it is rejected in the end, alone or as a member of a group
rejected or set aside as a whole (`grouped`'s partners, the on-line strategy's points set
aside and never taken in again, the rays measured again with a rejected one); *identified*
(up to its inseparable group) when it is located or a component it cannot be told from
(|rho| >= 0.99 in the blunder-free block, every component: one column of Qvv) is rejected;
and *first* when the first rejection takes it.  Every other component rejected (or set
aside) is a good one lost (`n_false`): the strict and the group counts are told with it.

Strategies: `snoop` (iterative w-test), `tau` (Pope's tau), `by-point` (snooping that
rejects an image point's x and y together), `grouped` (snooping that rejects a component
with the ones it cannot be told from, |rho| >= 0.99, where the block stays determined:
quality/iterative.py), `robust` (Danish method, then snooping),
`screen` (sequential screening before the bundle, then snooping), `modified` (Gruen's
modified snooping, one pass), `threshold` (iteratively reject the largest |v| / sigma above
THRESHOLD: a residual threshold without redundancy numbers, as the seeds compare), `online`
(the block measured again photo by photo in strip order, each photo tested as it comes, the
worst rejected observation taken out while there is one: online/replay.py; its blunder rows
also say whether the blunder was rejected at the step it was taken in, `at_entry`),
`online-remeasure` (the same, the operator measuring a rejected image point again: the
value of the block without blunders, one rejected again kept as confirmed; its "rejected"
are the components measured again).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from baarda.block.photo_block import Block
from baarda.bundle.bundle_model import BundleModel
from baarda.errors import GeometryError
from baarda.evaluation.strategies import (
    DEFAULT_STRATEGIES,
    STRATEGIES,
    Outcome,
    component_keys,
    run_strategy,
)
from baarda.linalg.threads import one_kernel_thread
from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.pipeline import adjust
from baarda.quality.iterative import inseparable_partners
from baarda.quality.separability import RHO_INSEPARABLE
from baarda.quality.statistics import QualityResult, analyse
from baarda.simulate.aerial import FlightPlan, simulate_block

if TYPE_CHECKING:
    import pandas as pd

KINDS = ("x", "y", "X", "Y", "Z")
R_MIN = 0.01  # a blunder is planted only where the observation's redundancy number is this

@dataclass(frozen=True)
class StudyOptions:
    """What a study simulates and runs.  size_mdb: (A, B), each blunder's size drawn
    uniformly between A and B times its observation's MDB (A = B: exactly A MDB)."""

    plan: FlightPlan = field(default_factory=FlightPlan)
    trials: int = 100
    blunders: int = 1
    size_mdb: tuple[float, float] = (1.0, 1.0)
    kinds: tuple[str, ...] = ("x", "y")
    strategies: tuple[str, ...] = DEFAULT_STRATEGIES
    seed: int = 0
    tests: TestOptions = DEFAULT_TESTS

    def __post_init__(self):
        bad = [s for s in self.strategies if s not in STRATEGIES]
        if bad:
            raise ValueError(f"unknown strategy '{bad[0]}' (one of {', '.join(STRATEGIES)})")
        bad = [k for k in self.kinds if k not in KINDS]
        if bad:
            raise ValueError(f"unknown blunder kind '{bad[0]}' (x, y, X, Y, Z)")
        if self.trials < 1 or self.blunders < 0:
            raise ValueError("trials must be at least 1 and blunders at least 0")
        a, b = self.size_mdb
        if not (0 <= a <= b):
            raise ValueError("blunder size in MDB: 0 <= A <= B")


@dataclass(frozen=True)
class TrialRows:
    """The rows of one trial: one per planted blunder and strategy, one per strategy."""

    blunders: list[dict]
    trials: list[dict]


def _plant(block: Block, model: BundleModel, rows: np.ndarray, sizes: np.ndarray) -> Block:
    """The block with `sizes` (model units: image mm, control m) added to the components
    `rows` of the flat observation vector."""
    im, pts = block.image, block.points
    xy, xyz = im.xy_mm.copy(), pts.xyz.copy()
    for i, s in zip(rows.tolist(), sizes.tolist(), strict=True):
        c = str(model.component[i])
        if model.image_row[i] >= 0:
            xy[model.image_row[i], "xy".index(c)] += s
        else:
            xyz[model.control_index[i], "XYZ".index(c)] += s
    return replace(block, image=replace(im, xy_mm=xy), points=replace(pts, xyz=xyz))


def run_trial(options: StudyOptions, trial: int) -> TrialRows:
    """Simulate, plant and run every strategy for trial number `trial` (module docstring).
    The numerical kernels run on one thread: trials are parallel across processes (a
    100-photo trial: 1.1 s so, 2.8 s with two threads on two busy cores)."""
    with one_kernel_thread():
        return _trial(options, trial)


@dataclass(frozen=True)
class PlantedBlock:
    """A trial's block: simulated without blunders (`block`, its adjustment `model` and
    statistics `q`), the flat components `rows` that get blunders of `size_mdb` times
    their MDB (`sizes` in model units), and the blundered block."""

    block: Block
    model: BundleModel
    q: QualityResult
    rows: np.ndarray
    size_mdb: np.ndarray
    sizes: np.ndarray
    blundered: Block


def planted_block(options: StudyOptions, trial: int) -> PlantedBlock:
    """Steps 1-2 of a trial (module docstring): the same block and blunders for every
    strategy, and for any tool that looks at one trial again."""
    seq = np.random.SeedSequence([options.seed, trial])
    plan = replace(options.plan, seed=int(seq.generate_state(1)[0] % 2**31), blunders=0,
                   noise=True)
    rng = np.random.default_rng(seq.spawn(1)[0])
    block, _ = simulate_block(plan)
    model = BundleModel(adjust(block))
    q = analyse(model, options.tests, separability=False)
    kind_ok = np.isin(model.component, options.kinds) & np.isin(model.kind,
                                                                ["image", "control"])
    candidates = np.flatnonzero(kind_ok & q.active & (q.redundancy_number >= R_MIN)
                                & np.isfinite(q.mdb))
    k = min(options.blunders, len(candidates))
    rows = np.sort(rng.choice(candidates, size=k, replace=False)) if k else \
        np.zeros(0, np.int64)
    a, b = options.size_mdb
    size_mdb = rng.uniform(a, b, k) * rng.choice([-1.0, 1.0], k)
    sizes = size_mdb * q.mdb[rows]
    return PlantedBlock(block, model, q, rows, size_mdb, sizes,
                        _plant(block, model, rows, sizes))


def _trial(options: StudyOptions, trial: int) -> TrialRows:
    p = planted_block(options, trial)
    model, q, rows, size_mdb, sizes = p.model, p.q, p.rows, p.size_mdb, p.sizes
    k = len(rows)
    # the components each blunder cannot be told from in the blunder-free block
    groups, rho_max = [], []
    for i in rows.tolist():
        idx, rho = inseparable_partners(model, q, i, model.active, threshold=0.0)
        big = np.abs(rho) >= RHO_INSEPARABLE
        groups.append(set(idx[big].tolist()))
        rho_max.append(float(np.max(np.abs(rho))) if len(rho) else 0.0)
    blundered = p.blundered
    fmodel = BundleModel(adjust(blundered))
    fq = analyse(fmodel, options.tests, separability=False)
    keys = component_keys(fmodel)
    planted = [keys[i] for i in rows]
    partner_keys = [{keys[j] for j in g} for g in groups]
    significant = np.abs(np.nan_to_num(fq.w)) > fq.k_w
    tested = fq.active & np.isfinite(fq.w)  # controlled components (r >= r_min)
    n_sig = int(np.sum(significant & tested))
    blunder_rows, trial_rows = [], []
    unit = np.where(model.kind[rows] == "image", 1e3, 1.0)  # µm, m
    for name in options.strategies or ("",):  # none: the first adjustment only
        t0 = time.perf_counter()
        if not name:
            out, failed = Outcome([], set(), float(fmodel.result.sigma0)), ""
        else:
            try:
                out, failed = run_strategy(name, blundered, options.tests, p.block), ""
            except GeometryError as e:  # e.g. a rejection that leaves a point with one ray
                out, failed = Outcome([], set(), float("nan")), str(e)
        rejected, sigma0 = out.rejected, out.sigma0
        seconds = time.perf_counter() - t0
        rank = {key: n + 1 for n, key in enumerate(rejected)}
        located = [key in rank for key in planted]
        own = out.located_strictly
        strict = [key in own for key in planted]
        identified = [loc or bool(pk & set(rank)) for loc, pk in
                      zip(located, partner_keys, strict=True)]
        for j, i in enumerate(rows.tolist()):
            kind, photo, point, comp = planted[j]
            blunder_rows.append({
                "trial": trial, "strategy": name, "kind": kind, "photo": photo,
                "point": point, "component": comp, "size": float(sizes[j] * unit[j]),
                "unit": "um" if kind == "image" else "m", "size_mdb": float(size_mdb[j]),
                "w_first": float(fq.w[i]), "significant_first": bool(significant[i]),
                "rho_max": rho_max[j], "separable": not groups[j],
                "located": located[j], "strict": strict[j], "identified": identified[j],
                "first": planted[j] in out.first, "rank": rank.get(planted[j]),
                "at_entry": None if out.entry is None else out.entry.get(planted[j], "held")})
        trial_rows.append({
            "trial": trial, "strategy": name, "n_observations": int(model.n),
            "n_planted": k, "n_located": int(sum(located)), "n_strict": int(sum(strict)),
            "n_identified": int(sum(identified)),
            "n_false": len(set(rejected) - set(planted)),
            "n_tested_first": int(tested.sum()), "n_significant_first": n_sig,
            "sigma0_final": sigma0, "failed": failed,
            "seconds": seconds})
    return TrialRows(blunder_rows, trial_rows)


@dataclass(frozen=True)
class Study:
    """The rows of every trial (pandas DataFrames) and the options that made them."""

    options: StudyOptions
    blunders: pd.DataFrame
    trials: pd.DataFrame
    seconds: float

    def rates(self) -> dict:
        """Per strategy: located rate and false rejections with 95 % Clopper-Pearson
        intervals; the share of planted components significant in the first adjustment
        and of significant components among the unplanted ones (B-method checks)."""
        from baarda.evaluation.rates import study_rates

        return study_rates(self)

    def summary(self) -> str:
        r = self.rates()
        o = self.options
        lines = [f"{o.trials} trials of {o.plan.strips} x {o.plan.photos_per_strip} photos, "
                 f"{o.blunders} blunder(s) of {o.size_mdb[0]:g}-{o.size_mdb[1]:g} MDB "
                 f"({', '.join(o.kinds)}), alpha0 {o.tests.alpha0:g}, beta0 {o.tests.beta0:g}; "
                 f"{self.seconds:.1f} s"]
        f = r["first_adjustment"]
        if f["planted"]:
            lines.append(f"planted blunders significant in the first adjustment: "
                         f"{f['planted_significant']}/{f['planted']} = {f['power']:.3f} "
                         f"[{f['power_ci'][0]:.3f}, {f['power_ci'][1]:.3f}] (B-method: "
                         f"{o.tests.beta0:g} at 1 MDB)")
        share = (f"{f['false_share']:.5f} [{f['false_ci'][0]:.5f}, {f['false_ci'][1]:.5f}]")
        if f["planted"]:
            lines.append(f"spill-over: unplanted components significant in the first "
                         f"adjustment {share} (the blunders' correlated neighbours, and false "
                         f"alarms at alpha0 {o.tests.alpha0:g})")
        else:
            b = f["blocks_with_false_alarm"]
            lines.append(f"false alarms: components significant in the first adjustment "
                         f"{share} (alpha0 {o.tests.alpha0:g}); blocks with at least one "
                         f"|w| > k: {b['k']}/{b['n']} = {b['rate']:.3f} [{b['ci'][0]:.3f}, "
                         f"{b['ci'][1]:.3f}] (independent tests: "
                         f"{b['independent_tests']:.3f})")
        for name, s in r["strategies"].items():
            if not s["planted"]:
                lines.append(f"{name:<10} good observations rejected "
                             f"{s['false_per_trial']:.2f} per trial ({s['false_rate']:.5f}), "
                             f"{s['seconds_per_trial']:.3f} s per trial")
                continue
            lines.append(f"{name:<10} located strictly {_fmt(s['strict'])}, identified up to "
                         f"its group {_fmt(s['identified'])}; good components lost "
                         f"{s['false_per_trial']:.2f} per trial ({s['false_rate']:.5f})")
            lines.append(f"{'':<10} located {s['located']}/{s['planted']} = "
                         f"{s['located_rate']:.3f} [{s['located_ci'][0]:.3f}, "
                         f"{s['located_ci'][1]:.3f}] (alone or with a group rejected or set "
                         f"aside as a whole), rejected first {_fmt(s['first'])}; "
                         f"{s['seconds_per_trial']:.3f} s per trial")
            if s["inseparable_located"]["n"]:
                lines.append(f"{'':<10} separable blunders: strictly "
                             f"{_fmt(s['separable_strict'])}, located "
                             f"{_fmt(s['separable_located'])}; not separable (|rho| >= "
                             f"{RHO_INSEPARABLE}): strictly {_fmt(s['inseparable_strict'])}, "
                             f"located {_fmt(s['inseparable_located'])}, identified up to the "
                             f"group {_fmt(s['inseparable_identified'])}")
            if "rejected_at_entry" in s:
                lines.append(f"{'':<10} rejected when taken in {s['rejected_at_entry']}/"
                             f"{s['planted']} = {s['at_entry_rate']:.3f} "
                             f"[{s['at_entry_ci'][0]:.3f}, {s['at_entry_ci'][1]:.3f}], not "
                             f"checked then (suspect) {s['suspect_at_entry']}")
        return "\n".join(lines)


def _fmt(r: dict) -> str:
    return f"{r['k']}/{r['n']} = {r['rate']:.3f} [{r['ci'][0]:.3f}, {r['ci'][1]:.3f}]"


def run_study(options: StudyOptions, *, workers: int = 1, scheduler: str | None = None,
              progress: Callable[[int, int], None] | None = None) -> Study:
    """Every trial of a study: in this process (workers 1), a local process pool (workers
    > 1) or on a running Dask distributed scheduler (its address, e.g. tcp://host:8786)."""
    import pandas as pd

    t0 = time.perf_counter()
    trials = range(options.trials)
    if scheduler is not None:
        results = _on_dask(options, trials, scheduler, progress)
    elif workers > 1:
        results = _in_pool(options, trials, workers, progress)
    else:
        results = []
        for n, t in enumerate(trials):
            results.append(run_trial(options, t))
            if progress:
                progress(n + 1, options.trials)
    blunders = pd.DataFrame([r for t in results for r in t.blunders],
                            columns=BLUNDER_COLUMNS)
    rows = pd.DataFrame([r for t in results for r in t.trials], columns=TRIAL_COLUMNS)
    return Study(options, blunders, rows, time.perf_counter() - t0)


BLUNDER_COLUMNS = ["trial", "strategy", "kind", "photo", "point", "component", "size", "unit",
                   "size_mdb", "w_first", "significant_first", "rho_max", "separable",
                   "located", "strict", "identified", "first", "rank", "at_entry"]
TRIAL_COLUMNS = ["trial", "strategy", "n_observations", "n_planted", "n_located", "n_strict",
                 "n_identified", "n_false", "n_tested_first", "n_significant_first",
                 "sigma0_final", "failed", "seconds"]


def _in_pool(options, trials: Iterable[int], workers: int, progress) -> list[TrialRows]:
    from concurrent.futures import ProcessPoolExecutor, as_completed

    out: dict[int, TrialRows] = {}
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(run_trial, options, t): t for t in trials}
        try:
            for n, f in enumerate(as_completed(futures)):
                out[futures[f]] = f.result()
                if progress:
                    progress(n + 1, len(futures))
        except BaseException:  # Ctrl-C, SIGTERM: the trials not started are not run
            pool.shutdown(wait=True, cancel_futures=True)
            raise
    return [out[t] for t in sorted(out)]


def _on_dask(options, trials: Iterable[int], address: str, progress) -> list[TrialRows]:
    try:
        from distributed import Client, as_completed
    except ImportError:  # pragma: no cover - distributed is a dependency of the test extra
        raise RuntimeError("--scheduler needs Dask distributed: pip install distributed") \
            from None
    out: dict[int, TrialRows] = {}
    with Client(address) as client:
        trials = list(trials)
        futures = client.map(run_trial, [options] * len(trials), trials, pure=False)
        index = {f.key: t for f, t in zip(futures, trials, strict=True)}
        for n, f in enumerate(as_completed(futures)):
            out[index[f.key]] = f.result()
            if progress:
                progress(n + 1, len(trials))
    return [out[t] for t in sorted(out)]
