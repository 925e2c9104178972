"""The data of an independent-model block: models, points and model coordinates.

Units: model coordinates in mm of the model scale (image scale for models formed from
photographs), their standard deviations in mm inside (µm in files and reports); terrain
coordinates and control standard deviations in m.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from baarda.options import DEFAULT_TESTS


@dataclass
class ModelSettings:
    """Settings of a model project (project.toml)."""

    name: str = "models"
    sigma_model_um: tuple[float, float] = (10.0, 15.0)  # xy, z (FOTEF's standard)
    sigma_control_m: tuple[float, float, float] = (0.05, 0.05, 0.05)
    alpha0: float = DEFAULT_TESTS.alpha0
    beta0: float = DEFAULT_TESTS.beta0
    pre_um: tuple[float, float] = (250.0, 500.0)  # pre-adjustment thresholds xy, z (FOTEF)
    angle_unit: str = "gon"  # of the rotations in the output


@dataclass
class ModelBlock:
    """Models (frames), points and one row of model coordinates per point per model.

    `role` of a point: 'control' (given coordinates with sigma; NaN sigma = not observed),
    'check' (given, not used), 'tie'.  Projection centres are points with `pc` True.
    `obs_cov` (m, 3, 3), when given, is the full covariance of each row (mm^2); otherwise
    the rows are uncorrelated with standard deviations `obs_sigma`.
    """

    settings: ModelSettings
    models: list[str]
    strip: np.ndarray  # (nm,) object: strip label of each model
    points: list[str]
    role: np.ndarray  # (np,) object
    pc: np.ndarray  # (np,) bool
    xyz: np.ndarray  # (np, 3) given terrain coordinates [m], NaN where not given
    sigma: np.ndarray  # (np, 3) control standard deviations [m], NaN = not observed
    obs_model: np.ndarray  # (m,) int
    obs_point: np.ndarray  # (m,) int
    obs_xyz: np.ndarray  # (m, 3) model coordinates [mm]
    obs_sigma: np.ndarray  # (m, 3) [mm]
    obs_cov: np.ndarray | None = None  # (m, 3, 3) [mm^2]
    source: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def n_models(self) -> int:
        return len(self.models)

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def controlled(self) -> np.ndarray:
        """(np, 3) bool: the coordinate is a control observation."""
        return (self.role == "control")[:, None] & np.isfinite(self.sigma)

    def models_per_point(self) -> np.ndarray:
        return np.bincount(self.obs_point, minlength=self.n_points)

    def centroids(self) -> np.ndarray:
        """(nm, 3) centroid of each model's coordinates (projection centres left out)."""
        use = ~self.pc[self.obs_point]
        use_any = np.bincount(self.obs_model[use], minlength=self.n_models) > 0
        use = use | ~use_any[self.obs_model]
        c = np.zeros((self.n_models, 3))
        np.add.at(c, self.obs_model[use], self.obs_xyz[use])
        return c / np.maximum(np.bincount(self.obs_model[use], minlength=self.n_models),
                              1)[:, None]

    def with_observations(self, obs_xyz: np.ndarray) -> ModelBlock:
        return replace(self, obs_xyz=np.asarray(obs_xyz, float), notes=list(self.notes))

    def summary(self) -> str:
        r = self.role
        return (f"{self.settings.name}: {self.n_models} models in "
                f"{len(np.unique(self.strip.astype(str)))} strip(s), {len(self.obs_model)} "
                f"model points, {self.n_points} points ({int(np.sum(r == 'control'))} control, "
                f"{int(np.sum(r == 'check'))} check, {int(np.sum((r == 'tie') & ~self.pc))} "
                f"tie, {int(np.sum(self.pc))} projection centres)")
