"""Data snooping and reliability of a bundle adjustment: glue between bundle and quality.

Both return an Assessment (quality/assessment.py): the adjustment with the statistics of
every observation.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import cast

import numpy as np

from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.bundle_result import BundleResult
from baarda.options import Progress, TestOptions
from baarda.quality.assessment import Assessment
from baarda.quality.hypotheses import HypothesisTest, parameter_test
from baarda.quality.iterative import iterative_snooping
from baarda.quality.robust import danish_method
from baarda.quality.statistics import analyse


def assess(result: BundleResult, tests: TestOptions | None = None, *,
           separability: bool = True) -> Assessment[BundleResult]:
    """Statistics of every observation of an adjusted block, without rejecting any.

    tests: alpha0 and beta0 (default: the project's settings); separability: the w-test
    correlations (rho_max, its partner, the MSB) too (False: left None)."""
    tests = tests or TestOptions.resolve(result.block.settings)
    model = BundleModel(result)
    q = analyse(model, tests, separability=separability)
    return Assessment(result, model, q, hypotheses=calibration_tests(result, tests))


def calibration_tests(result: BundleResult, tests: TestOptions) -> tuple[HypothesisTest, ...]:
    """The significance test of each group of estimated camera parameters (interior
    orientation, radial, decentring, affinity; Ebner's or Gruen's set), camera by camera,
    and of each group of GNSS/IMU unknowns (a shift per block or strip, a strip's drift,
    the boresight): is it needed?"""
    cal = result.problem.calibration
    gi = result.problem.gnss_imu
    if not cal.n and not gi.n:
        return ()
    out = []
    for i, cid in enumerate(result.block.cameras.ids):
        groups = cal.groups(i)
        if not groups:
            continue
        values, qi = result.camera_parameters(i), result.camera_cofactors(i)
        for label, rows in groups:
            if label == "interior orientation":  # tested against the nominal values
                est = values[rows] - cal.nominal[i][cal.free_index[i][rows]]
            else:
                est = values[rows]
            out.append(parameter_test(f"{label} of camera {cid}", est, qi[np.ix_(rows, rows)],
                                      tests))
    if not gi.n:
        return tuple(out)
    g = result.state[2]
    q = result.factor.global_covariance()
    for label, c in gi.parameter_groups():  # GNSS shifts and drifts, IMU boresight
        out.append(parameter_test(label, g[c], q[np.ix_(c, c)], tests))
    return tuple(out)


def snoop(problem: BundleProblem, tests: TestOptions | None = None, *,
          statistic: str = "w", by_point: bool = False, max_iterations: int = 200,
          robust: bool = False, inseparable: str = "flag",
          progress: Progress | None = None) -> Assessment[BundleResult]:
    """Iterative data snooping of a bundle block (re-adjusting after each rejection).

    `problem`: the BundleProblem of a prepared block (pipeline.prepare: local frame,
    approximations, datum; pipeline.snoop takes a block as read).  With `robust`, the
    Danish method first down-weights large errors; the components it leaves with (almost)
    no weight start out rejected and are tested again by snooping.  `inseparable`: what a
    rejection does with the components it cannot be told from (quality/iterative.py):
    "flag" them, or reject the "group".
    """
    tests = tests or TestOptions.resolve(problem.block.settings)
    t0 = time.perf_counter()
    result = problem.fit(progress=progress)
    if not result.converged:  # tests on a solution that is none would mislead
        note = "data snooping not run: the adjustment did not converge"
        if progress:
            progress(note)
        return assess(replace(result, notes=result.notes + (note,)), tests)
    first = BundleModel(result)
    active = first.active.copy()
    if robust:
        rob = danish_method(first)
        active &= ~rob.rejected
        if progress:
            progress(f"Danish method: {rob.iterations} re-weightings, "
                     f"{int(rob.rejected.sum())} component(s) down-weighted to rejection")
    run = iterative_snooping(first, tests, active=active, statistic=statistic,
                             by_group=by_point, max_iterations=max_iterations,
                             started_by="Danish method" if robust else "",
                             inseparable=inseparable, progress=progress)
    last = cast(BundleModel, run.model).result
    # re-adjustments taken: one per rejection and restoration, one after the Danish method
    refits = sum(s.iteration > 0 and s.action in ("reject", "restore") for s in run.log) + \
        int(not np.array_equal(active, first.active))
    final = replace(last, iterations=result.iterations, seconds=time.perf_counter() - t0,
                    refits=(refits, last.iterations) if refits else (0, 0))
    return Assessment(final, run.model, run.quality, run,
                      hypotheses=calibration_tests(last, run.quality.tests))
