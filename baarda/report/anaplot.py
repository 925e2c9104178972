"""The data-snooping table in the style of NRC ANAPLOT (Kratky & El-Hakim 1983, Fig. 6).

Per observation: redundancy number (RED-N), residual (PARX), its expected size sigma_v
(EXPD) and the significance w = -v / sigma_v (SIGF), with a flag.  The values are those the
adjustment wrote (observations.csv); nothing is recomputed here.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from baarda.schema import UNITS
from baarda.table_data import Column, TableData, text_lines

COLUMNS = ["kind", "frame", "point", "component", "unit", "redundancy", "residual",
           "sigma_residual", "w", "flag"]


def flag_of(df: pd.DataFrame) -> np.ndarray:
    """'REJECTED', 'FLAGGED' (active, |w| above the critical value), 'uncontrolled'
    (redundancy number too small to test) or ''."""
    rej = df["rejected"].to_numpy(bool)
    fl = df["flagged"].to_numpy(bool)
    unc = ~np.isfinite(df["w"].to_numpy(float))
    return np.where(rej, "REJECTED", np.where(fl, "FLAGGED",
                                              np.where(unc, "uncontrolled", ""))).astype(object)


def snooping_table(df: pd.DataFrame, *, sort: str = "w", min_abs_w: float | None = None,
                   top: int | None = None, always: str = "rejected+flagged",
                   units: dict[str, str] | None = None) -> pd.DataFrame:
    """Rows of the snooping table.

    sort: 'w' (largest |w| first; untested last) or 'input' (file order).
    min_abs_w: keep only |w| >= this; top: keep the first `top` rows after sorting.
    always: rows kept whatever the filters ('rejected+flagged', 'rejected' or '').
    """
    units = {**UNITS, **(units or {})}
    if sort == "w" and top is not None and len(df) > 4 * (top + 1000):
        df = df.iloc[_candidates(df, min_abs_w, top, always)]  # the same rows, fewer to sort
    t = df.copy()
    if "frame" not in t:  # the photo, or the model, of each observation
        model = t["model"] if "model" in t else ""
        t["frame"] = np.where(t["photo"].astype(str) != "", t["photo"], model)
    t["flag"] = flag_of(t)
    t["unit"] = [units.get(k, "") for k in t["kind"]]
    absw = np.abs(t["w"].to_numpy(float))
    t["_absw"] = np.where(np.isfinite(absw), absw, -1.0)
    keep_always = np.zeros(len(t), bool)
    if "rejected" in always:
        keep_always |= t["rejected"].to_numpy(bool)
    if "flagged" in always:
        keep_always |= t["flagged"].to_numpy(bool)
    if sort == "w":
        order = np.argsort(-t["_absw"].to_numpy(), kind="stable")
        t, keep_always = t.iloc[order], keep_always[order]
    elif sort != "input":
        raise ValueError(f"sort must be 'w' or 'input', not {sort!r}")
    sel = np.ones(len(t), bool)
    if min_abs_w is not None:
        sel &= t["_absw"].to_numpy() >= min_abs_w
    if top is not None:
        rank = np.cumsum(sel)
        sel &= rank <= top
    return t[sel | keep_always][COLUMNS + (["line"] if "line" in t else [])]


def _candidates(df: pd.DataFrame, min_abs_w: float | None, top: int,
                always: str) -> np.ndarray:
    """The rows (in file order) that snooping_table(sort='w') can show of a large table:
    those it keeps always and every row with |w| at least the top-th largest (ties
    included)."""
    absw = np.abs(df["w"].to_numpy(float))
    absw = np.where(np.isfinite(absw), absw, -1.0)
    sel = absw >= min_abs_w if min_abs_w is not None else np.ones(len(df), bool)
    keep = np.zeros(len(df), bool)
    if "rejected" in always:
        keep |= df["rejected"].to_numpy(bool)
    if "flagged" in always:
        keep |= df["flagged"].to_numpy(bool)
    a = absw[sel]
    if top <= 0 or not len(a):
        return np.flatnonzero(keep)
    kth = np.partition(a, len(a) - min(top, len(a)))[len(a) - min(top, len(a))]
    return np.flatnonzero(keep | (sel & (absw >= kth)))


def snooping_data(t: pd.DataFrame) -> TableData:
    """The rows of snooping_table as a TableData with ANAPLOT headings (the text report's):
    residual and sigma_v to 0.1 mm in m (.4f), to 0.01 in the other units."""
    in_m = {"m": ".4f"}
    cols = [Column("kind", text_title="KIND", text=True, width=8),
            Column("frame", text_title="FRAME", text=True, width=10),
            Column("point", text_title="POINT", text=True, width=12),
            Column("component", text_title="C", text=True, width=2),
            Column("redundancy", text_title="RED-N", fmt=".3f", width=7),
            Column("residual", text_title="PARX", fmt=".2f", unit_fmt=in_m, width=11),
            Column("sigma_residual", text_title="EXPD", fmt=".2f", unit_fmt=in_m,
                   width=10),
            Column("w", text_title="SIGF", fmt=".2f", width=8),
            Column("unit", text_title="UNIT", text=True, width=4, gap=2),
            Column("flag", text_title="FLAG", text=True, gap=1)]
    return replace(TableData.of(cols, t), unit_key="unit")


def format_snooping(t: pd.DataFrame, k_w: float | None = None) -> str:
    """The table as text, ANAPLOT headings."""
    lines = []
    if k_w is not None and np.isfinite(k_w):
        lines.append(f"critical value |w| = {k_w:.2f}; SIGF = w = -v / sigma_v")
    return "\n".join(lines + text_lines(snooping_data(t)))


def format_log(summary: dict) -> str:
    """The snooping log of summary.json (rejections and restorations in order)."""
    log = summary.get("rejection_log") or []
    if not log:
        return "no observation rejected" if summary.get("snooping_converged") is not None \
            else "no data snooping run (baarda adjust without --snoop)"
    lines = [f"{'step':>4}  {'action':<8}{'sigma0':>8}{'test':>6}{'value':>8}{'MDB':>10}  "
             "observation"]
    for s in log:
        obs = "; ".join(s.get("observations", []))
        mdb, unit = log_mdb(s)
        test, value = log_test(s)
        lines.append(f"{s.get('iteration', ''):>4}  {s.get('action', ''):<8}"
                     f"{s.get('sigma0', np.nan):8.3f}{test:>6}{value:8.2f}"
                     f"{mdb:>10} {unit:<3} {obs}"
                     + (f"\n{'':>14}{s['reason']}" if s.get("reason") else "")
                     + "".join(f"\n{'':>14}{w}" for w in identification_words(s)))
    if summary.get("snooping_incomplete"):
        lines.append(str(summary["snooping_incomplete"]))
    elif summary.get("snooping_converged") is False:
        lines.append("snooping did NOT converge (iteration limit)")
    return "\n".join(lines)


def identification_words(step: dict) -> list[str]:
    """What a log step says about separability (issue 30): the inseparable group and what
    was done with it, the components it left uncontrolled."""
    out = []
    group = step.get("identified_up_to")
    if group:
        flagged = step.get("not_separable") or []
        out.append(f"identified up to {{{', '.join(group)}}}: " + (
            f"{'; '.join(flagged)} flagged: not separable" if flagged else "all rejected"))
    out += list(step.get("uncontrolled") or [])
    return out


def log_rows(summary: dict) -> list[dict]:
    """The snooping log of summary.json as table rows (step, action, observation with the
    reason of a refused removal, test, value, MDB, sigma0 before) for the reports."""
    rows = []
    for s in summary.get("rejection_log") or []:
        mdb, unit = log_mdb(s)
        test, value = log_test(s)
        rows.append({"step": s.get("iteration"), "action": s.get("action"),
                     "observation": "; ".join(s.get("observations", []))
                     + (f" ({s['reason']})" if s.get("reason") else "")
                     + "".join(f"; {w}" for w in identification_words(s)),
                     "test": test, "value": value, "MDB": f"{mdb} {unit}",
                     "sigma0 before": s.get("sigma0", np.nan)})
    return rows


def log_test(step: dict) -> tuple[str, float]:
    """(test, value) of a log step: w or tau, or the method that rejected before snooping
    (with the component's w)."""
    stat = step.get("statistic", "w")
    return (stat if stat in ("w", "tau") else "robust"), float(step.get("value", np.nan))


def log_mdb(step: dict) -> tuple[str, str]:
    """MDB of a log step as written (summary.json: `mdb` in `mdb_unit`)."""
    mdb, unit = step.get("mdb"), step.get("mdb_unit", "")
    if mdb is None or not np.isfinite(mdb):
        return "-", ""
    return (f"{mdb:.3f}" if unit == "m" else f"{mdb:.1f}" if unit else f"{mdb:.4g}"), unit
