"""Non-conventional alternative hypotheses of a model block (FOTEF sec. 5).

The H matrices are built here; the tests themselves (w = H^T P v / sqrt(H^T P Qvv P H),
nabla, one forward substitution on the Cholesky factor) are quality.hypotheses.

* model deformations (deformations.py), block-invariant (one column: the same deformation
  in every model) and strip-invariant (one column per strip);
* control clusters: the control points of a group shifted together (one column per
  coordinate);
* user-defined H read from a file (hypotheses.csv):

      hypothesis, kind, model, point, component, value [, column]

  kind 'model' (model coordinate of `point` in `model`, component x/y/z, value in µm) or
  'control' (control coordinate, component X/Y/Z, value in m); each row is the shift of
  that observation for nabla = 1; `column` (default 1) makes multi-dimensional hypotheses.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from baarda.block.hypothesis_rows import HypothesisRows
from baarda.block.model_deformations import ALL, deformation_rows
from baarda.errors import ProjectError
from baarda.independent.independent_model import IndependentModel
from baarda.options import DEFAULT_TESTS, TestOptions
from baarda.quality.distributions import b_method
from baarda.quality.hypotheses import HypothesisTest, hypothesis_test
from baarda.quality.statistics import R_MIN


def _model_part(qm: IndependentModel, rows_field: np.ndarray) -> np.ndarray:
    """(m_block, 3, q) shifts in mm of the block rows -> flat (n, q) of the quality model."""
    pb = qm.problem
    f = rows_field[pb.rows][:, pb.comps, :]
    f = pb.transform_rows(f)
    h = np.zeros((qm.n, f.shape[2]))
    h[: qm.m * qm.k] = f.reshape(qm.m * qm.k, -1)
    return h


def deformation_h(qm: IndependentModel, name: str, per: str = "block"):
    """H (n, q) of deformation `name`, nabla in µm; per 'block' (q = 1) or 'strip'.

    Returns (H, column labels) or None when the deformation has no component in this
    adjustment (e.g. affinity in the height adjustment).
    """
    pb = qm.problem
    bl = pb.block
    field = deformation_rows(bl, name, pb.centroid, pb.radius) * 1e-3  # mm per µm
    if not np.any(field[pb.rows][:, pb.comps]):
        return None
    if per == "block":
        return _model_part(qm, field[:, :, None]), [name]
    strips = np.unique(bl.strip.astype(str))
    s_of = bl.strip.astype(str)[bl.obs_model]
    cols = np.stack([field * (s_of == s)[:, None] for s in strips], axis=2)
    return _model_part(qm, cols), [f"{name} strip {s}" for s in strips]


def _test(qm: IndependentModel, h: np.ndarray, name: str,
          tests: TestOptions) -> HypothesisTest:
    """quality.hypotheses.hypothesis_test on the testable columns of h.

    A column is testable when the adjustment does not absorb it: its redundancy
    r_H = h^T P Qvv P h / h^T P h (from the test's own boundary value: M = (delta0/MDB)^2)
    is at least R_MIN, the limit the w-tests use.  Below it M is at the level of rounding
    and the test statistic would be noise (z_scale of a flat block, whose projection-centre
    heights are free tie points, is such a case).
    """
    h = np.atleast_2d(h.T).T
    p = np.where(qm.active, 1.0 / qm.sigma**2, 0.0)
    delta0 = b_method(tests.alpha0, tests.beta0).delta0
    keep = np.zeros(h.shape[1], bool)
    for j in range(h.shape[1]):
        hpj = float(h[:, j] @ (p * h[:, j]))
        if hpj <= 0:
            continue
        t = hypothesis_test(qm, h[:, j], name, tests)
        if t.q == 1 and t.mdb is not None and np.isfinite(t.mdb):
            keep[j] = (delta0 / t.mdb) ** 2 / hpj >= R_MIN
    if not keep.any():
        return HypothesisTest(f"{name} (not testable: absorbed by the adjustment)", 0, np.nan,
                              np.nan, np.nan, False, np.full(h.shape[1], np.nan), None, None)
    if not keep.all():
        name += f" ({int((~keep).sum())} absorbed column(s) left out)"
    t = hypothesis_test(qm, h[:, keep], name, tests)
    if not keep.all():
        nabla = np.full(h.shape[1], np.nan)
        nabla[keep] = t.nabla
        t = replace(t, nabla=nabla)
    return t


def deformation_tests(qm: IndependentModel, names: tuple[str, ...] = ALL,
                      tests: TestOptions = DEFAULT_TESTS) -> list[HypothesisTest]:
    """Block-invariant and strip-invariant tests of every deformation, and all together."""
    out, joint, joint_names = [], [], []
    n_strips = len(np.unique(qm.problem.block.strip.astype(str)))
    for name in names:
        hb = deformation_h(qm, name, "block")
        if hb is None:
            continue
        tb = _test(qm, hb[0], f"block-invariant {name}", tests)
        out.append(tb)
        if tb.q:
            joint.append(hb[0])
            joint_names.append(name)
        if n_strips > 1:
            hs, _ = deformation_h(qm, name, "strip")
            out.append(_test(qm, hs, f"strip-invariant {name} ({n_strips} strips)",
                             tests))
    if len(joint) > 1:
        out.append(_test(qm, np.hstack(joint), "all block-invariant deformations "
                         f"({', '.join(joint_names)})", tests))
    return out


def control_cluster_h(qm: IndependentModel, points: list[str]) -> np.ndarray:
    """H (n, q): the control points `points` shifted together, one column per coordinate."""
    pb = qm.problem
    want = np.isin(qm.point, np.asarray(points, dtype=object)) & (qm.kind == "control")
    cols = []
    for c in pb.comps:
        col = (want & (qm.xyz_col == c)).astype(float)
        if col.any():
            cols.append(col)
    return np.column_stack(cols) if cols else np.zeros((qm.n, 0))


def cluster_tests(qm: IndependentModel, clusters: dict[str, list[str]],
                  tests: TestOptions = DEFAULT_TESTS) -> list[HypothesisTest]:
    out = []
    for name, pts in clusters.items():
        h = control_cluster_h(qm, pts)
        if h.shape[1]:
            out.append(_test(qm, h, f"control cluster {name} ({len(pts)} points)",
                             tests))
    return out


class UserHypotheses:
    """The hypotheses of hypotheses.csv (io/hypotheses_files.read_hypotheses), turned into H
    for a given quality model."""

    def __init__(self, rows: HypothesisRows):
        self.rows = rows

    def names(self) -> list[str]:
        return self.rows.names()

    def h(self, qm: IndependentModel, name: str) -> np.ndarray:
        """H (n, q) of hypothesis `name`; rows not in this adjustment are ignored."""
        u = self.rows
        pb = qm.problem
        bl = pb.block
        sel = np.flatnonzero(u.name == name)
        cols = sorted(set(u.column[sel]))
        mindex = {m: i for i, m in enumerate(bl.models)}
        pindex = {p: i for i, p in enumerate(bl.points)}
        row_of = {(int(m), int(p)): r for r, (m, p) in
                  enumerate(zip(bl.obs_model, bl.obs_point, strict=True))}
        field = np.zeros((len(bl.obs_model), 3, len(cols)))
        hc = np.zeros((qm.n, len(cols)))
        for i in sel:
            line = int(u.lines[i])
            j = pindex.get(u.point[i])
            if j is None:
                raise ProjectError(u.path, f"unknown point '{u.point[i]}'", line,
                                   "point")
            q = cols.index(u.column[i])
            if u.kind[i] == "model":
                m = mindex.get(u.model[i])
                r = row_of.get((m, j)) if m is not None else None
                if r is None:
                    raise ProjectError(u.path, f"point '{u.point[i]}' is not in "
                                       f"model '{u.model[i]}'", line, "model")
                field[r, "xyz".index(u.component[i]), q] += u.value[i] * 1e-3
            else:
                hit = (qm.kind == "control") & (qm.point == u.point[i]) & \
                      (qm.xyz_col == "XYZ".index(u.component[i]))
                hc[hit, q] += u.value[i]
        return _model_part(qm, field) + hc

    def tests(self, qm: IndependentModel,
              tests: TestOptions = DEFAULT_TESTS) -> list[HypothesisTest]:
        out = []
        for name in self.names():
            h = self.h(qm, name)
            keep = np.any(h != 0, axis=0)
            if keep.any():
                out.append(_test(qm, h[:, keep], f"user: {name}", tests))
        return out


def decision(tests: Sequence[HypothesisTest]) -> str:
    """Whether a systematic-error model is needed, from the deformation tests."""
    rej = [t for t in tests if t.rejected and ("invariant" in t.name)]
    if not rej:
        return ("no model deformation is significant: no systematic-error model (self-"
                "calibration) is needed")
    parts = []
    for t in rej:
        size = np.array2string(t.nabla, precision=2, max_line_width=200)
        parts.append(f"{t.name} (T/q = {t.statistic:.2f} > {t.critical:.2f}, estimated "
                     f"{size} µm)")
    return "systematic-error model needed for: " + "; ".join(parts)
