"""Matplotlib figures of the report (Agg backend, PNG bytes): histograms.

Every function returns a `Plot`: the PNG, a title and a caption that says in words what
the figure marks, so that the HTML (and a test) can read what was drawn.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.stats import norm  # noqa: E402

from baarda.report.histogram import Histogram  # noqa: E402

DPI = 96
COLORS = {"active": "#1f5fa8", "rejected": "#d62728", "flagged": "#ff7f0e",
          "control": "#1f5fa8", "check": "#2ca02c", "tie": "#7f7f7f"}


@dataclass
class Plot:
    name: str
    title: str
    png: bytes
    caption: str = ""
    marked: list[str] = field(default_factory=list)  # observations marked in the figure


def to_png(fig, tight: bool = True) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, bbox_inches="tight" if tight else None)
    plt.close(fig)
    return buf.getvalue()


def _bars(ax, h: Histogram, color: str) -> None:
    ax.bar(h.centers, h.counts, width=h.width * 0.9, color=color, edgecolor="none")
    ax.set_xlim(h.centers[0] - h.width, h.centers[-1] + h.width)
    ax.grid(axis="y", alpha=0.3)


def residual_histograms(hists: list[tuple[str, Histogram]], unit: str,
                        name: str = "hist_image") -> Plot:
    """Side-by-side histograms (e.g. image x, y, x+y) with the outside counts."""
    fig, axes = plt.subplots(1, len(hists), figsize=(3.6 * len(hists), 2.8), squeeze=False)
    for ax, (title, h) in zip(axes[0], hists, strict=True):
        _bars(ax, h, COLORS["active"])
        out = len(h.outside_values)
        ax.set_title(f"{title}: n = {h.n}" + (f", {out} outside" if out else ""), fontsize=10)
        ax.set_xlabel(f"residual [{unit}] (classes of {h.width:g})")
        ax.set_ylabel("number")
    fig.tight_layout()
    cap = "; ".join(f"{t}: {len(h.outside_values)} beyond {h.centers[0]:g} .. "
                    f"{h.centers[-1]:g} {unit}" for t, h in hists)
    return Plot(name, "Histograms of the residuals", to_png(fig), cap)


def w_histogram(hists: list[tuple[str, Histogram]], k: float | None,
                name: str = "hist_w") -> Plot:
    """Histograms of w with the standard normal curve (scaled to the count) and +-k marked."""
    cols = min(4, len(hists))  # a grid, four per row: readable at any number of groups
    rows = -(-len(hists) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.5 * cols, 2.75 * rows), squeeze=False)
    for ax in axes.ravel()[len(hists):]:
        ax.axis("off")
    caps = []
    for ax, (title, h) in zip(axes.ravel(), hists, strict=False):
        _bars(ax, h, COLORS["active"])
        x = np.linspace(h.centers[0] - h.width / 2, h.centers[-1] + h.width / 2, 400)
        ax.plot(x, h.n * h.width * norm.pdf(x), color="black", lw=1.2, label="N(0, 1)")
        beyond = 0
        if k is not None and np.isfinite(k):
            for s in (-1, 1):
                ax.axvline(s * k, color=COLORS["rejected"], ls="--", lw=1.2,
                           label=f"±{k:.2f}" if s > 0 else None)
            beyond = int(np.sum(np.abs(h.outside_values) > k)) + int(
                np.sum(h.counts[np.abs(h.centers) - h.width / 2 >= k]))
        out = len(h.outside_values)
        ax.set_xlabel(f"w (classes of {h.width:g})")
        ax.set_ylabel("number")
        ax.set_title(f"w, {title}: n = {h.n}" + (f", {out} outside" if out else ""),
                     fontsize=10)
        ax.legend(fontsize=7, loc="upper right")
        caps.append(f"{title}: {h.n} values, {beyond} wholly beyond the critical value")
    fig.tight_layout()
    crit = f"critical value ±{k:.2f} dashed; " if k is not None and np.isfinite(k) else ""
    cap = ("active observations (rejected ones are in the snooping table); normal curve "
           "N(0, 1) scaled to the count; " + crit + "; ".join(caps))
    return Plot(name, "Histograms of the standardized residuals w", to_png(fig), cap)
