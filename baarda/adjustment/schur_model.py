"""A model adjusted on a SchurSystem, seen by the quality layer as a flat observation vector.

The flat vector is: the k rows of every frame-point observation (image points, model
coordinates), then the observed rows of the point observations (control), selected by
`ctrl_sel` from their (n_control * kc) rows (`FlatLayout`).  The bundle and the
independent-model adjustment describe their observations (labels, sigmas, residuals) in
their subclasses; the linear algebra they hand to baarda.quality is here, once, on the
SchurFactor of the solution.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from baarda.adjustment import pair_cofactors
from baarda.adjustment.schur import SchurFactor
from baarda.quality.adjusted_model import AdjustedModel


@dataclass(frozen=True)
class FlatLayout:
    """Where the components of the flat observation vector sit in the Schur arrays: the k
    rows of each frame-point observation, the observed point-observation rows, then the kx
    rows of each extra observation (SchurSystem: observations of border unknowns)."""

    m: int  # frame-point observations
    k: int  # rows of each
    n_control: int  # point observations
    kc: int  # rows of each
    ctrl_sel: np.ndarray  # observed rows among the (n_control * kc) point-observation rows
    mx: int = 0  # extra observations
    kx: int = 0  # rows of each

    @property
    def n(self) -> int:
        return self.m * self.k + len(self.ctrl_sel) + self.mx * self.kx

    def split(self, h: np.ndarray, fill: float = 0.0) -> tuple[np.ndarray, ...]:
        """Flat (n,) or (n, q) -> frame-point rows (m, k[, q]) and point rows (nc, kc[, q])
        (and extra rows (mx, kx[, q]) when there are any)."""
        h = np.asarray(h)
        tail = h.shape[1:]
        nm, ncs = self.m * self.k, len(self.ctrl_sel)
        hm = h[:nm].reshape(self.m, self.k, *tail)
        hc = np.full((self.n_control * self.kc, *tail), fill, dtype=h.dtype)
        hc[self.ctrl_sel] = h[nm:nm + ncs]
        hc = hc.reshape(self.n_control, self.kc, *tail)
        if not self.mx:
            return hm, hc
        return hm, hc, h[nm + ncs:].reshape(self.mx, self.kx, *tail)

    def flat(self, rm: np.ndarray, rc: np.ndarray, rx: np.ndarray | None = None) -> np.ndarray:
        """Inverse of split for (m, k[, q]), (nc, kc[, q]) and (mx, kx[, q]) arrays."""
        tail = rm.shape[2:]
        parts = [rm.reshape(self.m * self.k, *tail), rc.reshape(-1, *tail)[self.ctrl_sel]]
        if self.mx:
            assert rx is not None
            parts.append(rx.reshape(self.mx * self.kx, *tail))
        return np.concatenate(parts)


class SchurModel(AdjustedModel):
    """Base of BundleModel and IndependentModel: the AdjustedModel services of a SchurFactor."""

    factor: SchurFactor
    layout: FlatLayout
    result: Any  # the adjustment result (BundleResult, ModelResult): converged, notes

    @property
    def converged(self) -> bool:
        return bool(self.result.converged)

    @property
    def convergence_note(self) -> str:
        """The solver's message (the first note of a result that did not converge after the
        problem's own notes)."""
        if self.result.converged:
            return ""
        own = len(getattr(self.result.problem, "notes", ()))
        notes = list(getattr(self.result, "notes", ()))[own:]
        return notes[0].removesuffix("; the estimate before it is reported") if notes else \
            "not converged"

    def parameter_effect(self, h: np.ndarray) -> tuple[np.ndarray, ...]:
        """N^-1 A^T P H: changes of the frame (nf, b, q) and point (np, d, q) unknowns (and
        the global ones (ng, q) when the adjustment has any)."""
        return self.factor.solve_normal(*self.factor.apply_AtP(*self.layout.split(h)))

    def _adjusted_cofactors(self) -> tuple[np.ndarray, ...]:
        """Blocks of A N^-1 A^T, computed once (statistics and grouped tests both need them)."""
        if getattr(self, "_qll", None) is None:
            self._qll = self.factor.adjusted_cofactors()
        return self._qll

    # ------------------------------------------------------------- interface
    def adjusted_cofactor_diag(self) -> np.ndarray:
        return self.layout.flat(*(np.diagonal(q, axis1=1, axis2=2)
                                  for q in self._adjusted_cofactors()))

    def adjusted_cofactor_blocks(self) -> tuple[np.ndarray, np.ndarray]:
        q = self._adjusted_cofactors()[0]
        lay = self.layout
        return np.arange(lay.m * lay.k).reshape(lay.m, lay.k), q

    def normal_forward(self, h: np.ndarray) -> np.ndarray:
        return self.factor.forward(*self.factor.apply_AtP(*self.layout.split(h)))

    def solve_columns(self, h: np.ndarray) -> np.ndarray:
        return self.layout.flat(*self.factor.apply_A(*self.parameter_effect(h)))

    def point_effect_rows(self) -> np.ndarray:
        """Effect of a unit error of each component on its point's unknowns, (n, d)."""
        return self.layout.flat(*self.factor.point_effect())

    # ------------------------------------------------- cofactors of pairs (separability)
    def local_cofactor_diag(self) -> np.ndarray:
        return pair_cofactors.local_diag(self.factor, self.layout)

    def adjusted_cofactor_columns(self, rows: np.ndarray) -> np.ndarray:
        return pair_cofactors.columns(self.factor, self.layout, rows)

    def point_pair_cofactors(self) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Pairs of one eliminated point from the factor (pair_cofactors.point_pairs); the
        extra rows that share a point label (border points, distances) by their columns."""
        yield from pair_cofactors.point_pairs(self.factor, self.layout)
        lay = self.layout
        first = lay.m * lay.k + len(lay.ctrl_sel)
        if lay.mx:
            labels = np.asarray(self.point, dtype=object)
            extra = labels[first:]
            named = np.unique(extra[extra != ""])
            rows = np.flatnonzero(np.isin(labels, named))
            if len(rows):
                cols = self.adjusted_cofactor_columns(rows)[rows]
                same = labels[rows][:, None] == labels[rows][None, :]
                a, c = np.nonzero(np.triu(same, 1))
                yield rows[a], rows[c], cols[a, c]

    def frame_pair_cofactors(self, rows: np.ndarray
                             ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        lay, s = self.layout, self.factor.system
        rows = np.asarray(rows, np.int64)
        nm, first = lay.m * lay.k, lay.m * lay.k + len(lay.ctrl_sel)
        frames = [s.frame[rows[rows < nm] // lay.k]]
        if lay.mx:
            x = s.x_frame[(rows[rows >= first] - first) // lay.kx]
            frames.append(x[x >= 0])
        yield from pair_cofactors.frame_pairs(self.factor, self.layout, np.concatenate(frames))
