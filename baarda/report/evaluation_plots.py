"""Power curves of a detection-power study: detection (the planted component's w-test
significant in the first adjustment, with the B-method's curve) next to identification
(the share each strategy located, and identified up to the inseparable group) against the
blunder's size in MDB (docs/evaluation.md); as PNG and a self-contained HTML page."""

from __future__ import annotations

import base64
import html

import numpy as np
from scipy.stats import norm

from baarda.evaluation.rates import clopper_pearson
from baarda.evaluation.study import Study
from baarda.quality.distributions import b_method
from baarda.report.plots import plt, to_png

BINS = 8


def b_method_power(size_mdb: np.ndarray, alpha0: float, beta0: float) -> np.ndarray:
    """P(|w| > k) for a blunder of `size_mdb` MDB: the w-test's noncentrality is
    size_mdb * delta0 (delta0 of alpha0, beta0), so 1 MDB gives beta0."""
    bm = b_method(alpha0, beta0)
    k = norm.ppf(1 - alpha0 / 2)
    d = np.abs(size_mdb) * bm.delta0
    return norm.sf(k - d) + norm.cdf(-k - d)


def power_curves(study: Study) -> bytes | None:
    """PNG of the located share against |size| in MDB per strategy (95 % intervals), the
    share significant in the first adjustment and the B-method's curve; None without
    blunders."""
    b = study.blunders
    if not len(b):
        return None
    o = study.options
    size = np.abs(b["size_mdb"].to_numpy(float))
    lo, hi = float(size.min()), float(size.max())
    edges = np.linspace(lo, hi, BINS + 1) if hi > lo else np.array([lo - 0.05, hi + 0.05])
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    x = np.linspace(0, max(hi, 1.0) * 1.1, 200)
    ax.plot(x, b_method_power(x, o.tests.alpha0, o.tests.beta0), color="black", lw=1,
            label=f"B-method, w-test (alpha0 {o.tests.alpha0:g})")
    first = b.drop_duplicates(["trial", "kind", "photo", "point", "component"])
    series = [("detected: |w| > k in the first adjustment", first, "significant_first")]
    for name in o.strategies:
        part = b[b["strategy"] == name]
        series.append((f"{name}: located", part, "located"))
        if "identified" in part and not part["separable"].all():
            series.append((f"{name}: identified up to the group", part, "identified"))
    for n, (name, part, col) in enumerate(series):
        s = np.abs(part["size_mdb"].to_numpy(float))
        hit = part[col].to_numpy(bool)
        mids, rate, err = [], [], []
        for a, z in zip(edges[:-1], edges[1:], strict=True):
            sel = (s >= a) & (s <= z)
            if sel.any():
                k, m = int(hit[sel].sum()), int(sel.sum())
                ci = clopper_pearson(k, m)
                mids.append(0.5 * (a + z) + 0.01 * n * (z - a))
                rate.append(k / m)
                err.append((k / m - ci[0], ci[1] - k / m))
        if mids:
            ax.errorbar(mids, rate, yerr=np.array(err).T, marker="o", ms=4, capsize=2,
                        lw=1, ls={"significant_first": "--", "identified": ":"}.get(col, "-"),
                        label=name)
    ax.set_xlabel("blunder size in units of the observation's own MDB")
    ax.set_ylabel("share detected / identified")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    return to_png(fig)


def study_html(study: Study, png: bytes | None) -> str:
    """A self-contained HTML page: the summary lines and the power curves."""
    lines = "".join(f"<li>{html.escape(s)}</li>" for s in study.summary().splitlines())
    img = (f'<img alt="power curves" src="data:image/png;base64,'
           f'{base64.b64encode(png).decode()}">' if png else "<p>no blunders planted</p>")
    return ("<!doctype html><html><head><meta charset='utf-8'><title>baarda evaluate"
            "</title></head><body><h1>Detection power</h1><ul>" + lines + "</ul>" + img
            + "</body></html>\n")
