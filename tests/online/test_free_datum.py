"""Issue 33: the on-line bundle of a free network (no control, no GNSS): the minimal
constraints it holds (the first adjustment's photos, bundle/free_network.py) give the same
redundancy numbers, w-tests and MDBs of every image component as the batch free-network
adjustment of the same observations (`baarda.pipeline.prepare`, which chooses its own minimal
datum), and the same datum-invariant geometry (distances between projection centres and
points); coordinates themselves refer to the datum and differ."""

from dataclasses import replace

import numpy as np
import pytest

from baarda.block.rotation import similarity
from baarda.bundle.bundle_model import BundleModel
from baarda.online.bundle import OnlineBundle
from baarda.options import SolveOptions
from baarda.pipeline import prepare
from baarda.quality.statistics import analyse
from baarda.simulate.aerial import FlightPlan, simulate_block

TIGHT = SolveOptions(max_iterations=50, tolerance=1e-10, min_step=1e-3, final_step=True)


@pytest.fixture(scope="module")
def free_block():
    """12 photos (2 strips x 6), 5 x 5 points per photo, 30 m relief, no control: a free
    network (datum free)."""
    block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=6, pattern=5,
                                         control="none", height_chains=0, relief_m=30.0,
                                         seed=3))
    assert not block.points.controlled.any()
    return replace(block, settings=replace(block.settings, datum="free"))


def labels(model):
    return [(str(k), str(f), str(p), str(c)) for k, f, p, c in
            zip(model.kind, model.frame, model.point, model.component, strict=True)]


def distances(xyz: np.ndarray) -> np.ndarray:
    d = xyz[:, None, :] - xyz[None, :, :]
    return np.sqrt((d ** 2).sum(axis=2))[np.triu_indices(len(xyz), 1)]


def compare(ob: OnlineBundle, rtol: float = 1e-8) -> dict:
    """The on-line state against the batch free-network adjustment of its observations."""
    qc = ob.result()
    m = ob.m
    block, maps = m.state_block(np.array(m.photo_eo), np.full((len(m.point_ids), 3), np.nan))
    problem = prepare(block, free=True).with_solve_options(TIGHT)
    res = problem.fit()
    model = BundleModel(res)
    q = analyse(model, ob.tests)
    on = dict(zip(labels(qc.model), range(qc.model.n), strict=True))
    idx = np.array([on[k] for k in labels(model)])
    assert len(idx) == qc.model.n  # the same observations
    oq = qc.quality
    r = q.redundancy_number
    assert np.abs(oq.redundancy_number[idx] - r).max() <= rtol
    # w = v / (sigma sqrt(r)) and MDB = delta0 sigma / sqrt(r): an agreement of r to rtol
    # (absolute) carries over to them as dw / w = -dr / 2r (the two solutions' residuals
    # agree to 1e-12 mm; r of a free network's weakest rays is 0.002)
    ok = np.isfinite(q.w)
    assert np.array_equal(np.isfinite(oq.w[idx]), ok)
    assert (np.abs(oq.w[idx][ok] - q.w[ok]) <= rtol * np.maximum(1.0, np.abs(q.w[ok]))
            / r[ok]).all()
    fin = np.isfinite(q.mdb)
    assert np.array_equal(np.isfinite(oq.mdb[idx]), fin)
    assert (np.abs(oq.mdb[idx][fin] / q.mdb[fin] - 1) <= rtol / r[fin]).all()
    assert qc.adjustment.redundancy == res.redundancy
    assert qc.adjustment.sigma0 == pytest.approx(res.sigma0, rel=rtol)
    # datum-invariant geometry: the shape (ratios of distances between projection centres
    # and points), and the coordinates after the 7-parameter datum transformation
    eo, xyz = ob.estimates()
    here = np.vstack([eo[maps.photos, :3], xyz[maps.points]])
    there = np.vstack([res.eo[:, :3], res.xyz])
    d0, d1 = distances(here), distances(there)
    assert np.abs(d0 / d0.max() - d1 / d1.max()).max() <= rtol
    s, r, t = similarity(here, there)
    assert np.abs(s * here @ r.T + t - there).max() <= rtol * d1.max()
    return {"datum": ob._datum, "batch_datum": problem.datum, "n": qc.model.n,
            "shift": float(np.abs(here - there).max()), "scale": s}


