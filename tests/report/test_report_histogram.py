"""Printer histograms: Salsig's Figure 3 counts, class edges, bar scaling, the w histogram."""

import re

import numpy as np
import pytest
from salsig import FIG2_X, FIG3_X_COUNTS

from baarda.cli import main
from baarda.io.residual_listings import read_residuals
from baarda.report.histogram import bar_scale, classes, format_histogram, histogram
from baarda.report.stats import group_statistics


def parse_counts(text: str, title: str) -> dict[float, int]:
    """Class -> count of the histogram block that starts with `title`."""
    block = text[text.index(title):].split("\n\n")[0]
    out = {}
    for line in block.splitlines():
        m = re.match(r"^\s*(\d+)(?:\s+[\d.]+)?\s+(-?\d+(?:\.\d+)?) \|(.*)$", line)
        if m:
            out[float(m.group(2))] = (int(m.group(1)), m.group(3))
    return out


def fig3_values(spread: bool) -> np.ndarray:
    """Residuals (µm) with Figure 3's class counts; spread: anywhere inside each class."""
    vals = []
    for k, n in FIG3_X_COUNTS.items():
        off = np.linspace(-0.5, 0.499, n) if spread and n > 1 else np.zeros(n)
        vals.append(k + off)
    return np.concatenate(vals)


@pytest.mark.parametrize("spread", [False, True])
def test_salsig_figure3_counts_exactly(tmp_path, capsys, spread):
    vx = fig3_values(spread)
    rows = ["point,photo,vx,vy"] + [f"p{i},ph{i % 30},{float(v)!r},0" for i, v in enumerate(vx)]
    (tmp_path / "res.csv").write_text("\n".join(rows) + "\n")
    assert main(["residuals", str(tmp_path / "res.csv"), "--line-width", "80"]) == 0
    text = capsys.readouterr().out
    counts = parse_counts(text, "IMAGE X RESIDUALS")
    assert sorted(counts) == list(range(-25, 26))  # 51 classes of 1 µm
    for k in range(-25, 26):
        n, bar = counts[k]
        assert n == FIG3_X_COUNTS.get(k, 0)
        assert bar == "*" * n  # 70 <= 80: one star per observation
    assert "none outside -25 .. 25 µm" in text.split("IMAGE Y RESIDUALS")[0]


def test_salsig_figure2_x_statistics_from_figure3(tmp_path):
    """Integer-µm residuals with Figure 3's counts give Figure 2's X row (mm, 3 decimals)."""
    vx = fig3_values(False)
    rows = ["point,photo,vx,vy"] + [f"p{i},ph,{float(v)!r},0" for i, v in enumerate(vx)]
    (tmp_path / "res.csv").write_text("\n".join(rows) + "\n")
    rs = read_residuals([tmp_path / "res.csv"])
    x = {g.name: g for g in group_statistics(rs.obs)}["image x"]
    assert x.count == 318
    assert round(x.mean / 1000, 3) + 0.0 == FIG2_X["average"]
    assert round(x.rms / 1000, 3) == FIG2_X["rms"]
    assert (x.minimum / 1000, x.maximum / 1000) == (FIG2_X["min"], FIG2_X["max"])


def test_bars_scale_when_a_class_outgrows_the_line():
    h = histogram(fig3_values(False))
    assert bar_scale(h.counts, 35) == 2.0
    text = format_histogram(h, "X", line_width=35)
    assert "each * = 2 observations" in text
    counts = parse_counts(text, "X")
    for k, (n, bar) in counts.items():
        assert len(bar) == int(round(n / 2.0)), k
    assert max(len(b) for _, b in counts.values()) == 35


def test_class_edges_and_outside():
    v = np.array([0.5, -0.5, 0.49, -0.51, 25.49, 25.5, -25.5, -25.51, 40.0, np.nan])
    h = histogram(v, np.array(list("abcdefghij"), dtype=object))
    c = dict(zip(h.centers, h.counts, strict=True))
    assert c[1] == 1 and c[0] == 2 and c[-1] == 1 and c[25] == 1 and c[-25] == 1
    assert list(h.outside_values) == [40.0, -25.51, 25.5]  # by |v|, NaN ignored
    assert list(h.outside_labels) == ["i", "h", "f"]
    assert h.n == 9
    text = format_histogram(h, "T")
    assert "outside -25 .. 25 µm: 3" in text and "40.00 µm  i" in text


def test_configurable_classes():
    h = histogram(np.array([-3.1, -0.9, 0.2, 1.1, 2.9, 3.0]), width=2.0, lo=-4, hi=4)
    assert list(h.centers) == [-4, -2, 0, 2, 4]
    assert list(h.counts) == [1, 0, 2, 2, 1]  # [-5,-3) [-3,-1) [-1,1) [1,3) [3,5)
    with pytest.raises(ValueError, match="whole number"):
        classes(0.3, -1, 1)
    with pytest.raises(ValueError, match="positive"):
        classes(0, -1, 1)


def test_w_histogram_normal_curve_and_critical_value():
    rng = np.random.default_rng(3)
    w = np.concatenate([rng.standard_normal(500), [4.0, -5.0, 9.0]])
    h = histogram(w, width=0.5, lo=-6, hi=6)
    e = h.expected_normal()
    # independent: integrate the normal density over each class numerically
    for c, ei in zip(h.centers, e, strict=True):
        x = np.linspace(c - 0.25, c + 0.25, 2001)
        dens = np.exp(-x**2 / 2) / np.sqrt(2 * np.pi)
        integral = np.sum((dens[1:] + dens[:-1]) / 2 * np.diff(x))
        assert ei == pytest.approx(h.n * integral, rel=1e-6, abs=1e-9)
    text = format_histogram(h, "W", "", expected=e, critical=3.29)
    lines = text.splitlines()
    lo = lines.index(next(s for s in lines if "critical value -3.29" in s))
    hi = lines.index(next(s for s in lines if "critical value +3.29" in s))
    # the marker lines separate the classes wholly beyond |w| = 3.29
    assert lines[lo - 1].split()[2] == "-4.0" and lines[lo + 1].split()[2] == "-3.5"
    assert lines[hi - 1].split()[2] == "3.5" and lines[hi + 1].split()[2] == "4.0"
    assert "9.00" in text.split("outside")[1]
    assert any("o" in s.split("|")[-1] for s in lines if "|" in s)


def test_classes_follow_the_residuals_spread():
    from baarda.report.histogram import fitted_classes, histogram

    rng = np.random.default_rng(3)
    small = rng.normal(0, 0.5, 36_000)  # MicMac: 36k image residuals of about 0.5 µm
    assert histogram(small, width=1.0).counts.nonzero()[0].size <= 5  # 1 µm: a few bars
    w, lo, hi = fitted_classes(small, 1.0, -25.0, 25.0)
    s = np.std(small)
    assert w == 0.1 and hi == -lo and 4 * s <= hi < 4 * s + w  # 0.1 <= s/3 < 0.2
    h = histogram(small, width=w, lo=lo, hi=hi)
    assert h.counts.nonzero()[0].size >= 30 and len(h.outside_values) < 0.001 * len(small)
    # classes that fit are kept: 3 µm in classes of 1 µm over +-25 µm
    assert fitted_classes(rng.normal(0, 3, 1000), 1.0, -25.0, 25.0) == (1.0, -25.0, 25.0)
    # a spread beyond the range: wider classes over +-4 s
    w, lo, hi = fitted_classes(rng.normal(0, 40, 1000), 1.0, -25.0, 25.0)
    assert w == 10.0 and hi >= 4 * 38
