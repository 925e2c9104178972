"""Sparse normal equations with points eliminated by the Schur complement.

Unknowns: `n_frames` frames of `b` unknowns (photos: 6; independent models: 7 or 4),
`n_points` points of `d` unknowns (3 or 2), and optionally `ng` global unknowns that many
observations share (the border: camera parameters of a self-calibration, points tied by
distance observations, offsets).  Observations come in these sets:

* frame-point observations, `k` rows each, tied to one frame and one point (image points,
  model coordinates), and through `jg` to a few global unknowns (`SchurSystem.gcol`);
* point observations, `kp` rows each, tied to one point (ground control);
* extra observations, `kx` rows each, tied to at most one frame and to the global unknowns
  (observations of border points, distances);
* direct observations of frame, point or global unknowns with diagonal weights (datum
  constraints, held coordinates: not part of the observation vector).

Weights are diagonal (1 / sigma^2, zero for a row that is not observed).  The reduced
frame system S is factored by the block Cholesky of baarda.linalg; its selected inverse
gives every covariance block that the residual cofactors need.  Global unknowns are
eliminated last by a dense Schur complement of their own (C, ng x ng): with
N0 the normal matrix of frames and points and Y = N0^-1 N0g,

    C = Ngg - N0g^T Y,    N^-1 = [[N0^-1 + Y C^-1 Y^T, -Y C^-1], [-C^-1 Y^T, C^-1]],

so every cofactor is the one with the globals held plus a rank-ng term a C^-1 a^T with
a = A0 Y - Ag per observation row.  No matrix whose size grows with the block is ever
dense (Y is n_unknowns x ng, ng small).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np

from baarda.adjustment import schur_kernels as kernels
from baarda.linalg import BlockPattern
from baarda.linalg.parallel import PARALLEL_MIN_WORK

if TYPE_CHECKING:
    from baarda.adjustment.schur import SchurFactor

HOLD = 1e24  # weight of a direct constraint that holds an unknown (datum, fixed control)
PARALLEL_ASSEMBLY_WORK = 10_000_000  # observations x (b^2 + b d + d^2): the parallel assembly


@dataclass(frozen=True)
class Linearization:
    """Jacobians, weights and misclosures e = l - f(x0) at the current estimate."""

    jf: np.ndarray  # (m, k, b)
    jp: np.ndarray  # (m, k, d)
    w: np.ndarray  # (m, k)
    e: np.ndarray  # (m, k)
    jc: np.ndarray  # (mp, kp, d) point observations
    wc: np.ndarray  # (mp, kp)
    ec: np.ndarray  # (mp, kp)
    wf: np.ndarray | None = None  # (nf, b) weights of direct observations of frame unknowns
    ef: np.ndarray | None = None  # (nf, b) their misclosures (observed - current)
    jg: np.ndarray | None = None  # (m, k, kg) frame-point rows wrt their globals (system.gcol)
    jxf: np.ndarray | None = None  # (mx, kx, b) extra rows wrt their frame (system.x_frame)
    jxg: np.ndarray | None = None  # (mx, kx, ng) extra rows wrt the global unknowns
    wx: np.ndarray | None = None  # (mx, kx)
    ex: np.ndarray | None = None  # (mx, kx)
    wp: np.ndarray | None = None  # (np, d) direct observations of point unknowns (held)
    ep: np.ndarray | None = None  # (np, d)
    wg: np.ndarray | None = None  # (ng,) direct observations of global unknowns (held)
    eg: np.ndarray | None = None  # (ng,)

    @property
    def cost(self) -> float:
        """v'Pv: the weighted sum of squares of the misclosures."""
        c = float(np.sum(self.w * self.e**2) + np.sum(self.wc * self.ec**2))
        for w, e in ((self.wf, self.ef), (self.wx, self.ex), (self.wp, self.ep),
                     (self.wg, self.eg)):
            if w is not None and e is not None:
                c += float(np.sum(w * e**2))
        return c


