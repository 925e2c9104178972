"""The frame pairs' product B Sigma B^T over the nonzero blocks of B
(adjustment/pair_cofactors._sandwich) against the dense product."""

import numpy as np

from baarda.adjustment.pair_cofactors import _sandwich


def test_the_blockwise_product_equals_the_dense_one_twin_rays_and_extra_rows_included():
    rng = np.random.default_rng(5)
    b, k, nh = 6, 2, 7
    # 4 points; each seen by some of the 7 frames of the neighbourhood (frame 0 the frame
    # itself); point 2 twice by frame 3 (two rays of one frame: its block counted once)
    frames_of = [[0, 1, 2], [0, 4], [0, 3, 3, 5, 6], [0, 2, 6]]
    ptr = np.cumsum([0] + [len(f) for f in frames_of]).astype(np.int64)
    frame_sorted = np.concatenate(frames_of).astype(np.int64)
    colof = np.arange(nh, dtype=np.int64)  # hood frame g is column block g
    obs = np.array([3, 0, 2, 1, 2], np.int64)  # the frame's observations (point 2 twice)
    point = np.array([0, 1, 2, 3], np.int64)
    nobs, extra = len(obs), 3
    nr = nobs * k + extra
    bm = np.zeros((nr, nh * b))
    for a, o in enumerate(obs):
        for g in set(frames_of[point[o]]):
            bm[a * k:a * k + k, g * b:g * b + b] = rng.normal(size=(k, b))
    bm[nobs * k:, :b] = rng.normal(size=(extra, b))
    s = rng.normal(size=(nh * b, nh * b))
    sig = s @ s.T
    q = _sandwich(bm, sig, nobs, k, b, obs, point, ptr, frame_sorted, colof)
    dense = bm @ sig @ bm.T
    upper = np.triu_indices(nr, 1)
    assert np.allclose(q[upper], dense[upper], rtol=1e-12, atol=1e-12 * np.abs(dense).max())
    assert not np.tril(q).any()
