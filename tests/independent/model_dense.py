"""Dense design matrix of an independent-model adjustment (brute-force reference)."""

import numpy as np


def dense_design(qm):
    """Dense A (n, u) of an IndependentModel from its linearization (frames, then points)."""
    pb, lin = qm.problem, qm.factor.lin
    nf, b, npnt, d = pb.system.nf, pb.b, pb.system.np, pb.d
    m, k = qm.m, qm.k
    a_rows = np.zeros((m, k, nf * b + npnt * d))
    pt = pb.remap[pb.block.obs_point[pb.rows]]
    for i in range(m):
        a_rows[i, :, pb.frame[i] * b:(pb.frame[i] + 1) * b] = lin.jf[i]
        a_rows[i, :, nf * b + pt[i] * d: nf * b + (pt[i] + 1) * d] = lin.jp[i]
    c_rows = np.zeros((len(pb.control), k, nf * b + npnt * d))
    for i, j in enumerate(pb.remap[pb.control]):
        c_rows[i, :, nf * b + j * d: nf * b + (j + 1) * d] = lin.jc[i]
    a = np.concatenate([a_rows.reshape(m * k, -1),
                        c_rows.reshape(-1, a_rows.shape[-1])[qm.layout.ctrl_sel]])
    return a
