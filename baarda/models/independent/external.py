"""External reliability on detail points and distances (FOTEF Appendix II, columns 6-12).

For an observation with boundary value MDB (from quality.statistics.analyse) the error
MDB * e_i changes the unknowns by N^-1 A^T P e_i MDB; the model transformations then carry
the change to every photogrammetrically determined detail point.  Detail points are taken
at the model's own points (projection centres left out): the displacement is an affine
function of the model coordinates, so its largest value over the model area is reached at
the outermost points, which in a regular block are these.  Distances: between two detail
points of the same model, and between two points of adjacent models (models that share a
point), the points being different.  The proportions (columns 10-12) are the effects per
unit error expressed in terrain units, independent of the MDB.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from baarda.models.independent import similarity
from baarda.models.independent.quality_model import IndependentModel
from baarda.quality.statistics import QualityResult


@dataclass
class ExternalReliability:
    index: np.ndarray  # (q,) observation components evaluated (flat index of the model)
    nabla: np.ndarray  # (q,) MDB in terrain units [m]
    point: np.ndarray  # (q,) largest displacement of a detail point [m]
    dist_same: np.ndarray  # (q,) largest change of a distance within a model [m]
    dist_diff: np.ndarray  # (q,) ... between points of adjacent models [m]
    point_where: np.ndarray  # (q,) 'model/point' of the largest displacement

    @property
    def point_prop(self) -> np.ndarray:
        return self.point / self.nabla

    @property
    def same_prop(self) -> np.ndarray:
        return self.dist_same / self.nabla

    @property
    def diff_prop(self) -> np.ndarray:
        return self.dist_diff / self.nabla


class DetailGeometry:
    """Detail points of every model, their Jacobians and the distance pairs."""

    def __init__(self, qm: IndependentModel):
        pb, res = qm.problem, qm.result
        bl = pb.block
        det = ~bl.pc[bl.obs_point[pb.rows]]
        self.rows = np.flatnonzero(det)  # into problem rows
        self.frame = pb.frame[self.rows]
        x = bl.obs_xyz[pb.rows[self.rows]]
        c = pb.centroid[self.frame]
        par = res.params[self.frame]
        if pb.mode == "3d":
            self.pos, self.jac = similarity.forward3d(par, x, c)
        elif pb.mode == "2d":
            self.pos, self.jac = similarity.forward2d(par, x[:, :2], c[:, :2])
        else:
            uv = pb.uv()[self.rows]
            mu = pb.mu[self.frame]
            self.jac = -np.column_stack([np.ones(len(uv)), uv])[:, None, :] / mu[:, None, None]
            self.pos = res.pts[pb.remap[bl.obs_point[pb.rows[self.rows]]]]
        self.label = np.array([f"{bl.models[m]}/{bl.points[j]}" for m, j in
                               zip(self.frame, bl.obs_point[pb.rows[self.rows]], strict=True)],
                              dtype=object)
        pid = bl.obs_point[pb.rows[self.rows]]
        i1, i2 = np.triu_indices(len(self.rows), 1)
        same = self.frame[i1] == self.frame[i2]
        share = np.zeros((bl.n_models, bl.n_models), bool)  # small: models x models
        inc = np.zeros((bl.n_models, bl.n_points), bool)
        inc[pb.frame, bl.obs_point[pb.rows]] = True
        share = (inc.astype(np.int32) @ inc.T.astype(np.int32)) > 0
        adjacent = ~same & share[self.frame[i1], self.frame[i2]] & (pid[i1] != pid[i2])
        self.same = (i1[same], i2[same])
        self.diff = (i1[adjacent], i2[adjacent])
        self.dir_same = self._directions(*self.same)
        self.dir_diff = self._directions(*self.diff)

    def _directions(self, a, b):
        d = self.pos[b] - self.pos[a]
        if d.shape[1] == 1:  # heights: the change of the height difference
            return np.ones_like(d)
        n = np.linalg.norm(d, axis=1, keepdims=True)
        return np.where(n > 0, d / np.where(n > 0, n, 1), 0.0)

    def effects(self, dframe: np.ndarray):
        """dframe (nf, b, q) -> displacements (rows, d, q), distance changes (pairs, q)."""
        disp = np.einsum("rdb,rbq->rdq", self.jac, dframe[self.frame])

        def dist(pairs, u):
            a, b = pairs
            return np.einsum("pd,pdq->pq", u, disp[b] - disp[a])

        return disp, dist(self.same, self.dir_same), dist(self.diff, self.dir_diff)


def external_reliability(qm: IndependentModel, quality: QualityResult,
                         index: np.ndarray | None = None, chunk: int = 256
                         ) -> ExternalReliability:
    """FOTEF's external reliability for the components `index` (default: every active,
    controlled component)."""
    if index is None:
        index = np.flatnonzero(quality.active & quality.controlled)
    index = np.asarray(index, int)
    geo = DetailGeometry(qm)
    q = len(index)
    point, same, diff = np.zeros(q), np.zeros(q), np.zeros(q)
    where = np.empty(q, dtype=object)
    for s in range(0, q, chunk):
        idx = index[s:s + chunk]
        h = np.zeros((qm.n, len(idx)))
        h[idx, np.arange(len(idx))] = 1.0
        dframe, _ = qm.parameter_effect(h)
        disp, dsame, ddiff = geo.effects(dframe)
        size = np.linalg.norm(disp, axis=1)  # (rows, q)
        best = np.argmax(size, axis=0)
        point[s:s + len(idx)] = size[best, np.arange(len(idx))]
        where[s:s + len(idx)] = geo.label[best]
        same[s:s + len(idx)] = np.max(np.abs(dsame), axis=0, initial=0.0)
        diff[s:s + len(idx)] = np.max(np.abs(ddiff), axis=0, initial=0.0)
    mdb = quality.mdb[index]
    return ExternalReliability(index, mdb * qm.terrain_per_unit[index], point * mdb,
                               same * mdb, diff * mdb, where)