class SchurSystem:
    """The structure of the reduced normal equations: fixed for a problem, never changed.

    `factorize(lin)` returns the numbers of one linearisation as a new SchurFactor.
    n_fixed: unknowns held by direct constraints (zero Jacobian columns plus a direct
    observation of large weight): they are not unknowns of the model
    (bundle/free_network.py, fixed control).  ng: global unknowns; gcol (m, kg): the global
    column of each of the kg `jg` columns of a frame-point observation (-1: none); x_frame
    (mx,): the frame of each extra observation (-1: none).  column_names(k): the names of
    frame k's b unknowns (messages about undetermined unknowns name them).
    """

    def __init__(self, n_frames: int, b: int, n_points: int, d: int,
                 frame: np.ndarray, point: np.ndarray, control_point: np.ndarray,
                 frame_names: list[str] | None = None, point_names: list[str] | None = None,
                 n_fixed: int = 0, ng: int = 0, gcol: np.ndarray | None = None,
                 x_frame: np.ndarray | None = None, global_names: list[str] | None = None,
                 column_names: Callable[[int], list[str]] | None = None):
        self.nf, self.b, self.np, self.d = n_frames, b, n_points, d
        self.column_names = column_names  # the names of a frame's b unknowns, when known
        self.frame_names = frame_names or [str(i) for i in range(n_frames)]
        self.point_names = point_names or [str(i) for i in range(n_points)]
        frame = np.asarray(frame, np.int64)
        point = np.asarray(point, np.int64)
        self.order = np.argsort(point, kind="stable")  # observation order inside kernels
        self.frame_sorted = frame[self.order]
        self.point_sorted = point[self.order]
        self.frame, self.point = frame, point
        self.ptr = np.zeros(n_points + 1, np.int64)
        np.cumsum(np.bincount(point, minlength=n_points), out=self.ptr[1:])
        self.control_point = np.asarray(control_point, np.int64)
        npairs = kernels.count_pairs(self.ptr, self.frame_sorted)
        self.pair_a, self.pair_c, self.pair_point = kernels.pair_observations(
            self.ptr, self.frame_sorted, npairs)
        rows, cols = self.frame_sorted[self.pair_a], self.frame_sorted[self.pair_c]
        self.pattern = BlockPattern.from_pairs(n_frames, b, rows, cols)
        self.pair_slot, self.pair_tr = self.pattern.slots(rows, cols)
        diag = np.arange(n_frames)
        self.diag_slot, _ = self.pattern.slots(diag, diag)
        # the parallel point elimination: pairs by storage slot and observations by frame,
        # each in the serial loop's order (schur_kernels.reduce_points_parallel)
        self.slot_pairs = np.argsort(self.pair_slot, kind="stable")
        self.slot_ptr = np.zeros(self.pattern.nnz_blocks + 1, np.int64)
        np.cumsum(np.bincount(self.pair_slot, minlength=self.pattern.nnz_blocks),
                  out=self.slot_ptr[1:])
        self.slot_diag = np.full(self.pattern.nnz_blocks, -1, np.int64)
        self.slot_diag[self.diag_slot] = diag
        self.frame_obs = np.argsort(self.frame_sorted, kind="stable")
        self.frame_ptr = np.zeros(n_frames + 1, np.int64)
        np.cumsum(np.bincount(self.frame_sorted, minlength=n_frames), out=self.frame_ptr[1:])
        self.n_fixed = int(n_fixed)
        self.ng = int(ng)
        self.gcol = (np.zeros((len(frame), 0), np.int64) if gcol is None
                     else np.asarray(gcol, np.int64).reshape(len(frame), -1))
        self.x_frame = (np.zeros(0, np.int64) if x_frame is None
                        else np.asarray(x_frame, np.int64))
        self.global_names = global_names or [f"global {i}" for i in range(self.ng)]

    def parallel_reduction(self) -> bool:
        """Whether the point elimination runs on numba's threads: with more than one thread
        and enough work (as the factorisation, linalg/parallel.PARALLEL_MIN_WORK); small
        blocks stay on one thread and never start numba's thread pool (a process that has
        started it cannot fork safely, as `baarda evaluate`'s process pool does)."""
        work = len(self.pair_slot) * self.b * self.b * self.d
        return work >= PARALLEL_MIN_WORK and numba.get_num_threads() > 1

    def parallel_assembly(self) -> bool:
        """Whether the normal equations are assembled on numba's threads: with the parallel
        point elimination and enough work to pay for a parallel region (about 10 ms on one
        thread; where other processes share the cores, each region waits for the
        scheduler, and on a small block the serial loop is faster)."""
        work = len(self.order) * (self.b * self.b + self.b * self.d + self.d * self.d)
        return work >= PARALLEL_ASSEMBLY_WORK and self.parallel_reduction()

    @property
    def n_unknowns(self) -> int:
        return self.nf * self.b + self.np * self.d + self.ng - self.n_fixed

    @property
    def mx(self) -> int:
        return len(self.x_frame)

    def factorize(self, lin: Linearization, damping: float = 0.0) -> SchurFactor:
        """Assemble the normal equations of `lin`, reduce them and factor S.

        damping: Levenberg-Marquardt lambda; the diagonal of N is multiplied by 1 + lambda.
        """
        from baarda.adjustment.schur import SchurFactor

        return SchurFactor(self, lin, damping)
