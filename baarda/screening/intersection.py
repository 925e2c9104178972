"""Small collinearity adjustments of the strip formation: some photos free, points intersected.

A step of the progressive strip formation frees the new photo; the strip adjustment at the end
frees every photo but the first (and one base component of the second: the scale).  Other
photos keep their strip-frame orientation.  Observations: x and y of the given image rows (one
group per row) and, for points already in the strip, their strip coordinates (positional
constraint, one group per point).  A point whose active rays no longer determine it is left
out of the unknowns and its components are undetermined (uncontrolled for the tests).
"""

from __future__ import annotations

import numpy as np

from baarda.block.photo_block import Block
from baarda.block.rotation import rotation_matrix
from baarda.bundle.collinearity import project_with_jacobians
from baarda.screening.fit import Observations, SmallModel, least_squares, small_model

XY = np.array(["x", "y"], dtype=object)
XYZ = np.array(["X", "Y", "Z"], dtype=object)


def intersect_rays(eo: np.ndarray, xy: np.ndarray, focal: np.ndarray, pp: np.ndarray,
                   point: np.ndarray, n_points: int) -> np.ndarray:
    """Least-squares intersection of rays (one per row) grouped by `point`, (n_points, 3)."""
    r = rotation_matrix(eo[:, 3], eo[:, 4], eo[:, 5])
    d = np.einsum("mij,mj->mi", r, np.column_stack([xy - pp, -focal]))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    proj = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    a = np.zeros((n_points, 3, 3))
    b = np.zeros((n_points, 3))
    np.add.at(a, point, proj)
    np.add.at(b, point, np.einsum("mij,mj->mi", proj, eo[:, :3]))
    out = np.full((n_points, 3), np.nan)
    ok = np.linalg.cond(a) < 1e12
    out[ok] = np.linalg.solve(a[ok], b[ok][:, :, None])[:, :, 0]
    return out


