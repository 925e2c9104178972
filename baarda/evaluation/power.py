"""What the report of a detection-power study shows, as tables (`baarda evaluate` writes
them: power.csv, b_method_power.csv): the share of planted blunders each strategy located
per size class in MDB with its 95 % Clopper-Pearson interval, and the B-method's power of
the w-test for a blunder of a given size in MDB."""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.stats import norm

from baarda.evaluation.rates import clopper_pearson
from baarda.evaluation.study import Study
from baarda.quality.distributions import b_method

BINS = 8
FIRST = "first adjustment: |w| > k"


def b_method_power(size_mdb: np.ndarray, alpha0: float, beta0: float) -> np.ndarray:
    """P(|w| > k) for a blunder of `size_mdb` MDB: the w-test's noncentrality is
    size_mdb * delta0 (delta0 of alpha0, beta0), so 1 MDB gives beta0."""
    bm = b_method(alpha0, beta0)
    k = norm.ppf(1 - alpha0 / 2)
    d = np.abs(size_mdb) * bm.delta0
    return norm.sf(k - d) + norm.cdf(-k - d)


def power_table(study: Study, bins: int = BINS) -> pd.DataFrame:
    """One row per series (the first adjustment's w-test, then each strategy: located, and
    identified up to the inseparable group where some blunders are not separable) and size
    class: series, lo, hi (|size| in MDB), n planted, located (or significant), rate,
    ci_lo, ci_hi (95 % Clopper-Pearson).  Empty without blunders."""
    cols = ["series", "lo", "hi", "n", "located", "rate", "ci_lo", "ci_hi"]
    b = study.blunders
    if not len(b):
        return pd.DataFrame(columns=cols)
    size = np.abs(b["size_mdb"].to_numpy(float))
    lo, hi = float(size.min()), float(size.max())
    edges = np.linspace(lo, hi, bins + 1) if hi > lo else np.array([lo - 0.05, hi + 0.05])
    first = b.drop_duplicates(["trial", "kind", "photo", "point", "component"])
    series = [(FIRST, first, "significant_first")]
    for name in study.options.strategies:
        part = b[b["strategy"] == name]
        series.append((name, part, "located"))
        if "identified" in part and not part["separable"].all():  # identification (issue 30)
            series.append((f"{name}: identified up to the group", part, "identified"))
    rows = []
    for name, part, col in series:
        s = np.abs(part["size_mdb"].to_numpy(float))
        hit = part[col].to_numpy(bool)
        for a, z in zip(edges[:-1], edges[1:], strict=True):
            sel = (s >= a) & (s <= z)
            if sel.any():
                k, m = int(hit[sel].sum()), int(sel.sum())
                ci = clopper_pearson(k, m)
                rows.append({"series": name, "lo": float(a), "hi": float(z), "n": m,
                             "located": k, "rate": k / m, "ci_lo": float(ci[0]),
                             "ci_hi": float(ci[1])})
    return pd.DataFrame(rows, columns=cols)


def b_method_table(study: Study, points: int = 200) -> pd.DataFrame:
    """The B-method's power of the w-test: size_mdb from 0 to 1.1 x the largest planted
    size (at least 1.1), power."""
    b = study.blunders
    top = float(np.abs(b["size_mdb"].to_numpy(float)).max()) if len(b) else 1.0
    x = np.linspace(0, max(top, 1.0) * 1.1, points)
    t = study.options.tests
    return pd.DataFrame({"size_mdb": x, "power": b_method_power(x, t.alpha0, t.beta0)})
