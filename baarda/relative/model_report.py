"""The ANAPLOT display of one model as text (Kratky and El-Hakim 1983, Figure 6).

First the parallaxes and tie discrepancies of every point, then for every measurement its
redundancy number (RED-N), the computed parallax (PARX = observed - adjusted, µm), the
statistically expected one (EXPD = sigma sqrt(r), µm) and the error significance (SIGF = |w|,
or |tau|), the critical error transfers and the point to remeasure.
"""

from __future__ import annotations

import numpy as np

from baarda.relative.model_qc import ModelQC
from baarda.relative.orientation import PARAMETER_NAMES

GON = 200.0 / np.pi


def _f(x: float, fmt: str) -> str:
    return "-" if not np.isfinite(x) else format(x, fmt)


def orientation_lines(qc: ModelQC) -> list[str]:
    o = qc.orientation
    q = qc.quality
    u = len(o.setup.unknowns)
    kind = "scaled orientation (scale transfer)" if o.setup.scale else "relative orientation"
    lines = [f"MODEL {o.name}: {kind}, {len(o.points)} points, {len(o.setup.tie_index)} tie "
             f"points, {u} unknowns, redundancy {q.redundancy}, {o.iterations} iterations"]
    g = o.params
    vals = [f"b_x {o.base:.4f}"]
    for k in o.setup.unknowns:
        name = PARAMETER_NAMES[k]
        vals.append(f"{name} {g[k] * GON:.5f} gon" if k >= 3 else f"{name} {g[k]:.6f}")
    lines.append("  " + ", ".join(vals))
    if q.redundancy > 0:
        gt = q.global_test
        verdict = "" if gt is None else (" (global test: accepted)" if gt.passed
                                         else " (global test: rejected)")
        lines.append(f"  sigma0 a posteriori {q.sigma0_hat:.3f} (a priori 1; sigma x'' "
                     f"{o.setup.sigma_x:g} µm, y'' {o.sigma[0]:.4g} µm){verdict}")
    return lines


def parallax_lines(qc: ModelQC) -> list[str]:
    o = qc.orientation
    tie_of = {int(p): k for k, p in enumerate(o.setup.tie_index)}
    lines = ["  POINT      Y-PARX   X-PARX      dX      dY      dZ   (µm; tie discrepancies "
             "new - preceding model)"]
    for i, pid in enumerate(o.points):
        row = f"  {pid:<8} {o.y_parallax[i]:8.1f}"
        k = tie_of.get(i)
        if k is not None:
            d = o.tie_discrepancy[k]
            row += f" {o.x_parallax[k]:8.1f} {d[0]:7.1f} {d[1]:7.1f} {d[2]:7.1f}"
        lines.append(row)
    return lines


def table_lines(qc: ModelQC) -> list[str]:
    q = qc.quality
    sig = qc.significance
    name = "SIGF" if qc.statistic == "w" else "TAU"
    lines = [f"  POINT    OBS   RED-N     PARX     EXPD    {name}",]
    for i in range(len(q.residual)):
        o = qc.orientation
        mark = ""
        if qc.flagged[i]:
            mark = " *"
        if qc.remeasure_index == i:
            mark = " * <- remeasure"
        lines.append(f"  {o.points[o.obs_point[i]]:<8} {o.obs_component[i]:>3} "
                     f"{q.redundancy_number[i]:7.2f} {-q.residual[i]:8.1f} "
                     f"{_f(qc.expected[i], '8.1f')} {_f(abs(sig[i]), '7.2f')}{mark}")
    lines.append(f"  critical value {qc.critical_value:.2f} (alpha0 {q.alpha0:g}, beta0 "
                 f"{q.beta0:g}); sum of RED-N {q.sum_redundancy_numbers:.2f}")
    return lines


def variance_lines(qc: ModelQC) -> list[str]:
    """The variance components of the strip so far (OnlineSession(vce=True)), and the
    q_yy / q_xx and q_tie this model was oriented and tested with."""
    if not qc.variance_components:
        return []
    lines = ["  variance components over the strip so far (this model and the accepted "
             "ones; Foerstner):"]
    for c in qc.variance_components:
        lines.append("    " + c.summary(1.0, "µm"))
    if qc.variance_left_out:
        lines.append("    left out of the estimate (significant against their group estimated "
                     "without them): " + ", ".join(qc.variance_left_out))
    s = qc.orientation.setup
    lines.append(f"  oriented and tested with q_yy/q_xx {s.qyy:.4g}, q_tie {s.qtie:.4g} "
                 f"(sigma y'' {np.sqrt(s.qyy) * s.sigma_x:.4g} µm, x'' at tie points "
                 f"{np.sqrt(s.qtie) * s.sigma_x:.4g} µm)")
    return lines


def transfer_lines(qc: ModelQC, limit: int = 12) -> list[str]:
    if not qc.transfers:
        return ["  no critical error transfers"]
    items = [f"{qc.label(t.source)}->{qc.label(t.target)} {t.value:+.2f}/{t.diagonal:.2f}"
             for t in qc.transfers[:limit]]
    more = len(qc.transfers) - limit
    tail = f" (+{more} more)" if more > 0 else ""
    return ["  critical transfers (error in -> shows at, QvvP off-diagonal/diagonal): "
            + ", ".join(items) + tail]


def verdict_line(qc: ModelQC) -> str:
    if qc.quality.redundancy <= 0:
        return "  no redundancy: nothing can be tested"
    if qc.remeasure is None:
        return "  no significant error: accept the model"
    i = qc.remeasure_index
    return (f"  REMEASURE POINT {qc.remeasure} ({qc.orientation.obs_component[i]}'': "
            f"{'SIGF' if qc.statistic == 'w' else 'TAU'} {abs(qc.significance[i]):.2f} > "
            f"{qc.critical_value:.2f})")


def model_report(qc: ModelQC) -> str:
    """The whole display of one model."""
    lines = (orientation_lines(qc) + parallax_lines(qc) + table_lines(qc) + variance_lines(qc)
             + transfer_lines(qc) + [verdict_line(qc)])
    return "\n".join(lines)
