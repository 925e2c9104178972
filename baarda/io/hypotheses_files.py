"""The files of the tests of an independent-model block: control clusters (clusters.csv)
and user hypotheses (hypotheses.csv), docs/independent_models.md.  Read and checked here;
independent/model_hypotheses.py turns them into the H of a given adjustment."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.hypothesis_rows import HypothesisRows
from baarda.errors import ProjectError
from baarda.io.table import Table


def read_clusters(path: str | Path) -> dict[str, list[str]]:
    """clusters.csv: columns cluster, point; the points of each cluster in file order."""
    t = Table(path, ["cluster", "point"])
    out: dict[str, list[str]] = {}
    for c, p in zip(t.text("cluster"), t.text("point"), strict=True):
        out.setdefault(str(c), []).append(str(p))
    return out


def read_hypotheses(path: str | Path) -> HypothesisRows:
    """hypotheses.csv: columns hypothesis, kind, point, component, value and optionally
    model and column (docs/independent_models.md)."""
    t = Table(path, ["hypothesis", "kind", "point", "component", "value"])
    kind, comp = t.text("kind"), t.text("component")
    model = t.text("model", allow_empty=True) if t.has("model") else np.full(len(t), "")
    column = t.numbers("column", allow_empty=True) if t.has("column") else np.ones(len(t))
    column = np.where(np.isfinite(column), column, 1).astype(int)
    for i in range(len(t)):
        k, c = kind[i], comp[i]
        ok = (k == "model" and c in ("x", "y", "z") and model[i]) or \
             (k == "control" and c in ("X", "Y", "Z"))
        if not ok:
            raise ProjectError(t.path, f"kind '{k}' with component '{c}': use kind model "
                               "(with a model, component x/y/z) or control (X/Y/Z)",
                               int(t.lines[i]), "kind")
    return HypothesisRows(str(t.path), t.text("hypothesis"), kind, model, t.text("point"),
                          comp, t.numbers("value"), column, np.asarray(t.lines))
