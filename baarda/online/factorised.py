"""The on-line bundle's factorisation (online/bundle.py): the block factored again at its
Gauss-Newton solution, warm-started from the current estimates (`Factorisation._refactor`),
with what the low-rank update and the tests need of it (`Factored`); the current estimates
from the last factorisation and the rows since (`_current`); whether those rows moved the
estimates beyond the linear limit (`_nonlinear`)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from baarda.block.photo_block import Block
from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.bundle_result import BundleResult
from baarda.errors import GeometryError
from baarda.kinds import CONTROL, GNSS, IMAGE, IMU
from baarda.online.answers import Change
from baarda.online.approximations import resected_again
from baarda.online.lowrank import LowRank
from baarda.online.measurements import Measurements
from baarda.options import SolveOptions, TestOptions
from baarda.quality.distributions import BMethod
from baarda.quality.statistics import residual_cofactors, w_tests

RESTART = 3.0  # a refactorisation's sigma0 this many times the last one's: start cold too
SAME = 1e-6  # the cold start's sigma0 not this much smaller (relative): the same minimum
Key = tuple[str, int, int]  # (kind, universe index, component number)


def undetermined_photo(e: GeometryError) -> int | None:
    """The universe photo whose orientation (or own camera parameters) a refactorisation
    found not determined (`Factorisation._refactor` names it in the error's frame), else
    None: the photo to leave out before the block is factored again."""
    return e.frame


@dataclass
class Factored:
    """The block at its last factorisation: the problem, its solution and what the
    low-rank update needs of it."""

    problem: BundleProblem
    result: BundleResult
    model: BundleModel
    keys: list
    flat_of: dict
    q0: np.ndarray  # adjusted cofactors of every component (flat)
    v0: np.ndarray  # residuals
    sigma: np.ndarray
    frame_of: np.ndarray  # universe photo -> frame (-1)
    elim_of: np.ndarray  # universe point -> eliminated point (-1)
    by_photo: dict  # universe photo -> flat components on it
    by_point: dict
    lowrank: LowRank


class Factorisation:
    """The factorisation of an OnlineBundle (a base of it: its state declared here)."""

    # the state of an OnlineBundle (online/bundle.py sets it)
    m: Measurements
    tests: TestOptions
    free: bool
    max_rows: int
    linear_limit: float
    solve_options: SolveOptions
    _bm: BMethod
    _datum: tuple[int, int, int] | None
    _f: Factored | None
    _ycol: dict
    _y0: np.ndarray
    _pending: list[Key]
    _verdict: dict[Key, str]
    _keys_told: dict[tuple, Key]

    # ------------------------------------------------------------ factorisation
    def _current(self) -> tuple[np.ndarray, np.ndarray]:
        """Current estimates of every photo and point (approximations where not in the
        block; NaN where none).  New unknowns whose rows are not in the low-rank update yet
        (a large group on its way into a new factorisation) stand at their approximations."""
        eo, xyz, tie = self.m.arrays()
        eo = eo.copy()
        xyz = np.where(tie[:, None], np.nan, xyz)
        f = self._f
        if f is None:
            return eo, xyz
        res = f.result
        sol = f.lowrank.solution() if f.lowrank.r else None
        fr = np.flatnonzero(f.frame_of >= 0)
        e = res.state[0][f.frame_of[fr]]
        if sol is not None:
            e = e + sol.dxf[f.frame_of[fr]]
        eo[fr] = e
        pt = np.flatnonzero(f.elim_of >= 0)
        x = res.state[1][f.elim_of[pt]]
        if sol is not None:
            x = x + sol.dxp[f.elim_of[pt]]
        xyz[pt] = x
        y = self._y0.copy()
        if sol is not None:
            y[:len(sol.dy)] += sol.dy
        for (what, u), c in self._ycol.items():
            (eo if what == "photo" else xyz)[u] = y[c:c + (6 if what == "photo" else 3)]
        return eo, xyz

    def _globals(self) -> np.ndarray:
        f = self._f
        assert f is not None
        g = f.result.state[2] if len(f.result.state) == 3 else np.zeros(0)
        if f.lowrank.r and len(g):
            g = g + f.lowrank.solution().dxg
        return g

    def _refactor(self, first: bool = False) -> list[Change]:
        """Factor the block again at its Gauss-Newton solution (warm-started from the
        current estimates); returns the verdicts that changed since they were last told."""
        m = self.m
        eo, xyz = self._current()
        old_g = None if self._f is None else (self._f.problem.system.global_names,
                                              self._globals())
        block, maps = m.state_block(np.where(np.isfinite(eo), eo, 0.0), xyz)
        problem = self._problem(block, maps).with_solve_options(self.solve_options)
        start = (eo[maps.photos], xyz[maps.points[problem.elim_ids]])
        if problem.system.ng:
            g = np.concatenate([problem.calibration.start(), np.zeros(problem.gnss_imu.n)])
            if old_g is not None:
                at = {n: v for n, v in zip(old_g[0], old_g[1], strict=True)}
                g = np.array([at.get(n, v) for n, v in
                              zip(problem.system.global_names, g, strict=True)])
            start += (g,)
        try:
            result = problem.fit(start=None if first else start)
        except GeometryError as e:  # the frame named: its photo in the universe
            if e.frame is None:
                raise
            raise GeometryError(str(e), frame=int(maps.photos[e.frame])) from None
        if not first and self._f is not None:
            result = self._better_cold(problem, result, self._f.result.sigma0, eo)
        model = BundleModel(result)
        keys = _flat_keys(problem, maps)
        nf = len(m.photo_ids)
        frame_of = np.full(nf, -1)
        frame_of[maps.photos] = np.arange(len(maps.photos))
        elim_of = np.full(len(m.point_ids), -1)
        elim_of[maps.points[problem.elim_ids]] = np.arange(len(problem.elim_ids))
        by_photo: dict[int, list[int]] = {}
        by_point: dict[int, list[int]] = {}
        for n, (kind, u, _c) in enumerate(keys):
            if kind == IMAGE.name:
                by_photo.setdefault(m.im_photo[u], []).append(n)
                by_point.setdefault(m.im_point[u], []).append(n)
            elif kind == CONTROL.name:
                by_point.setdefault(u, []).append(n)
            else:
                by_photo.setdefault((m.g_photo if kind == GNSS.name else m.i_photo)[u],
                                    []).append(n)
        q0 = np.maximum(model.adjusted_cofactor_diag(), 0.0)
        self._f = Factored(
            problem=problem, result=result, model=model, keys=keys,
            flat_of={k: n for n, k in enumerate(keys)}, q0=q0, v0=model.residuals,
            sigma=model.sigma, frame_of=frame_of, elim_of=elim_of,
            by_photo={k: np.array(v) for k, v in by_photo.items()},
            by_point={k: np.array(v) for k, v in by_point.items()},
            lowrank=LowRank(result.factor))
        self._ycol, self._y0, self._pending = {}, np.zeros(0), []
        if first and not result.converged:
            raise GeometryError("the adjustment of the block did not converge: "
                                + "; ".join(result.notes[-1:]))
        if first:
            return []
        w, r, *_, mdb = self._stats(self._f)
        return self._changes(keys, w, r, mdb)

    def _better_cold(self, problem: BundleProblem, warm: BundleResult, before: float,
                     now: np.ndarray) -> BundleResult:
        """The warm-started solution, or, where its sigma0 exceeds RESTART times the last
        factorisation's (a local minimum: new photos and points refined to a block held in
        a weak, nearly critical configuration), a solution from approximations when its
        sigma0 is smaller (by more than SAME: another minimum): from the photos' given or
        resected orientations (what the batch adjustment starts from), else, where that
        does not converge to a better minimum, with the photos resected on-line resected
        again from the points the other photos intersect (`resected_again`: their first
        resection used points in the wrong minimum).  `now`: the current orientations
        (`_current`, as the warm start had them), for photos without given ones."""
        if not warm.sigma0 > RESTART * max(before, 1.0):
            return warm
        m = self.m
        eo, xyz, tie = m.arrays()
        eo = np.where(np.isfinite(eo).all(axis=1)[:, None], eo, now)
        block, maps = m.state_block(np.where(np.isfinite(eo), eo, 0.0),
                                    np.where(tie[:, None], np.nan, xyz))
        again = np.isin(maps.photos, sorted(m.resected))
        for anew in (False, True):
            if anew and not again.any():
                break
            try:
                if anew:
                    block = replace(block, photos=replace(
                        block.photos, eo=resected_again(block, again)))
                cold = problem.fit(start=self._problem(block, maps).approximations)
            except GeometryError:
                continue
            if cold.converged and cold.sigma0 < (1.0 - SAME) * warm.sigma0:
                return cold
        return warm

    def _problem(self, block: Block, maps) -> BundleProblem:
        """The bundle problem of the state block: with its control, or a free network held by
        the minimal constraints of the first adjustment (universe photos, `_datum`), chosen
        again (choose_datum) when one of its photos has left the block."""
        if not self.free:
            return BundleProblem(block)
        from baarda.bundle.free_network import FreeBundleProblem, choose_datum

        at = {int(u): n for n, u in enumerate(maps.photos)}
        d = self._datum
        if d is None or d[0] not in at or d[1] not in at:
            a, b, k = choose_datum(block)
            d = self._datum = (int(maps.photos[a]), int(maps.photos[b]), k)
        return FreeBundleProblem(block, datum=(at[d[0]], at[d[1]], d[2]),
                                 inner=self.m.settings.datum == "inner")

    def _nonlinear(self) -> bool:
        """Whether the rows since the factorisation moved the estimates so far from where
        they were linearised that the one-step solution is no longer exact enough: a
        position by more than LINEAR_LIMIT of the flying height or an angle by more than
        LINEAR_LIMIT rad (the error of the linearisation, c * LINEAR_LIMIT^2, then stays
        below 0.015 µm for c = 153 mm)."""
        f = self._f
        assert f is not None
        sol = f.lowrank.solution()
        h = f.problem.scale
        size = max(np.max(np.abs(sol.dxf[:, :3]), initial=0.0) / h,
                   np.max(np.abs(sol.dxf[:, 3:]), initial=0.0),
                   np.max(np.abs(sol.dxp), initial=0.0) / h)
        for (what, _u), c in self._ycol.items():
            d = sol.dy[c:c + (6 if what == "photo" else 3)]
            size = max(size, np.max(np.abs(d[:3])) / h,
                       np.max(np.abs(d[3:]), initial=0.0) if what == "photo" else 0.0)
        return size > self.linear_limit

    def _stats(self, f: Factored):
        """w, r, v, sigma_v, mdb of every component at the factorisation (the quality
        layer's w_tests)."""
        qvv, r = residual_cofactors(f.q0, f.sigma)
        sv, w, mdb, _ = w_tests(f.v0, f.sigma, qvv, r, self._bm.delta0)
        return w, r, f.v0, sv, mdb

    def _changes(self, keys, w, r, mdb) -> list[Change]:
        """The verdicts of `keys` that changed since they were last told (AdditionTests)."""
        raise NotImplementedError


def _flat_keys(problem: BundleProblem, maps) -> list:
    """The universe key of every component of a problem's flat observation vector."""
    keys = []
    for r in problem.obs:
        u = int(maps.image[r])
        keys += [(IMAGE.name, u, 0), (IMAGE.name, u, 1)]
    sel = problem.layout.ctrl_sel
    ci, cc = np.divmod(sel, 3)
    for i, c in zip(ci, cc, strict=True):
        keys.append((CONTROL.name, int(maps.points[problem.control[i]]), int(c)))
    gi = problem.gnss_imu
    for r in range(gi.n_gnss):
        keys += [(GNSS.name, int(maps.gnss[r]), c) for c in range(3)]
    for r in range(gi.n_imu):
        keys += [(IMU.name, int(maps.imu[r]), c) for c in range(3)]
    return keys

