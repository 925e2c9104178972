"""The self-contained HTML report: plots embedded as base64 PNG, no network access.

A small script at the end writes into #render-status whether every image decoded
(naturalWidth > 0), so a headless browser can check that every plot rendered.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pandas as pd
from markupsafe import Markup

from baarda.io.result_folder import Results
from baarda.kinds import EXTERIOR_NAMES
from baarda.output.accuracy import TABLE_FORMATS
from baarda.output.verdict import failures
from baarda.report import maps
from baarda.report.anaplot import format_log, log_rows, snooping_table
from baarda.report.footprint import footprints, image_extent
from baarda.report.front import (
    accuracy,
    check_view,
    length_unit,
    metadata,
    patterns,
    quality_check,
    row_units,
)
from baarda.report.geometry import geometry_plots
from baarda.report.histogram import format_histogram
from baarda.report.html_base import (
    csv_link,
    esc,
    figure,
    html_table,
    macro,
    metadata_section,
    page,
    table,
    with_user_templates,
    worst_table,
)
from baarda.report.plots import Plot, residual_histograms, w_histogram
from baarda.report.quality_html import tables_html
from baarda.report.separability import (
    SEPARABLE_FORMATS,
    counts_line,
    least_separable,
    msb_histogram,
)
from baarda.report.stats import (
    gnss_imu_per_strip,
    group_statistics,
    group_table,
    image_group_table,
    largest_rms,
    model_group_table,
    model_groups,
    per_photo,
    per_strip,
    weakest,
)
from baarda.report.text_report import ReportOptions, image_histograms, w_hists


def _snoop_table(res: Results, opt: ReportOptions) -> str:
    every = snooping_table(res.obs, sort=opt.sort, min_abs_w=opt.min_abs_w, top=opt.top,
                           units=res.units)
    limit = min(opt.max_rows, SNOOP_ROWS)
    t, note = every, ""
    if len(every) > limit:  # the rejected rows, then the first others, in this order
        rej = (every["flag"] == "REJECTED").to_numpy()
        n_rej = min(int(rej.sum()), limit)
        keep = (rej & (np.cumsum(rej) <= n_rej)) | (~rej & (np.cumsum(~rej) <= limit - n_rej))
        t = every[keep]
        note = (f"; {len(t)} of {len(every)} such rows shown: every rejected one"
                + ("" if n_rej == int(rej.sum()) else f" (the first {n_rej} of "
                   f"{int(rej.sum())})") + " and the first others in this order")
    show = pd.DataFrame({
        "kind": t["kind"], "photo/model": t["frame"], "point": t["point"], "c": t["component"],
        "RED-N": t["redundancy"], "PARX": t["residual"], "EXPD": t["sigma_residual"],
        "SIGF (w)": t["w"], "unit": t["unit"], "flag": t["flag"]})
    cls = {"REJECTED": "rejected", "FLAGGED": "flagged", "uncontrolled": "uncontrolled"}
    return (f"<p>{len(t)} of {len(res.obs)} observations: those with the {opt.top} largest "
            f"|w| and every rejected and flagged one{esc(note)}. RED-N redundancy number, "
            f"PARX residual v, EXPD its expected size sigma_v, SIGF w = -v/sigma_v (critical |w| = "
            f"{res.k_w:.2f}).</p>"
            + table(show, {"RED-N": ".3f", "PARX": ".4g", "EXPD": ".4g", "SIGF (w)": ".2f"},
                    lambda d: [cls.get(f, "") for f in d["flag"]],
                    ("kind", "photo/model", "point", "c", "unit", "flag"),
                    'id="snooping-table"', csv=csv_link(every, "snooping_table")
                    if len(t) < len(every) else None, csv_text=f"all {len(every)} rows (CSV)",
                    download="snooping_table.csv", note="" if len(t) == len(every) else
                    "Largest |w| first;"))


def _log_table(summary: dict) -> str:
    log = summary.get("rejection_log") or []
    if not log:
        return f"<p>{esc(format_log(summary))}</p>"
    rows = log_rows(summary)
    incomplete = summary.get("snooping_incomplete") or (
        "snooping did not converge" if summary.get("snooping_converged") is False else "")
    tail = f'<p class="bad">{esc(incomplete)}</p>' if incomplete else ""
    df = pd.DataFrame(rows)
    return worst_table(df, -np.arange(len(df)), LOG_ROWS, "snooping_log", "steps",
                       {"value": ".2f", "sigma0 before": ".3f"}, which="first",
                       text_cols=("action", "test", "observation"),
                       attrs='id="snooping-log"') + tail


def _group_table(res: Results) -> str:
    return html_table(group_table(group_statistics(res.obs, res.units)), 'id="groups"')


def _image_table(t: pd.DataFrame, by: str) -> str:
    return html_table(image_group_table(t, by))


def plots(res: Results, opt: ReportOptions) -> dict[str, Plot | None]:
    """Every figure of the report (None where the data for one are missing)."""
    hists = image_histograms(res.obs, opt, fit=True)
    out: dict[str, Plot | None] = {}
    out["hist_image"] = (residual_histograms(hists, "µm") if hists[2][1].n else None)
    wh = w_hists(res.obs, opt, res.summary.get("observation_groups"))
    out["hist_w"] = w_histogram(wh, res.k_w) if wh else None
    outlines = {}
    if res.photos is not None and res.points is not None and res.cameras:
        ext = image_extent(res.obs, res.photos, res.cameras)
        zg = float(np.nanmedian(res.points["Z"])) if len(res.points) else 0.0
        outlines = footprints(res.photos, res.cameras, res.angle_unit, ext, zg)
    have_pts = res.points is not None and len(res.points)
    pts = maps.point_summary(res) if have_pts else None
    out["block_map"] = maps.block_map(res, outlines, pts=pts,
                                      max_points=opt.max_points) if have_pts else None
    out["vectors"] = maps.residual_vectors(res, opt.exaggeration, opt.vector_photos)
    stats = bool(have_pts) and bool(res.obs["redundancy"].notna().any())
    out["redundancy_map"] = maps.redundancy_map(res, pts, opt.max_points) if stats else None
    out["reliability_map"] = (maps.reliability_map(res, pts, opt.max_points) if stats
                              else None)
    out.update(geometry_plots(res))
    out["msb_mdb"] = msb_histogram(res.obs)
    return out


def _weakest_tables(res: Results, opt: ReportOptions) -> str:
    """The observations with the smallest r and the largest MDB (the largest |w| are in the
    snooping table)."""
    if not res.obs["redundancy"].notna().any():
        return ""
    out = ""
    lname, lf = length = length_unit(res)
    for title, t in weakest(res.obs, opt.worst, res.units).items():
        unit, f = row_units(res, t["kind"], length)
        show = pd.DataFrame({"kind": t["kind"], "photo/model": t["frame"], "point": t["point"],
                             "c": t["component"], "r": t["redundancy"], "w": t["w"],
                             "unit": unit, "MDB": t["mdb"].to_numpy(float) * f,
                             f"external {lname}": t["external_max"].to_numpy(float) * lf})
        out += f'<div class="wrap"><h3>{esc(title)}</h3>' + table(
            show, {"r": ".3f", "w": ".2f", "MDB": ".4g", f"external {lname}": ".4g"},
            text_cols=("kind", "photo/model", "point", "c", "unit")) + "</div>"
    return f'<div class="grid2">{out}</div>'  # side by side where the page is wide


def _separability(res: Results, opt: ReportOptions) -> str:
    """The least separable observations (issue 30; the histogram of MSB/MDB stands beside
    the reliability maps)."""
    t = least_separable(res.obs, opt.worst)
    if not len(t):
        return ""
    t = t.rename(columns={"frame": "photo/model"})
    return (f"<h3>Least separable</h3><p>{esc(counts_line(res.obs))}; MDB and MSB in the "
            "units of the kind</p>" + table(
                t, SEPARABLE_FORMATS,
                text_cols=("kind", "photo/model", "point", "c", "partner")))


def _verdict_class(line: str) -> str:
    """The colour of one global-test line by its own verdict (a B-method line that is not
    the verdict: neutral)."""
    if "(not the verdict" in line:
        return "note"
    return "bad" if "-> REJECTED" in line else "ok" if "-> accepted" in line else ""


def _variance_components(summary: dict) -> pd.DataFrame | None:
    """The variance components of every adjustment (summary.json), one row per group."""
    parts = summary.get("adjustments") or {}
    rows = [dict(c, adjustment=name) for name, p in parts.items() if isinstance(p, dict)
            for c in p.get("variance_components", [])]
    if not rows:
        rows = [dict(c, adjustment="") for c in summary.get("variance_components", [])]
    if not rows:
        return None
    cols = ["adjustment", "group", "n", "redundancy", "sigma_apriori", "unit", "factor",
            "factor_std", "p_value", "rejected", "estimated_variance_factor", "sigma_estimated",
            "pooled_into"]
    t = pd.DataFrame(rows).reindex(columns=cols)
    t["pooled_into"] = t["pooled_into"].fillna("")
    t["unit"] = t["unit"].fillna("")
    return t if len(parts) > 1 else t.drop(columns="adjustment")


SNOOP_ROWS = 40  # rows of the snooping table in the HTML (the rejected first, the whole as CSV)
LOG_ROWS = 20  # steps of the snooping log in the HTML (the first; the whole log as CSV)
HTML_ROWS = 20  # rows of a long table shown in the HTML (the worst; the whole as CSV)


def _observations_link(res: Results, out: Path | None) -> tuple[str, str]:
    """A link to the result folder's observation table, relative to the report's place."""
    name = ("observations.csv" if (res.folder / "observations.csv").is_file()
            else "observations.parquet")
    target = res.folder / name
    if out is None:
        return target.resolve().as_uri(), name
    return Path(os.path.relpath(target.resolve(), out.resolve().parent)).as_posix(), name


def front_sections(res: Results, opt: ReportOptions, rest: list[dict]) -> list[dict]:
    """The sections both reports open with: the quality check (its rows linked to the
    sections of `rest`, the page's other sections), the accuracy statement on the check
    points, the rejection patterns and the metadata with the sign-off block."""
    ids = {"check", "accuracy", "patterns", "metadata"} | {s["id"] for s in rest} | {
        i for s in rest for i in re.findall(r'id="([^"]+)"', str(s["body"]))}
    acc = accuracy(res)
    notes = "".join(f'<p class="bad">{esc(w)}</p>' if "No check points" in w or
                    "Only" in w or "none was applied" in w else f"<p>{esc(w)}</p>"
                    for w in acc.warnings)
    misses = acc.misses if acc.misses is not None else pd.DataFrame()
    pts = ("<h3>Check points (adjusted - given), largest miss first</h3>"
           + worst_table(misses, misses["d"], HTML_ROWS, "check_points",
                         "check points", {c: ".3f" for c in ("dX", "dY", "dZ", "d")}
                         | {"sigma": ".3f", "ratio": ".1f"}, text_cols=("point",),
                         attrs='id="check-points"')) if acc.n else ""
    if acc.stated:  # the figures beside the check points, the standard's sentences below
        figs = (table(acc.table.drop(columns="n"), TABLE_FORMATS, text_cols=("axis",),
                      attrs='id="accuracy-table"')
                + table(pd.DataFrame(acc.statements, columns=["", "Edition 2 (2023)"]),
                        text_cols=("", "Edition 2 (2023)"), attrs='id="accuracy-figures"'))
        body = (f'<div class="grid2"><div>{figs}</div><div>{pts}</div></div>'
                f'<p id="accuracy-statement">{esc(acc.statement_text())}</p>' + notes)
    else:
        body = notes + pts
    groups, advice = patterns(res)
    pat = ""
    if advice:
        pat += "<h3>Advice</h3>" + table(pd.DataFrame(
            [{"what": a.what, "remedy": a.remedy, "where": a.where} for a in advice]),
            text_cols=("what", "remedy", "where"), attrs='id="advice" class="advice"')
    if len(groups):
        pat += ("<h3>Rejections by kind, component and sign of the residual</h3>"
                + table(groups, text_cols=("kind", "component", "residual sign",
                                           "most on photo", "strips"),
                        attrs='id="rejection-groups"'))
    if not pat:
        ids.discard("patterns")
    check = macro("check")(check_view(quality_check(res), ids))
    out = [{"id": "check", "nav": "Quality check", "title": "Quality check",
            "body": Markup(check)},
           {"id": "accuracy", "nav": "Accuracy", "title": "Accuracy on check points",
            "body": Markup(body)}]
    if pat:
        out.append({"id": "patterns", "nav": "Patterns", "title": "Rejection patterns",
                    "body": Markup(pat)})
    from baarda.report.facts import project_facts

    facts = project_facts(res)
    block = ("<h3>The block</h3>" + macro("meta")(facts) + "<h3>Run, input and settings</h3>"
             if facts else "")
    out.append(metadata_section(metadata(res), "Run, input and settings", before=block,
                                after=macro("signoff")()))
    return out


@with_user_templates
def html_report(res: Results, opt: ReportOptions | None = None,
                calibration: list | None = None, out: Path | None = None,
                templates: str | Path | None = None) -> str:
    """The whole report as one HTML string; `calibration`: the quality report's camera,
    control and GNSS parts (quality_report.calibration_parts) when they are at hand; `out`:
    where it will be written (links to the result folder are relative to it);
    `templates`: a folder of templates that override baarda's own."""
    opt = opt or ReportOptions()
    figs = plots(res, opt)
    passed = res.global_test_passed
    summary = ('<div class="grid2">' + "".join(
        f"<div><h3>{esc(s.title)}</h3><pre>{esc(chr(10).join(s.lines))}</pre></div>"
        for s in res.sections) + "</div>") if res.sections else \
        "<p>summary.json has no sections</p>"
    sec = [("summary", "Project summary",
            f'<p class="facts">source {esc(res.summary.get("source", "?"))}</p>' + summary
            + "".join(f"<p>note: {esc(n)}</p>" for n in res.notes))]
    gt_lines = res.global_test_lines() or ["global test: not available"]
    sec.append(("global", "Global test", '<p id="global-test">' + "<br>".join(
        f'<span class="{_verdict_class(x)}">{esc(x)}</span>' for x in gt_lines) + "</p>"
        + "<p>The test at the conventional level (first line) gives the verdict; the "
        "B-method's test is coupled to the w-tests and shown for that reason.</p>"))
    cal = tables_html(res, calibration)
    if cal:
        sec.append(("calibration", "Camera calibration, control and GNSS", cal))
    vc = _variance_components(res.summary)
    if vc is not None:
        sec.append(("vce", "Variance components per group", table(
            vc, {"redundancy": ".2f", "sigma_apriori": ".4g", "factor": ".4f",
                 "factor_std": ".4f", "p_value": ".3g", "estimated_variance_factor": ".4f",
                 "sigma_estimated": ".4g"},
            text_cols=("adjustment", "group", "unit", "pooled_into"),
            attrs='id="variance-components"')
            + "<p>Foerstner's estimate sigma_k^2 = v'Pv / r_k per group (factor: a ratio of "
              "variances; the sigmas scale by its square root), its test against one "
              "(5 %); a group with r_k &lt; 5 in the first estimate is not estimated by itself "
              "(control axes are then estimated together, pooled_into) and keeps its a-priori "
              "sigma throughout; sigmas in the units of observations.csv (unit); the tests "
              "and snooping used the estimated sigmas.</p>"))
    sec.append(("log", "Data snooping log", _log_table(res.summary)))
    body = _group_table(res)
    if res.photos is not None and (res.obs["kind"] == "image").any():
        body += "<h3>Per strip</h3>" + _image_table(per_strip(res.obs, res.strip_of()), "strip")
        every = per_photo(res.obs)
        t, note = largest_rms(every, min(opt.max_rows, HTML_ROWS), "photos")
        link = (f' <a download="per_photo.csv" href="{csv_link(every, "per_photo")}">all '
                f"{len(every)} photos (CSV)</a>" if len(t) < len(every) else "")
        body += (f"<h3>Per photo{esc(note)}</h3><p class=more>largest RMS x+y first{link}</p>"
                 + _image_table(t.iloc[np.argsort(-t["rms_xy"].fillna(-1.0).to_numpy(),
                                                  kind="stable")], "photo"))
    if res.photos is not None and res.obs["kind"].isin(EXTERIOR_NAMES).any():
        t = gnss_imu_per_strip(res.obs, res.strip_of())
        body += "<h3>GNSS and IMU per strip</h3>" + table(
            t, {c: ".4f" for c in t.columns if c.startswith(("mean", "RMS"))} | {
                "max |w|": ".2f"}, text_cols=("kind", "strip"))
    if (res.obs["kind"] == "model").any():
        body += "<h3>Per model</h3>" + html_table(model_group_table(model_groups(res.obs)))
    sec.append(("groups", "Group statistics (rejected observations left out; image and model "
                "µm, control m)", body))
    geo = "".join(str(figure(figs.get(k))) for k in ("centres", "ground_vectors",
                                                     "overlap", "rays", "image_grid"))
    if geo:
        sec.append(("geometry", "Geometry", f'<div class="grid3">{geo}</div>'))
    texts = "".join(
        f"<details><summary>text histogram: image {esc(n)}</summary><pre>"
        f"{esc(format_histogram(h, f'IMAGE {n.upper()} RESIDUALS', 'µm', opt.line_width))}"
        "</pre></details>" for n, h in image_histograms(res.obs, opt, fit=True))
    sec.append(("histograms", "Histograms", figure(figs["hist_image"]) + texts
                + figure(figs["hist_w"])))
    sec.append(("maps", "Block map", figure(figs["block_map"])))
    sec.append(("vectors", "Image residual vectors", figure(figs["vectors"])
                or "<p>no image coordinates in the results</p>"))
    sec.append(("reliability", "Redundancy and reliability",
                f'<div class="grid3">{figure(figs["redundancy_map"])}'
                f'{figure(figs["reliability_map"])}{figure(figs.get("msb_mdb"))}</div>'
                + _weakest_tables(res, opt) + _separability(res, opt)
                if figs["redundancy_map"] else
                "<p>no redundancy numbers in the results (adjusted without statistics)</p>"))
    href, name = _observations_link(res, out)
    sec.append(("table", "Snooping table (ANAPLOT)", _snoop_table(res, opt)
                + f'<p class=more>Every observation with r, w, MDB and the external '
                  f'reliability: <a href="{esc(href)}">{esc(name)}</a> of the result '
                  "folder.</p>"))
    sections = [{"id": k, "nav": t.split(" (")[0], "title": t, "body": Markup(b)}
                for k, t, b in sec]
    sections = front_sections(res, opt, sections) + sections
    subtitle = (f"{res.folder.name} · " + (f"run {res.run} · " if res.run else "")
                + f"global test {'n/a' if passed is None else 'accepted' if passed else 'REJECTED'}"
                f" · {res.summary.get('n_rejected', 0)} rejected, "
                f"{res.summary.get('n_flagged', 0)} flagged")
    return page("adjustment", templates, title=res.title, subtitle=subtitle,
                banners=failures(res.summary), sections=sections, footer=footer(res))


def footer(res: Results) -> str:
    return (f"baarda {res.manifest.get('baarda', '')} · run {res.run or 'not recorded'} · "
            f"{res.manifest.get('finished', '')}")


def write_html(path: str | Path, text: str) -> None:
    from baarda.output.atomic import write_text

    write_text(path, text)
