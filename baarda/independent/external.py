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
from scipy import sparse

from baarda.independent import similarity
from baarda.independent.independent_model import IndependentModel
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
        self.same, self.diff = self._pairs(pb, pid)
        self.dir_same = self._directions(*self.same)
        self.dir_diff = self._directions(*self.diff)
        nb = pb.system.nf * pb.b
        self.b = pb.b
        self.disp_op = self._operator(np.arange(len(self.rows)), None, nb)
        self.same_op = self._operator(self.same[1], self.dir_same, nb, self.same[0])
        self.diff_op = self._operator(self.diff[1], self.dir_diff, nb, self.diff[0])

    def _operator(self, b, u, nb, a=None):
        """Sparse map of the frame changes (nf * b) to displacements of rows `b`
        (u None: (rows * d) outputs) or to changes of the distances a-b along u."""
        jb = self.jac[b]  # (p, d, b)
        cols = self.frame[b][:, None] * self.b + np.arange(self.b)[None, :]
        if u is None:
            p, d = len(b), jb.shape[1]
            rows = np.repeat(np.arange(p * d), self.b)
            vals = jb.reshape(p * d, self.b).ravel()
            cc = np.repeat(cols, d, axis=0).ravel()
            return sparse.csr_matrix((vals, (rows, cc)), shape=(p * d, nb))
        ga = np.einsum("pd,pdb->pb", u, self.jac[a])
        gb = np.einsum("pd,pdb->pb", u, jb)
        ca = self.frame[a][:, None] * self.b + np.arange(self.b)[None, :]
        p = len(b)
        rows = np.repeat(np.arange(p), 2 * self.b)
        vals = np.concatenate([gb, -ga], axis=1).ravel()
        cc = np.concatenate([cols, ca], axis=1).ravel()
        return sparse.csr_matrix((vals, (rows, cc)), shape=(p, nb))

    def _pairs(self, pb, pid):
        """Row pairs within a model and between adjacent models (sharing a point), built
        model by model: their number grows with the block, never its square."""
        bl = pb.block
        order = np.argsort(self.frame, kind="stable")
        starts = np.searchsorted(self.frame[order], np.arange(bl.n_models + 1))
        rows_of = [order[starts[m]:starts[m + 1]] for m in range(bl.n_models)]
        # adjacency from the points shared by models (all rows of the adjustment)
        frame_all, pt_all = pb.frame, bl.obs_point[pb.rows]
        o = np.argsort(pt_all, kind="stable")
        cuts = np.flatnonzero(np.diff(pt_all[o])) + 1
        adj = set()
        for grp in np.split(frame_all[o], cuts):
            g = np.unique(grp)
            for k, a in enumerate(g):
                for b in g[k + 1:]:
                    adj.add((int(a), int(b)))
        same_a, same_b, diff_a, diff_b = [], [], [], []
        for r in rows_of:
            a, b = np.triu_indices(len(r), 1)
            same_a.append(r[a])
            same_b.append(r[b])
        for m1, m2 in sorted(adj):
            r1, r2 = rows_of[m1], rows_of[m2]
            a, b = np.repeat(r1, len(r2)), np.tile(r2, len(r1))
            keep = pid[a] != pid[b]
            diff_a.append(a[keep])
            diff_b.append(b[keep])

        def cat(x):
            return np.concatenate(x) if x else np.zeros(0, int)

        return (cat(same_a), cat(same_b)), (cat(diff_a), cat(diff_b))

    def _directions(self, a, b):
        d = self.pos[b] - self.pos[a]
        if d.shape[1] == 1:  # heights: the change of the height difference
            return np.ones_like(d)
        n = np.linalg.norm(d, axis=1, keepdims=True)
        return np.where(n > 0, d / np.where(n > 0, n, 1), 0.0)

    def effects(self, dframe: np.ndarray):
        """dframe (nf, b, q) -> displacements (rows, d, q), distance changes (pairs, q)."""
        q = dframe.shape[2]
        flat = dframe.reshape(-1, q)
        disp = (self.disp_op @ flat).reshape(len(self.rows), -1, q)
        return disp, self.same_op @ flat, self.diff_op @ flat


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
        dframe, _ = qm.unit_effect(idx)
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
