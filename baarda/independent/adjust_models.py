"""Gauss-Newton driver of the independent-model adjustment (sparse Schur system)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from baarda.block.model_block import ModelBlock
from baarda.errors import GeometryError
from baarda.independent.model_problem import ModelProblem
from baarda.independent.model_result import ModelResult

Progress = Callable[[str], None]


def _cost(lin) -> float:
    return float(np.sum(lin.w * lin.e**2) + np.sum(lin.wc * lin.ec**2))


def adjust_models(block: ModelBlock, mode: str = "3d", *, problem: ModelProblem | None = None,
                  start: tuple[np.ndarray, np.ndarray] | None = None,
                  max_iterations: int = 50, tolerance: float = 1e-12,
                  progress: Progress | None = None, **problem_args) -> ModelResult:
    """Adjust the model block; returns a ModelResult.

    `start` = (params (nm, b) with T reduced by problem.origin, points (np_used, d) reduced);
    without it the approximations come from the pre-adjustment connection of the models
    (3d, 2d) or zero (height: the model is linear).  Gauss-Newton with step halving.
    """
    t0 = time.perf_counter()
    say = progress or (lambda msg: None)
    if problem is None:
        problem = ModelProblem(block, mode, **problem_args)
    mode = problem.mode
    notes: list[str] = []
    if start is None:
        if mode == "height":
            params = np.zeros((block.n_models, 3))
            pts = np.zeros((len(problem.point_ids), 1))
        else:
            from baarda.independent.preadjust import approximations

            params, pts = approximations(problem)
    else:
        params, pts = (np.array(a, float) for a in start)
    system = problem.system
    med_mu = float(np.median(params[:, -1])) if mode != "height" else 1.0
    size = problem.radius / med_mu  # m: typical model radius in the terrain
    lin = problem.linearize(params, pts)
    cost = _cost(lin)
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        system.factorize(lin)
        dxf, dxp = system.solve()
        step = 1.0
        for _ in range(30):
            p_new, x_new = params + step * dxf, pts + step * dxp
            lin_new = problem.linearize(p_new, x_new)
            cost_new = _cost(lin_new)
            if cost_new <= cost * (1 + 1e-12) or step < 1e-3:
                break
            step *= 0.5
        params, pts, lin = p_new, x_new, lin_new
        rel = abs(cost - cost_new) / max(cost_new, 1e-300)
        cost = cost_new
        if not np.isfinite(cost):
            raise GeometryError("the model adjustment diverged (non-finite residuals)")
        dpos = np.max(np.abs(step * dxp), initial=0.0)
        if mode == "3d":
            dpos = max(dpos, np.max(np.abs(step * dxf[:, :3]), initial=0.0))
            dang = np.max(np.abs(step * dxf[:, 3:6]), initial=0.0)
            dmu = np.max(np.abs(step * dxf[:, 6] / params[:, 6]), initial=0.0)
        elif mode == "2d":
            dpos = max(dpos, np.max(np.abs(step * dxf[:, :2]), initial=0.0))
            dang = np.max(np.abs(step * dxf[:, 2]), initial=0.0)
            dmu = np.max(np.abs(step * dxf[:, 3] / params[:, 3]), initial=0.0)
        else:
            dang, dmu = 0.0, np.max(np.abs(step * dxf), initial=0.0) * 1e-3
        say(f"{mode} iteration {it}: vTPv = {cost:.6g}, max correction {dpos:.3g} m"
            + ("" if step == 1 else f" (step {step:g})"))
        small = dpos < 1e-9 * size and dang < 1e-11 and dmu < 1e-11
        if small or (rel < tolerance and dpos < 1e-7 * size and dang < 1e-9 and dmu < 1e-9):
            converged = True
            break
    system.factorize(lin)  # at the solution, for the quality analysis
    if not converged:
        notes.append(f"not converged after {max_iterations} iterations")
    return ModelResult(problem, params, pts, lin, it, converged, notes,
                       time.perf_counter() - t0)
