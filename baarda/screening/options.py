"""The settings of the screening stages, apart from the computation, so that a command
line can offer them without importing it."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ScreeningOptions:
    """Settings of the three stages (alpha0/beta0 None: those of the project)."""

    stages: tuple[int, ...] = (1, 2, 3)
    alpha0: float | None = None  # stages 2 and 3 (w-test)
    beta0: float | None = None
    pair_alpha0: float = 1e-4  # stage 1: the 2D model is approximate, so only clear errors
    pair_transform: str = "auto"  # auto | similarity | affine | projective
    pair_statistic: str = "w"  # w (pooled sigma of the pairs) | tau (each pair's own)
    pair_min_redundancy: int = 4
    pair_tolerance_mm: float | None = None  # None: the relief parallax of each pair
    rho_max: float = 0.9  # |correlation| of w-tests above which errors are not separable