def test_photo_by_photo_equals_the_batch_free_network(free_block):
    """Photo by photo with refactorisation every 120 rows; then every step factored (exact)."""
    block = free_block
    empty = block.select_image(np.zeros(len(block.image), bool))
    ob = OnlineBundle(empty, solve=TIGHT)
    assert ob.free and not ob.started
    for i in range(len(block.photos)):
        rows = np.flatnonzero(block.image.photo == i)
        ob.add_photo(block.photos.ids[i],
                     {block.points.ids[block.image.point[r]]: tuple(block.image.xy_mm[r])
                      for r in rows})
        if i == 5:
            compare(ob)
    out = compare(ob)
    # the datum is the first adjustment's (photos 0 and 1), not the batch's choice:
    # coordinates differ between the two, the observations' statistics do not
    assert out["datum"][:2] == (0, 1) and out["batch_datum"] != (0, 1, out["datum"][2])
    assert out["shift"] > 1e-3 and abs(out["scale"] - 1) > 1e-4


def test_random_additions_and_removals_free_network(free_block):
    """100 random additions and removals of image points from 60 % of the block: r, w, MDB
    and the geometry equal the batch free network's every 50 steps."""
    block = free_block
    rng = np.random.default_rng(7)
    im = block.image
    given = rng.random(len(im)) < 0.6
    ob = OnlineBundle(block.select_image(given), solve=TIGHT)
    assert ob.started
    pending = list(np.flatnonzero(~given))
    photos, points = block.photos.ids, block.points.ids
    n_add = n_remove = 0
    for step in range(1, 101):
        if rng.random() < 0.7 and pending:
            r = pending.pop(int(rng.integers(len(pending))))
            ob.add_image_point(photos[im.photo[r]], points[im.point[r]], *im.xy_mm[r])
            n_add += 1
        else:
            m = ob.m
            live = [r for r in range(len(m.im_status)) if m.im_status[r] != "removed"]
            r = live[int(rng.integers(len(live)))]
            try:
                ob.remove_image_point(m.photo_ids[m.im_photo[r]], m.point_ids[m.im_point[r]])
            except Exception as e:  # a removal that would leave the block undetermined
                assert "cannot be taken out" in str(e)
            n_remove += 1
        if step % 50 == 0:
            compare(ob)
    assert n_add > 40 and n_remove > 15


def test_free_network_refuses_control(free_block):
    pts = free_block.points
    role = pts.role.copy()
    role[0] = "control"
    sigma = pts.sigma.copy()
    sigma[0] = 0.05
    bad = replace(free_block, points=replace(pts, role=role, sigma=sigma))
    with pytest.raises(ValueError, match="free network"):
        OnlineBundle(bad)


def test_inner_datum_equals_the_batch_free_network(free_block):
    """datum "inner": the on-line bundle holds the inner constraints of the first
    adjustment's photos (FreeBundleProblem(inner=True)); r, w, MDB and the geometry equal
    the batch free network's as with the minimal datum."""
    block = replace(free_block, settings=replace(free_block.settings, datum="inner"))
    empty = block.select_image(np.zeros(len(block.image), bool))
    ob = OnlineBundle(empty, solve=TIGHT)
    assert ob.free
    for i in range(len(block.photos)):
        rows = np.flatnonzero(block.image.photo == i)
        ob.add_photo(block.photos.ids[i],
                     {block.points.ids[block.image.point[r]]: tuple(block.image.xy_mm[r])
                      for r in rows})
    assert ob._f.problem.inner
    out = compare(ob)
    assert out["n"] == 2 * len(block.image)
