"""Gruen's modified data snooping of a bundle block with a reliability-model table.

Every image observation gets its Gruen class (baarda.planning.point_classes), the table gives the
approximate sqrt(qvv) of that class for the block's design (points per photo, stereo, single
or twin control), and baarda.quality.modified decides; control observations have no table
value and are computed exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from baarda.bundle.bundle_model import BundleModel
from baarda.bundle.bundle_result import BundleResult
from baarda.options import TestOptions
from baarda.planning.point_classes import classify
from baarda.planning.reliability_tables import DesignKey, ReliabilityTable, baarda_table, design_key
from baarda.quality.modified import ModifiedSnooping, modified_snooping


@dataclass
class BlockModifiedSnooping:
    model: BundleModel
    key: DesignKey
    classes: np.ndarray  # (n,) Gruen class per component ('control' for control obs)
    result: ModifiedSnooping
    table_source: str

    def table(self) -> pd.DataFrame:
        m, r = self.model, self.result
        scale = np.where(m.kind == "image", 1e3, 1.0)
        return pd.DataFrame({
            "kind": m.kind, "photo": m.frame, "point": m.point, "component": m.component,
            "class": self.classes, "residual": m.residuals * scale, "sigma": m.sigma * scale,
            "approx_sqrt_qvv": r.approx, "w0": r.w0, "exact": r.exact,
            "sqrt_qvv": np.sqrt(r.redundancy_number), "statistic": r.statistic_value,
            "rejected": r.rejected})

    def summary(self) -> str:
        k = self.key
        return (f"design {k.pattern}, {'stereo' if k.stereo else 'mono'}, {k.control} control; "
                f"approximations from {self.table_source}\n" + self.result.summary())


def model_classes(model: BundleModel, partial_as_control: bool = True) -> np.ndarray:
    """Gruen class of each component of a BundleModel ('control' for control observations)."""
    rc = classify(model.result.block, partial_as_control)
    img = model.image_row >= 0
    return np.where(img, rc.label[np.where(img, model.image_row, 0)], "control").astype(object)


def modified_snoop(result: BundleResult, *, table: ReliabilityTable | None = None,
                   key: DesignKey | None = None, k_q: float = 0.25,
                   tests: TestOptions | None = None,
                   statistic: str = "w") -> BlockModifiedSnooping:
    """One pass of Gruen's modified data snooping of an adjusted block (tests: default the
    project's alpha0 and beta0)."""
    model = BundleModel(result)
    table = table or baarda_table()
    key = key or design_key(result.block)
    classes = model_classes(model)
    approx = table.lookup(classes, model.component, key)
    approx[model.kind != "image"] = np.nan
    res = modified_snooping(model, approx, k_q=k_q, statistic=statistic,
                            tests=tests or TestOptions.resolve(result.block.settings))
    source = str(table.frame["source"].iloc[0]) if len(table.frame) else "table"
    return BlockModifiedSnooping(model, key, classes, res, source)
