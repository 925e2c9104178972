"""Dense brute-force references for tests (small blocks only)."""

from __future__ import annotations

import numpy as np

from baarda.bundle.bundle_model import BundleModel


def dense_system(model: BundleModel) -> tuple[np.ndarray, np.ndarray]:
    """Dense A (n, u) and weights p (n,) in the flat observation order of a BundleModel,
    assembled from the linearisation's own Jacobians (frames of b unknowns each, points,
    then the global unknowns; held unknowns left out)."""
    s = model.factor.system
    lin = model.factor.lin
    nf, npn, ng, m, b = s.nf, s.np, s.ng, model.layout.m, s.b
    nc = len(model.result.problem.control)
    nu = b * nf + 3 * npn + ng
    a = np.zeros((2 * m + 3 * nc, nu))
    for i in range(m):
        a[2 * i:2 * i + 2, b * s.frame[i]:b * s.frame[i] + b] = lin.jf[i]
        a[2 * i:2 * i + 2, b * nf + 3 * s.point[i]:b * nf + 3 * s.point[i] + 3] = lin.jp[i]
        if lin.jg is not None:
            for k, col in enumerate(s.gcol[i]):
                if col >= 0:
                    a[2 * i:2 * i + 2, b * nf + 3 * npn + col] = lin.jg[i, :, k]
    for c in range(nc):
        j = s.control_point[c]
        a[2 * m + 3 * c:2 * m + 3 * c + 3, b * nf + 3 * j:b * nf + 3 * j + 3] = lin.jc[c]
    keep = np.concatenate([np.arange(2 * m), 2 * m + model.layout.ctrl_sel])
    a = a[keep]
    if s.mx:
        ax = np.zeros((s.mx, nu))
        for r in range(s.mx):
            f = s.x_frame[r]
            if f >= 0:
                ax[r, b * f:b * f + b] = lin.jxf[r, 0]
            ax[r, b * nf + 3 * npn:] = lin.jxg[r, 0]
        a = np.vstack([a, ax])
    held = np.zeros(nu, bool)  # unknowns held by direct constraints: not unknowns
    for w, start in ((lin.wf, 0), (lin.wp, b * nf), (lin.wg, b * nf + 3 * npn)):
        if w is not None:
            held[start:start + w.size] = w.ravel() > 0
    p = np.where(model.active, 1.0 / model.sigma**2, 0.0)
    return a[:, ~held], p
