"""Observation kinds as a protocol (issue 27): a new kind, a measured height difference
between two points, takes one class and its registration; its rows are adjusted and tested
like every other: r, w and MDB equal a dense computation."""

import numpy as np
import pytest

from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_problem import BundleProblem
from baarda.bundle.bundle_quality import assess
from baarda.bundle.observation_kinds import ObservationKind, Rows
from baarda.simulate.aerial import FlightPlan, simulate_block


class HeightDifferenceRows(Rows):
    units = {"height difference": (1e3, "mm")}

    def __init__(self, ctx, a, b, dh, sigma):
        self.za = ctx.point_columns(a)[:, 2]
        self.zb = ctx.point_columns(b)[:, 2]
        self.ia, self.ib = ctx.bremap[a], ctx.bremap[b]
        self.dh = dh
        self.sigma = sigma
        ids = np.asarray(ctx.block.points.ids, dtype=object)
        self._labels(np.full(len(a), "height difference", dtype=object),
                     np.full(len(a), "dZ", dtype=object), ids[a] + "-" + ids[b])

    def linearize(self, state, ng):
        n = len(self.dh)
        j = np.zeros((n, ng))
        j[np.arange(n), self.zb] = 1.0
        j[np.arange(n), self.za] = -1.0
        computed = state.bxyz[self.ib, 2] - state.bxyz[self.ia, 2]
        return self.dh - computed, np.zeros((n, 6)), j


class HeightDifferences(ObservationKind):
    """Levelled height differences Z_b - Z_a (m) between pairs of points."""

    def __init__(self, a, b, dh, sigma):
        self.a, self.b = np.asarray(a), np.asarray(b)
        self.dh, self.sigma = np.asarray(dh, float), np.asarray(sigma, float)

    def tied_points(self, block):
        return np.concatenate([self.a, self.b])

    def bind(self, context):
        return HeightDifferenceRows(context, self.a, self.b, self.dh, self.sigma)


@pytest.fixture(scope="module")
def levelled():
    block, truth = simulate_block(FlightPlan(strips=3, photos_per_strip=5, relief_m=60.0,
                                             seed=8))
    tie = np.flatnonzero(block.points.role == "tie")
    a, b = tie[[1, 4, 9]], tie[[12, 20, 3]]
    z = np.array([truth["points"][p][2] for p in block.points.ids])
    rng = np.random.default_rng(2)
    dh = z[b] - z[a] + rng.normal(0, 0.3, 3)
    dh[1] += 3.0  # a blunder of 10 sigma in the second
    kind = HeightDifferences(a, b, dh, np.full(3, 0.3))
    res = BundleProblem(block, kinds=(kind,)).fit()
    return res, assess(res)


def test_a_new_kind_is_adjusted_and_tested(levelled):
    res, qc = levelled
    assert res.converged
    pb = res.problem
    assert len(pb.border_ids) == 6 and pb.extra_rows[4] == slice(pb.layout.mx - 3, pb.layout.mx)
    rows = np.flatnonzero(qc.model.kind == "height difference")
    assert len(rows) == 3
    w = qc.quality.w[rows]
    assert abs(w[1]) > qc.quality.k_w > max(abs(w[0]), abs(w[2]))
    t = qc.table()
    ids = block_ids = res.block.points.ids
    hd = t[t["kind"] == "height difference"]
    assert list(hd["point"]) == [f"{ids[i]}-{block_ids[j]}" for i, j in zip(
        pb.kinds[4].a, pb.kinds[4].b, strict=True)]
    assert np.allclose(hd["residual"], qc.model.residuals[rows] * 1e3)  # in mm
    assert qc.to_dict()["units"]["height difference"] == "mm"


def test_its_statistics_equal_a_dense_computation(levelled):
    from dense import dense_system

    res, qc = levelled
    model = BundleModel(res)
    a, p = dense_system(model)
    qxx = np.linalg.inv(a.T @ (p[:, None] * a))
    qll = np.einsum("ij,jk,ik->i", a, qxx, a)
    r = 1 - p * qll
    q = qc.quality
    ok = q.controlled
    assert np.allclose(q.redundancy_number[ok], r[ok], atol=1e-9)
    sv = model.sigma * np.sqrt(np.maximum(r, 0))
    w = -model.residuals / np.where(ok, sv, 1.0)
    assert np.allclose(q.w[ok], w[ok], rtol=1e-8, atol=1e-9)
    assert np.allclose(q.mdb[ok], q.delta0 * model.sigma[ok] / np.sqrt(r[ok]), rtol=1e-8)
    rows = np.flatnonzero(model.kind == "height difference")
    assert ok[rows].all() and (r[rows] > 0.05).all()
    assert abs(q.redundancy_number.sum() - res.redundancy) < 1e-6
