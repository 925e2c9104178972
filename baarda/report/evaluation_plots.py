"""The report of a detection-power study (`baarda evaluate`): the power curves drawn from
the files the study wrote (power.csv: the located share per size class with its 95 %
interval, b_method_power.csv: the B-method's curve of the w-test; docs/evaluation.md), as
PNG and a self-contained HTML page.  Nothing is recomputed here."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
from markupsafe import Markup

from baarda.report.plots import plt, to_png

FIRST = "first adjustment: |w| > k"


def power_curves(summary: dict, power: pd.DataFrame, curve: pd.DataFrame) -> bytes | None:
    """PNG of the located share against |size| in MDB per series (95 % intervals), with
    the B-method's curve; the legend beside the axes; None without blunders."""
    if not len(power):
        return None
    fig, ax = plt.subplots(figsize=(8.5, 4.2))
    ax.plot(curve["size_mdb"], curve["power"], color="black", lw=1,
            label=f"B-method, w-test (alpha0 {summary.get('alpha0', float('nan')):g})")
    for n, (name, part) in enumerate(power.groupby("series", sort=False)):
        width = (part["hi"] - part["lo"]).to_numpy(float)
        mid = 0.5 * (part["lo"] + part["hi"]).to_numpy(float) + 0.01 * n * width
        rate = part["rate"].to_numpy(float)
        err = np.vstack([rate - part["ci_lo"].to_numpy(float),
                         part["ci_hi"].to_numpy(float) - rate])
        ax.errorbar(mid, rate, yerr=err, marker="o", ms=4, capsize=2, lw=1,
                    ls="--" if name == FIRST else ":" if "identified" in name else "-",
                    label=name)
    ax.set_xlabel("blunder size in units of the observation's own MDB")
    ax.set_ylabel("share detected / identified")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return to_png(fig)


def read_study(file: Callable[[str], Path]) -> tuple[dict, pd.DataFrame, pd.DataFrame]:
    """summary.json, power.csv and b_method_power.csv of a study (`file(name)`: the path)."""
    summary = json.loads(Path(file("summary.json")).read_text(encoding="utf-8"))
    power = pd.read_csv(file("power.csv"), keep_default_na=False, na_values=[""])
    curve = pd.read_csv(file("b_method_power.csv"))
    return summary, power, curve


def study_html(summary: dict, power: pd.DataFrame, png: bytes | None,
               templates: str | Path | None = None, run=None) -> str:
    """A self-contained HTML page in the reports' look: the summary lines, the power
    curves (legend beside them) and the counts per size class, strategies side by side;
    `run`: the run being written (version, date, id and command, as every report)."""
    from baarda.report.html_base import user_templates

    with user_templates(templates):
        return _study_html(summary, power, png, templates, run)


def _study_html(summary: dict, power: pd.DataFrame, png: bytes | None,
                templates: str | Path | None, run) -> str:
    from baarda.report.html_base import (
        esc,
        figure,
        metadata_section,
        page,
        run_metadata,
        table,
    )
    from baarda.report.plots import Plot

    lines = "".join(f"<li>{esc(s)}</li>" for s in summary.get("summary", []))
    sections = [{"id": "summary", "nav": "Summary", "title": "Summary",
                 "body": Markup(f"<ul>{lines}</ul>")}]
    if png is not None:
        sections.append({"id": "curves", "nav": "Power curves", "title": "Power curves",
                         "body": Markup(figure(Plot(
                             "power", "power curves", png, "Share of the planted blunders "
                             "located against their size in units of the observation's own "
                             "MDB, with 95 % Clopper-Pearson intervals; black: the "
                             "B-method's power of the w-test.")))})
        wide = power.assign(cls=[f"{a:.2f} .. {b:.2f}" for a, b in zip(
            power["lo"], power["hi"], strict=True)], cell=[
            f"{k}/{n} = {r:.2f}" for k, n, r in zip(power["located"], power["n"],
                                                   power["rate"], strict=True)])
        wide = wide.pivot_table(index="cls", columns="series", values="cell",
                                aggfunc="first", sort=False).reset_index().rename(
            columns={"cls": "size class (MDB)"}).fillna("")
        sections.append({"id": "counts", "nav": "Counts per class",
                         "title": "Located per size class (strategies side by side)",
                         "body": Markup(table(wide, text_cols=tuple(wide.columns),
                                              attrs='id="power-counts"'))})
    else:
        sections.append({"id": "curves", "nav": "Power curves", "title": "Power curves",
                         "body": Markup("<p>no blunders planted</p>")})
    o = summary.get("plan") or {}
    sub = (f"{summary.get('trials')} trials of {o.get('strips', '?')} x "
           f"{o.get('photos_per_strip', '?')} photos, alpha0 {summary.get('alpha0')}, beta0 "
           f"{summary.get('beta0')}")
    meta = run_metadata(run)
    if run is None and summary.get("run"):
        meta[2] = ("run", str(summary["run"]))
    sections.append(metadata_section(meta))
    return page("evaluation", templates, title="simulated blocks", subtitle=sub,
                sections=sections,
                footer=f"baarda {meta[0][1]} · evaluate · run {meta[2][1]} · {meta[1][1]}")
