"""The tests of an addition to the on-line bundle (online/bundle.py): a group of held
observations taken in as a low-rank update of the last factorisation, or, when it is larger
than a factorisation takes, into a new one (`_take_in`, `_take_in_factored`); its
predictions, residuals, r, w and MDB through the quality layer's `w_tests`; the verdicts of
its neighbourhood that changed (`_neighbourhood`); the cofactors of residuals in the block
(`_qvv`); the labels of the components."""

from __future__ import annotations

import numpy as np

from baarda.errors import GeometryError
from baarda.kinds import CONTROL, GNSS, IMAGE, IMU, KINDS
from baarda.online.answers import Change, ComponentTest, verdicts
from baarda.online.approximations import intersect, refine
from baarda.online.entering import mark
from baarda.online.factorised import Factorisation, Key
from baarda.online.lowrank import Rows, quad_diag, times
from baarda.online.rows import factor_rows, group_rows, take
from baarda.quality.statistics import residual_cofactors, w_tests

CHUNK = 256  # rows solved together for a large group's predictions


class AdditionTests(Factorisation):
    """The tests of an OnlineBundle's additions (a base of it)."""

    def _exact(self, tested: list[ComponentTest]) -> list[ComponentTest]:
        """The tests of components now in the factorisation, from its solution (the
        prediction before inclusion kept)."""
        f = self._f
        assert f is not None
        w, r, v, sv, mdb = self._stats(f)
        out = []
        for t in tested:
            n = f.flat_of.get(self._key_of(t))
            if n is None:
                out.append(t)
                continue
            out.append(self._component(f.keys[n], t.predicted, t.sigma_predicted, float(w[n]),
                                       float(r[n]), float(v[n]), float(sv[n]), float(mdb[n])))
        return out

    def _sigma_of(self, key: Key) -> float:
        m = self.m
        kind, u, c = key
        if kind == IMAGE.name:
            return float(np.broadcast_to(m.im_sigma[u], (2,))[c])
        if kind == CONTROL.name:
            return float(m.point_sigma[u][c])
        return float((m.g_sigma if kind == GNSS.name else m.i_sigma)[u][c])

    def _qvv(self, keys: list[Key]) -> np.ndarray:
        """The cofactors of the residuals of components in the block (in the factorisation
        or added since), (k, k).  For rows S of the factorisation and rows P added since
        (lowrank.py: H = N0^-1 A_P^T, W, R = diag(sigma_P^2)):
            Q_SS = R_S - a_S N0^-1 a_S^T + (a_S H) W (a_S H)^T,
            Q_PP = R_P W R_P,   Q_SP = -(a_S H) W R_P."""
        f = self._f
        assert f is not None
        lr = f.lowrank
        pend = {k: n for n, k in enumerate(self._pending)}
        s_at = [n for n, k in enumerate(keys) if k not in pend]
        p_at = [n for n, k in enumerate(keys) if k in pend]
        q = np.zeros((len(keys), len(keys)))
        sol = lr.solution() if lr.r else None
        z = None
        if s_at:
            flat = np.array([f.flat_of[keys[n]] for n in s_at])
            rows = factor_rows(f.problem, f.result.factor, flat)
            qs = np.diag(f.sigma[flat] ** 2) - times(rows, *lr.solve(rows))
            if sol is not None:
                z = times(rows, *lr.columns())
                qs = qs + z @ sol.w @ z.T
            q[np.ix_(s_at, s_at)] = qs
        if p_at:
            assert sol is not None  # pending rows: the low-rank part has rows
            pr = [pend[keys[n]] for n in p_at]
            q[np.ix_(p_at, p_at)] = sol.qvv[np.ix_(pr, pr)]
            if s_at:
                qsp = -(z @ sol.w)[:, pr] * (lr.sigma[pr] ** 2)[None, :]
                q[np.ix_(s_at, p_at)] = qsp
                q[np.ix_(p_at, s_at)] = qsp.T
        return 0.5 * (q + q.T)

    def _key_of(self, t: ComponentTest) -> Key:
        return self._keys_told[(t.kind, t.photo, t.point, t.component)]

    def _changes(self, keys, w, r, mdb) -> list[Change]:
        out = []
        new = verdicts(np.asarray(w, float), np.asarray(r, float), self._bm.k_w)
        for k, v, wi, ri, mi in zip(keys, new, w, r, mdb, strict=True):
            before = self._verdict.get(k)
            if before is not None and before != v:
                out.append(self._change(k, before, v, float(wi), float(ri), float(mi)))
            self._verdict[k] = v
        return out

    # ------------------------------------------------------------ taking rows in
    def _take_in(self, group: dict) -> tuple[list[ComponentTest], list[Change], bool]:
        """Take a group of held observations in and test them: (the tests, the verdicts
        that changed, whether the block was factored again).  A group of more rows than a
        factorisation takes (a photo of hundreds of points) goes straight into a new
        factorisation (`_take_in_factored`); a smaller one is a low-rank update."""
        assert self._f is not None
        lr = self._f.lowrank
        ny0, ycol0 = len(self._y0), dict(self._ycol)
        y0 = self._new_unknowns(group)
        keys, rows = group_rows(self._f, self.m, self._ycol, group, y0)
        # the prediction from the block before: e - a dx, variance sigma^2 + a Q_xx a^T
        prev = lr.solution() if lr.r else None
        plain = np.all(rows.ycol < 0, axis=1)
        pred = rows.e.copy()
        var_old = np.zeros(len(rows))
        if prev is not None:
            z = times(rows, *lr.columns())
            pred = pred - z @ prev.we
            var_old = quad_diag(z, prev.w)
        if len(rows) > self.max_rows:
            return self._take_in_factored(group, keys, rows, plain, pred, var_old, ny0, ycol0)
        r0 = lr.r
        lr.add(rows, len(self._y0))
        try:
            sol = lr.solution()
        except GeometryError:
            lr.drop_last(len(rows), ny0)
            self._ycol, self._y0 = ycol0, self._y0[:ny0]
            raise GeometryError("held: these observations do not determine the new photo "
                                "or point yet") from None
        mark(self.m, group)
        self._pending += keys
        k = len(rows)
        sl = slice(r0, r0 + k)
        s2 = rows.sigma ** 2
        qvv = np.maximum(np.diag(sol.qvv)[sl], 0.0)
        r = qvv / s2
        sv, w, mdb, _ = w_tests(sol.v[sl], rows.sigma, qvv, r, self._bm.delta0)
        mdiag = np.diag(lr.m)[sl]
        sig_pred = np.where(plain, np.sqrt(s2 + mdiag - var_old), np.nan)
        pred = np.where(plain, pred, np.nan)
        tested = []
        for n, key in enumerate(keys):
            tested.append(self._component(key, float(pred[n]), float(sig_pred[n]),
                                          float(w[n]), float(r[n]), float(sol.v[r0 + n]),
                                          float(sv[n]), float(mdb[n])))
            self._verdict[key] = tested[-1].verdict
        # a step that brings more rows than a factorisation takes since the last one is
        # factored at once (_added), every verdict checked there: no neighbourhood first
        changed = [] if len(self._pending) > self.max_rows else \
            self._neighbourhood(group, keys, sol, r0)
        return tested, changed, False

    def _take_in_factored(self, group: dict, keys: list, rows: Rows, plain: np.ndarray,
                          pred: np.ndarray, var_old: np.ndarray, ny0: int, ycol0: dict
                          ) -> tuple[list[ComponentTest], list[Change], bool]:
        """A large group: its prediction's variance sigma^2 + a N0^-1 a^T - (the rows since
        the factorisation) for the rows between known photos and points (solves with the
        factor in chunks, nothing kept), then the block factored again with it, every
        component tested from that factorisation."""
        assert self._f is not None
        lr = self._f.lowrank
        sel = np.flatnonzero(plain)
        mdiag = np.zeros(len(rows))
        for a in range(0, len(sel), CHUNK):
            part = take(rows, sel[a:a + CHUNK])
            mdiag[sel[a:a + CHUNK]] = np.diagonal(times(part, *lr.solve(part)))
        s2 = rows.sigma ** 2
        # a row with a new photo or point has no prediction (mdiag not solved for it)
        sig_pred = np.sqrt(np.where(plain, s2 + mdiag - var_old, np.nan))
        pred = np.where(plain, pred, np.nan)
        before = self.m.snapshot()
        mark(self.m, group)
        try:
            changed = self._refactor()
        except GeometryError:
            self.m.restore(before)
            self._ycol, self._y0 = ycol0, self._y0[:ny0]
            self._refactor()
            raise GeometryError("held: these observations do not determine the new photo "
                                "or point yet") from None
        f = self._f
        assert f is not None
        w, r, v, sv, mdb = self._stats(f)
        tested = []
        for n, key in enumerate(keys):
            at = f.flat_of[key]
            tested.append(self._component(key, float(pred[n]), float(sig_pred[n]),
                                          float(w[at]), float(r[at]), float(v[at]),
                                          float(sv[at]), float(mdb[at])))
            self._verdict[key] = tested[-1].verdict
        return tested, changed, True

    def _neighbourhood(self, group: dict, new_keys: list, sol, r0: int) -> list[Change]:
        """Verdict changes among the factorisation's observations on the photos and points
        of the group and the rows added since the factorisation."""
        f, m = self._f, self.m
        assert f is not None
        photos = {m.im_photo[r] for r in group[IMAGE.name]} | \
            {m.g_photo[r] for r in group[GNSS.name]} | {m.i_photo[r] for r in group[IMU.name]}
        points = {m.im_point[r] for r in group[IMAGE.name]} | set(group[CONTROL.name])
        flat = set()
        for i in photos:
            flat.update(f.by_photo.get(i, np.zeros(0, int)).tolist())
        for j in points:
            flat.update(f.by_point.get(j, np.zeros(0, int)).tolist())
        out = []
        if flat:
            flat = np.array(sorted(flat))
            rows = factor_rows(f.problem, f.result.factor, flat)
            q, v = f.lowrank.old_rows(rows, f.q0[flat], f.v0[flat])
            qvv, r = residual_cofactors(q, f.sigma[flat])
            _, w, mdb, _ = w_tests(v, f.sigma[flat], qvv, r, self._bm.delta0)
            out += self._changes([f.keys[n] for n in flat], w, r, mdb)
        if r0:
            sigma = f.lowrank.sigma[:r0]
            qvv = np.maximum(np.diag(sol.qvv)[:r0], 0.0)
            r = qvv / sigma ** 2
            _, w, mdb, _ = w_tests(sol.v[:r0], sigma, qvv, r, self._bm.delta0)
            out += self._changes(self._pending[:r0], w, r, mdb)
        return out

    def _new_unknowns(self, group: dict) -> np.ndarray:
        """Columns and approximations of the group's new photos and points: photos from
        their approximate orientation, points intersected, then both refined by
        Gauss-Newton with everything in the block held at its current estimate."""
        m = self.m
        if not (group["photos"] or group["points"]):
            return self._y0
        eo, xyz = self._current()
        cols = {}
        n = len(self._y0)
        for i in group["photos"]:
            cols[("photo", i)] = n
            n += 6
        for j in group["points"]:
            cols[("point", j)] = n
            n += 3
        if len(cols) == 0:
            return self._y0
        for i in group["photos"]:
            eo[i] = m.photo_eo[i]
        for j in group["points"]:
            xyz[j] = intersect(m, j, eo, group)
        assert self._f is not None
        if not refine(m, self._f.problem, self._globals(), group, eo, xyz):
            raise GeometryError("held: these observations do not determine the new photo "
                                "or point yet")
        y = np.zeros(n - len(self._y0))
        base = len(self._y0)
        for (what, u), c in cols.items():
            y[c - base:c - base + (6 if what == "photo" else 3)] = \
                eo[u] if what == "photo" else xyz[u]
        self._ycol.update(cols)
        self._y0 = np.concatenate([self._y0, y])
        return self._y0

    # ------------------------------------------------------------ labels
    def _label(self, key: Key) -> tuple[str, str, str, str]:
        m = self.m
        kind, u, c = key
        comp = KINDS[kind].components[c]
        if kind == IMAGE.name:
            return kind, m.photo_ids[m.im_photo[u]], m.point_ids[m.im_point[u]], comp
        if kind == CONTROL.name:
            return kind, "", m.point_ids[u], comp
        ph = (m.g_photo if kind == GNSS.name else m.i_photo)[u]
        return kind, m.photo_ids[ph], "", comp

    def _component(self, key: Key, pred: float, sig_pred: float, w: float, r: float,
                   v: float, sv: float, mdb: float) -> ComponentTest:
        from baarda.online.answers import verdict

        kind, photo, point, comp = self._label(key)
        self._keys_told[(kind, photo, point, comp)] = key
        return ComponentTest(kind, photo, point, comp, pred, sig_pred, v, sv, r, w, mdb,
                             verdict(w, r, self._bm.k_w))

    def _change(self, key: Key, before: str, after: str, w: float, r: float,
                mdb: float) -> Change:
        kind, photo, point, comp = self._label(key)
        return Change(kind, photo, point, comp, before, after, w, r, mdb)
