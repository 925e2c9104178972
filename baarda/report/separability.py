"""The report's view of separability (issue 30): the least separable tested observations
(largest rho_max, with the partner and MSB/MDB) as a table, and the histogram of MSB/MDB;
from observations.csv's rho_max, rho_partner, msb (docs/quality.md)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from baarda.report.plots import Plot, plt, to_png
from baarda.table_data import Column, TableData, text_lines

RHO_INSEPARABLE = 0.99  # as quality/separability.py (the report reads files, not the model)


def least_separable(obs: pd.DataFrame, n: int) -> pd.DataFrame:
    """The n active tested observations with the largest rho_max (ties: the largest MSB/MDB
    first): kind, frame, point, component, rho_max, partner, MDB, MSB, MSB/MDB."""
    if "rho_max" not in obs or not obs["rho_max"].notna().any():
        return pd.DataFrame()
    ok = ~obs["rejected"].to_numpy(bool) & np.isfinite(obs["rho_max"].to_numpy(float))
    d = obs.loc[ok]
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = d["msb"].to_numpy(float) / d["mdb"].to_numpy(float)
    t = pd.DataFrame({"kind": d["kind"].to_numpy(), "frame": d["frame"].to_numpy(),
                      "point": d["point"].to_numpy(), "c": d["component"].to_numpy(),
                      "rho_max": d["rho_max"].to_numpy(float),
                      "partner": d["rho_partner"].to_numpy(), "MDB": d["mdb"].to_numpy(float),
                      "MSB": d["msb"].to_numpy(float), "MSB/MDB": ratio})
    return t.sort_values(["rho_max", "MSB/MDB"], ascending=False, kind="stable").head(n)


def counts_line(obs: pd.DataFrame) -> str:
    """'k of n tested observations not separable (rho_max >= 0.99)' ("" without rho_max)."""
    if "rho_max" not in obs or not obs["rho_max"].notna().any():
        return ""
    rho = obs["rho_max"].to_numpy(float)
    ok = ~obs["rejected"].to_numpy(bool) & np.isfinite(rho)
    k = int(np.sum(rho[ok] >= RHO_INSEPARABLE))
    return (f"{k} of {int(ok.sum())} tested observations are detectable but not separable "
            f"(rho_max >= {RHO_INSEPARABLE}: their partner's w-test moves with theirs)")


# the number formats of least_separable's columns (the text and the HTML report)
SEPARABLE_FORMATS = {"rho_max": ".4f", "MSB/MDB": ".2f", "MDB": ".4g", "MSB": ".4g"}


def least_separable_data(t: pd.DataFrame) -> TableData:
    """The rows of least_separable as a TableData (the text report's layout); "-" where a
    number is not finite (an MSB of a pair that is one test)."""
    f = SEPARABLE_FORMATS
    return TableData.of([
        Column("kind", text=True, width=8), Column("frame", "photo/model", text=True, width=12),
        Column("point", text=True, width=10), Column("c", text=True, width=3),
        Column("rho_max", fmt=f["rho_max"], width=9),
        Column("MSB/MDB", fmt=f["MSB/MDB"], width=9),
        Column("MDB", fmt=f["MDB"], width=11), Column("MSB", fmt=f["MSB"], width=11),
        Column("partner", text=True, gap=2)], t)


def format_least_separable(t: pd.DataFrame) -> str:
    return "\n".join(text_lines(least_separable_data(t)))


def msb_histogram(obs: pd.DataFrame) -> Plot | None:
    """Histogram of MSB/MDB of the active tested observations (those not separable at
    all, MSB infinite, counted apart); None without MSB."""
    if "msb" not in obs or not obs["msb"].notna().any():
        return None
    ok = ~obs["rejected"].to_numpy(bool) & np.isfinite(obs["rho_max"].to_numpy(float))
    with np.errstate(invalid="ignore", divide="ignore"):
        r = (obs["msb"].to_numpy(float) / obs["mdb"].to_numpy(float))[ok]
    finite = r[np.isfinite(r)]
    if not len(finite):
        return None
    fig, ax = plt.subplots(figsize=(7.0, 3.2))
    hi = float(min(np.quantile(finite, 0.99) * 1.05, 10.0))
    ax.hist(np.clip(finite, 1.0, hi), bins=40, range=(1.0, hi), color="#4c72b0")
    inf = int(np.sum(~np.isfinite(r)))
    ax.set_xlabel("MSB / MDB (1: as separable as detectable)" + (
        f"; {inf} not separable at any size" if inf else ""))
    ax.set_ylabel("observations")
    ax.grid(alpha=0.3)
    return Plot("msb_mdb", "MSB / MDB", to_png(fig),
                "Minimal separable bias over minimal detectable bias of every tested "
                "observation: how much larger an error must be to be pinned on this "
                "observation in one step of snooping than to be detected at all")
