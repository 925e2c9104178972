"""A BAL problem and BAL's projection written out independently of baarda's collinearity
code, for the tests."""

import numpy as np

from baarda.io.bal import BalProblem, rodrigues, rotation_vector


def bal_residuals(p: BalProblem) -> np.ndarray:
    """BAL's projection written out independently of baarda's collinearity code."""
    c = p.cameras[p.obs_camera]
    pc = np.einsum("mij,mj->mi", rodrigues(c[:, :3]), p.points[p.obs_point]) + c[:, 3:6]
    q = -pc[:, :2] / pc[:, 2:3]
    n2 = np.sum(q**2, axis=1)
    return (c[:, 6] * (1 + c[:, 7] * n2 + c[:, 8] * n2**2))[:, None] * q - p.obs_xy


def _synthetic(seed=0, ncam=6, npt=60):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-1, 1, (npt, 3)) * [2, 2, 0.5]
    cams = np.zeros((ncam, 9))
    for i in range(ncam):
        ang = 2 * np.pi * i / ncam
        centre = np.array([3 * np.cos(ang), 3 * np.sin(ang), 2.0])
        z = centre / np.linalg.norm(centre)  # camera looks along -z, towards the origin
        x = np.cross([0, 0, 1.0], z)
        x /= np.linalg.norm(x)
        r = np.vstack([x, np.cross(z, x), z])  # world -> camera
        cams[i, :3] = rotation_vector(r)
        cams[i, 3:6] = -r @ centre
        cams[i, 6:9] = [500 + 20 * i, -0.05, 0.01]
    p = BalProblem(cams, pts, np.repeat(np.arange(ncam), npt), np.tile(np.arange(npt), ncam),
                   np.zeros((ncam * npt, 2)))
    p.obs_xy = bal_residuals(p) + rng.normal(0, 0.5, (ncam * npt, 2))  # obs_xy = 0 here
    return p
