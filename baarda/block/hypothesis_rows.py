"""User hypotheses of an independent-model block as data (hypotheses.csv, read by
io/hypotheses_files.py; turned into H by independent/model_hypotheses.py)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class HypothesisRows:
    """hypotheses.csv as read: one row per (hypothesis, observation component, column of
    H) with its value (µm for model coordinates, m for control); `lines` for messages."""

    path: str
    name: np.ndarray
    kind: np.ndarray  # "model" or "control"
    model: np.ndarray  # the model of a model coordinate ('' for control)
    point: np.ndarray
    component: np.ndarray  # x, y, z (model) or X, Y, Z (control)
    value: np.ndarray
    column: np.ndarray  # column of H (1, 2, ...)
    lines: np.ndarray

    def names(self) -> list[str]:
        return list(dict.fromkeys(self.name))