class Intersection:
    """Orientation of the photos `free` and intersection of the points of `rows`.

    eo: (n_photos, 6) strip-frame orientations (start values of the free photos);
    rows: block image rows used; constraints: {point: (xyz (3,), var (3,))};
    fixed: {photo: [unknown index 0..5, ...]} held at their start values (the datum).
    """

    def __init__(self, block: Block, eo: np.ndarray, rows: np.ndarray, free: list[int],
                 constraints: dict[int, tuple[np.ndarray, np.ndarray]] | None = None,
                 fixed: dict[int, list[int]] | None = None, what: str = "strip formation"):
        self.block, self.what = block, what
        self.eo = eo.copy()
        self.rows = np.asarray(rows, int)
        constraints = constraints or {}
        fixed = fixed or {}
        im = block.image
        self.photo = im.photo[self.rows]
        self.cpoints = np.array(sorted(constraints), dtype=int)
        self.points = np.unique(np.concatenate([im.point[self.rows], self.cpoints]))
        self.pindex = {int(p): i for i, p in enumerate(self.points)}
        self.row_point = np.array([self.pindex[int(p)] for p in im.point[self.rows]], dtype=int)
        con_point = np.array([self.pindex[int(p)] for p in self.cpoints], dtype=int)
        # unknown columns of the free photos' orientation elements
        self.eo_col = np.full((len(block.photos), 6), -1)
        ne = 0
        for f in free:
            for c in range(6):
                if c not in fixed.get(f, []):
                    self.eo_col[f, c] = ne
                    ne += 1
        self.ne = ne
        self.free = list(free)
        m, nc = len(self.rows), len(self.cpoints)
        ids = np.asarray(block.points.ids, dtype=object)
        photos = np.asarray(block.photos.ids, dtype=object)
        con = np.array([constraints[int(p)][0] for p in self.cpoints]).reshape(nc, 3)
        var = np.array([constraints[int(p)][1] for p in self.cpoints]).reshape(nc, 3)
        self.obs = Observations(
            np.concatenate([im.xy_mm[self.rows].ravel(), con.ravel()]),
            np.concatenate([im.sigma_xy[self.rows].ravel(), np.sqrt(var).ravel()]),
            np.array(["image"] * (2 * m) + ["constraint"] * (3 * nc), dtype=object),
            np.concatenate([np.tile(XY, m), np.tile(XYZ, nc)]),
            np.concatenate([np.repeat(photos[self.photo], 2),
                            np.full(3 * nc, "strip", dtype=object)]),
            np.concatenate([np.repeat(ids[im.point[self.rows]], 2),
                            np.repeat(ids[self.cpoints], 3)]),
            np.concatenate([np.repeat(np.arange(m), 2), np.repeat(m + np.arange(nc), 3)]))
        self.m = m
        self.comp_point = np.concatenate([np.repeat(self.row_point, 2), np.repeat(con_point, 3)])
        self.con_point = con_point
        self.xyz = np.full((len(self.points), 3), np.nan)
        for p, (x, _) in constraints.items():
            self.xyz[self.pindex[int(p)]] = x

    # ---------------------------------------------------------------- geometry
    def start_points(self, active: np.ndarray, eo: np.ndarray, xyz: np.ndarray) -> np.ndarray:
        """xyz with the points that have no coordinates intersected from their active rays."""
        need = ~np.isfinite(xyz).all(axis=1)
        if not need.any():
            return xyz
        ray = active[0:2 * self.m:2] | active[1:2 * self.m:2]
        im = self.block.image
        cam = self.block.photos.camera[self.photo]
        x = intersect_rays(eo[self.photo][ray], im.xy_mm[self.rows][ray],
                           self.block.cameras.focal_mm[cam][ray],
                           self.block.cameras.principal_point_mm[cam][ray],
                           self.row_point[ray], len(self.points))
        out = xyz.copy()
        out[need] = x[need]
        return out

    def _linearize(self, eo: np.ndarray, xyz: np.ndarray):
        """Computed values (n,), d/d(free orientation) (n, ne), d/d(point) (n, 3)."""
        cam = self.block.photos.camera[self.photo]
        xy, je, jp = project_with_jacobians(eo[self.photo], np.nan_to_num(xyz[self.row_point]),
                                            self.block.cameras.focal_mm[cam],
                                            self.block.cameras.principal_point_mm[cam])
        nc = len(self.cpoints)
        f = np.concatenate([xy.ravel(), np.nan_to_num(xyz[self.con_point]).ravel()])
        jeo = np.zeros((2 * self.m + 3 * nc, self.ne))
        cols = self.eo_col[self.photo]  # (m, 6)
        r, c = np.nonzero(cols >= 0)
        for k in range(2):
            jeo[2 * r + k, cols[r, c]] = je[r, k, c]
        jpt = np.concatenate([jp.reshape(2 * self.m, 3), np.tile(np.eye(3), (nc, 1))])
        return f, jeo, jpt

    def determined(self, active: np.ndarray, eo: np.ndarray, xyz: np.ndarray) -> np.ndarray:
        """(npoints,) bool: the active components fix the point (3 independent rows)."""
        _, _, jp = self._linearize(eo, xyz)
        out = np.zeros(len(self.points), bool)
        rows = np.flatnonzero(active)
        for i in range(len(self.points)):
            sel = rows[self.comp_point[rows] == i]
            if len(sel) < 3 or not np.all(np.isfinite(xyz[i])):
                continue
            j = jp[sel]
            s = np.linalg.svd(j / np.linalg.norm(j, axis=1, keepdims=True), compute_uv=False)
            out[i] = s[-1] > 1e-6 * s[0]
        return out

    # ---------------------------------------------------------------- adjustment
    def fit(self, active: np.ndarray, factors: np.ndarray | None = None,
            start: tuple[np.ndarray, np.ndarray] | None = None) -> SmallModel:
        """Adjust with the `active` components from `start` (orientations, point coordinates;
        default the given orientations and constraints): the quality layer's model, whose
        `x` is the solution (orientations (n_photos, 6), point coordinates)."""
        active = np.asarray(active, bool)
        eo, xyz = (self.eo, self.xyz) if start is None else start
        eo = eo.copy()
        xyz = self.start_points(active, eo, xyz)
        det = self.determined(active, eo, xyz)
        und = ~det[self.comp_point]
        pts = np.flatnonzero(det)
        col = np.full(len(self.points), -1)
        col[pts] = self.ne + 3 * np.arange(len(pts))
        comp_col = col[self.comp_point]
        r = np.flatnonzero(comp_col >= 0)
        u = self.ne + 3 * len(pts)
        fr, fc = np.nonzero(self.eo_col >= 0)

        def unpack(x):
            e = eo.copy()
            e[fr, fc] = x[self.eo_col[fr, fc]]
            p = xyz.copy()
            p[pts] = x[self.ne:].reshape(-1, 3)
            return e, p

        def func(x):
            f, jeo, jpt = self._linearize(*unpack(x))
            a = np.zeros((self.obs.n, u))
            a[:, :self.ne] = jeo
            for k in range(3):
                a[r, comp_col[r] + k] = jpt[r, k]
            return f, a

        x0 = np.zeros(u)
        x0[self.eo_col[fr, fc]] = eo[fr, fc]
        x0[self.ne:] = xyz[pts].ravel()
        sol = least_squares(func, x0, self.obs, active & ~und, factors, self.what)
        rows3 = (self.ne + 3 * np.arange(len(pts)))[:, None] + np.arange(3)[None, :]
        labels = [self.block.points.ids[int(self.points[p])] for p in pts]
        if not len(pts):
            rows3, labels = None, None
        model = small_model(sol.lin.a, self.obs, sol.lin.f, active, factors, problem=self,
                            x=unpack(sol.state), undetermined=und, point_rows=rows3,
                            point_labels=labels)
        model.func, model.unknowns = func, sol.state  # the function of the unknowns (tests)
        return model

    def components(self, point: int) -> np.ndarray:
        """Observation components that belong to block point `point`."""
        return np.flatnonzero(self.comp_point == self.pindex[int(point)])
