import numpy as np

from baarda.bundle.collinearity import project, project_with_jacobians


def test_analytic_jacobians_equal_finite_differences():
    rng = np.random.default_rng(0)
    m = 50
    eo = np.column_stack([rng.normal(0, 300, (m, 3)) + [0, 0, 1500],
                          rng.normal(0, 0.15, (m, 3))])
    xyz = np.column_stack([rng.normal(0, 400, (m, 2)), rng.normal(0, 50, m)])
    f = np.full(m, 153.0)
    pp = rng.normal(0, 0.02, (m, 2))
    _, je, jp = project_with_jacobians(eo, xyz, f, pp)
    steps = [1e-3] * 3 + [1e-7] * 3  # m, rad (central differences, O(h^2) error)
    for k in range(6):
        d = np.zeros(6)
        d[k] = steps[k]
        num = (project(eo + d, xyz, f, pp) - project(eo - d, xyz, f, pp)) / (2 * steps[k])
        assert np.max(np.abs(num - je[:, :, k])) <= 1e-6 * np.max(np.abs(je[:, :, k]))
    for k in range(3):
        d = np.zeros(3)
        d[k] = 1e-3
        num = (project(eo, xyz + d, f, pp) - project(eo, xyz - d, f, pp)) / 2e-3
        assert np.max(np.abs(num - jp[:, :, k])) <= 1e-6 * np.max(np.abs(jp[:, :, k]))
