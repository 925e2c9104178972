"""Dense brute-force references for tests (small blocks only)."""

from __future__ import annotations

import numpy as np

from baarda.bundle.bundle_model import BundleModel


def dense_system(model: BundleModel) -> tuple[np.ndarray, np.ndarray]:
    """Dense A (n, u) and weights p (n,) in the flat observation order of a BundleModel."""
    s = model.factor.system
    lin = model.factor.lin
    nf, npn, m = s.nf, s.np, model.layout.m
    nc = len(model.result.problem.control)
    a = np.zeros((2 * m + 3 * nc, 6 * nf + 3 * npn))
    for i in range(m):
        a[2 * i:2 * i + 2, 6 * s.frame[i]:6 * s.frame[i] + 6] = lin.jf[i]
        a[2 * i:2 * i + 2, 6 * nf + 3 * s.point[i]:6 * nf + 3 * s.point[i] + 3] = lin.jp[i]
    for c in range(nc):
        j = s.control_point[c]
        a[2 * m + 3 * c:2 * m + 3 * c + 3, 6 * nf + 3 * j:6 * nf + 3 * j + 3] = lin.jc[c]
    keep = np.concatenate([np.arange(2 * m), 2 * m + model.layout.ctrl_sel])
    a = a[keep]
    p = np.where(model.active, 1.0 / model.sigma**2, 0.0)
    return a, p
