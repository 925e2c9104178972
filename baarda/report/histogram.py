"""Printer-character histograms of residuals (Salsig 1989, VAN) and of standardized residuals.

Classes are centred on multiples of the class width: the class labelled c holds the values
in [c - width/2, c + width/2), i.e. each residual is rounded to the nearest class centre, so
a listing in whole micrometres falls exactly into its own class.  Values outside the first
and last class are listed separately.  The count is printed at the left edge; each `*` is
one observation unless the longest bar would exceed the line width, then all bars are
scaled proportionally.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr


@dataclass
class Histogram:
    centers: np.ndarray  # (k,) class centres
    counts: np.ndarray  # (k,) int
    width: float
    outside_values: np.ndarray  # values beyond the range, sorted by |value| descending
    outside_labels: np.ndarray

    @property
    def n(self) -> int:
        return int(self.counts.sum()) + len(self.outside_values)

    def expected_normal(self, sigma: float = 1.0) -> np.ndarray:
        """Counts expected per class for n values from N(0, sigma^2)."""
        lo = (self.centers - self.width / 2) / sigma
        hi = (self.centers + self.width / 2) / sigma
        return self.n * (ndtr(hi) - ndtr(lo))


#: the most classes of a histogram (a text histogram prints a line for each)
MAX_CLASSES = 10_000


def classes(width: float, lo: float, hi: float) -> np.ndarray:
    """Class centres lo, lo + width, ..., hi (the range must hold a whole number of classes)."""
    if not width > 0:
        raise ValueError(f"class width must be positive, not {width}")
    if not hi > lo:
        raise ValueError(f"histogram range: upper end {hi} must exceed lower end {lo}")
    k = (hi - lo) / width
    if not k <= MAX_CLASSES:
        raise ValueError(f"the range {lo} .. {hi} in classes of {width} would be {k:.3g} "
                         f"classes: at most {MAX_CLASSES}")
    if abs(k - round(k)) > 1e-9 * max(1.0, abs(k)):
        raise ValueError(f"the range {lo} .. {hi} is not a whole number of classes of {width}")
    return lo + width * np.arange(int(round(k)) + 1)


def fitted_classes(values: np.ndarray, width: float, lo: float, hi: float
                   ) -> tuple[float, float, float]:
    """(width, lo, hi) of classes that fit the values' spread s (standard deviation): the
    given ones while s >= 2 classes and +-4 s lies within lo .. hi, else classes of a
    round width (1, 2 or 5 x 10^k) near s / 3 over +-4 s (about 24 classes)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    s = float(np.std(v)) if len(v) > 1 else 0.0
    if not s > 0 or (s >= 2 * width and -4 * s >= lo and 4 * s <= hi):
        return width, lo, hi
    e = 10.0 ** np.floor(np.log10(s / 3))
    w = float(max(m * e for m in (1, 2, 5) if m * e <= s / 3))
    k = int(np.ceil(4 * s / w))
    return w, -k * w, k * w


def histogram(values: np.ndarray, labels: np.ndarray | None = None, width: float = 1.0,
              lo: float = -25.0, hi: float = 25.0) -> Histogram:
    """Count `values` into classes of `width` centred on lo .. hi; NaN values are ignored."""
    v = np.asarray(values, float)
    lab = (labels if hasattr(labels, "rows") else np.asarray(labels, dtype=object)
           if labels is not None else np.array([str(i + 1) for i in range(len(v))],
                                               dtype=object))
    assert lab is not None
    keep = np.isfinite(v)
    v, lab = v[keep], lab[keep]
    centers = classes(width, lo, hi)
    idx = np.floor((v - lo) / width + 0.5).astype(np.int64)
    inside = (idx >= 0) & (idx < len(centers))
    counts = np.bincount(idx[inside], minlength=len(centers))
    order = np.argsort(-np.abs(v[~inside]), kind="stable")
    return Histogram(centers, counts, float(width), v[~inside][order],
                     np.asarray(lab[~inside][order], dtype=object))


def bar_scale(counts: np.ndarray, line_width: int) -> float:
    """Observations per `*`: 1, unless the longest bar would not fit in `line_width`."""
    top = float(np.max(counts, initial=0))
    return max(1.0, top / max(line_width, 1))


def _decimals(*xs: float) -> int:
    """Decimals needed to print every class centre exactly (at most 4)."""
    for d in range(5):
        if all(abs(x * 10**d - round(x * 10**d)) < 1e-6 for x in xs):
            return d
    return 4


def format_histogram(h: Histogram, title: str, unit: str = "µm", line_width: int = 60,
                     expected: np.ndarray | None = None, critical: float | None = None,
                     max_outside: int = 50) -> str:
    """The histogram as printer characters.

    `expected`: counts of the normal curve per class, drawn as `o` and listed; `critical`:
    the critical value; a marker line separates the classes lying wholly beyond it.
    """
    scale = bar_scale(np.maximum(h.counts, 0 if expected is None else expected), line_width)
    dec = _decimals(h.width, float(h.centers[0]))
    u = f" {unit}" if unit else ""
    head = f"{title}  (classes of {h.width:g}{u}; n = {h.n}"
    head += ")" if scale == 1 else f"; each * = {scale:.3g} observations)"
    lines = [head]
    if expected is not None:
        lines.append("o: normal distribution N(0, 1), expected count")
    lines.append(f"{'NUMBER':>7}" + (f"{'NORMAL':>8}" if expected is not None else "")
                 + f"{'MAGNITUDE':>11}")
    pad = " " * (18 if expected is not None else 10)
    k = abs(critical) if critical is not None and np.isfinite(critical) else None
    lo_edge = h.centers - h.width / 2
    hi_edge = h.centers + h.width / 2
    for i, (c, n) in enumerate(zip(h.centers, h.counts, strict=True)):
        if k is not None and lo_edge[i] >= k and (i == 0 or lo_edge[i - 1] < k):
            lines.append(f"{pad}---- critical value +{k:.2f} ----")
        bar = ["*"] * int(round(n / scale))
        exp = ""
        if expected is not None:
            e = int(round(expected[i] / scale))
            if e > 0:
                bar += [" "] * max(0, e - len(bar))
                bar[e - 1] = "o"
            exp = f"{expected[i]:8.1f}"
        lines.append(f"{int(n):>7}{exp}{c:>11.{dec}f} |{''.join(bar)}".rstrip())
        if k is not None and hi_edge[i] <= -k and (i + 1 == len(h.centers)
                                                   or hi_edge[i + 1] > -k):
            lines.append(f"{pad}---- critical value -{k:.2f} ----")
    rng = f"{h.centers[0]:.{dec}f} .. {h.centers[-1]:.{dec}f}{u}"
    if len(h.outside_values):
        lines.append(f"outside {rng}: {len(h.outside_values)}")
        for v, lab in list(zip(h.outside_values, h.outside_labels, strict=True))[:max_outside]:
            lines.append(f"  {v:>10.2f}{u}  {lab}")
        if len(h.outside_values) > max_outside:
            lines.append(f"  ... and {len(h.outside_values) - max_outside} more")
    else:
        lines.append(f"none outside {rng}")
    return "\n".join(lines)
