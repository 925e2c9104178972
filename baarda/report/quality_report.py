"""The quality report that drone-survey clients and regulators ask for (issue 20,
docs/odm.md): camera calibration with standard deviations and correlations, the GCP and
check-point residuals with RMS per axis, GNSS residuals, reprojection errors per image in
pixels, the redundancy number, w and MDB of every observation, the snooping log and the
external reliability of the ground points.

`quality_content(res)` gives the content once, as `Part`s (a heading, text, a table or a
figure); report/quality_html.py lays them out as HTML sections, report/quality_pdf.py as
PDF pages.
Everything is read from the result folder (io/result_folder.py); nothing is recomputed
but RMS values and per-group summaries of the observations table.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from baarda.io.result_folder import Results
from baarda.kinds import GNSS, IMU
from baarda.output.verdict import failures  # noqa: E402
from baarda.report.anaplot import log_rows  # noqa: E402
from baarda.report.front import (  # noqa: E402,F401  (pixel_um re-exported)
    length_unit,
    pixel_um,
    row_units,
    run_notes,
)
from baarda.report.stats import pair_xy  # noqa: E402

WORST = 25  # observations with the largest |w| shown (the whole table: observations.csv)


@dataclass
class Part:
    kind: str  # "alert" (why the run is no result), "heading", "text", "table", "figure"
    title: str = ""
    text: str = ""
    table: pd.DataFrame | None = None
    fmt: dict | None = None
    figure: Callable[[], plt.Figure] | None = None  # () -> a matplotlib Figure
    full_in_html: pd.DataFrame | None = None  # the whole table where the PDF shows a part
    # per row of the table: larger is worse (long tables: the worst)
    order: np.ndarray | pd.Series | None = None
    rows_are: str = "rows"  # what a row is, e.g. "photos"
    ident: str = ""  # the table's id stem in the HTML (default: from the title)
    which: str = "worst"  # the rows a long table keeps: "worst" by `order`, or "first"
    png: bytes | None = None  # a figure drawn already (the geometry figures), not `figure`


def _rms(x) -> float:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")


def _rms_per_axis(rows: pd.DataFrame) -> str:
    """'X .. m, Y .. m, Z .. m': the RMS of the residuals of each axis over the components
    that were used (rejected ones left out; an axis with none: '-')."""
    used = rows[~rows["rejected"].to_numpy(bool)]
    out = []
    for c in ("X", "Y", "Z"):
        v = used.loc[used["component"] == c, "residual"]
        out.append(f"{c} {_rms(v):.3f} m" if len(v) else f"{c} -")
    n = int(rows["rejected"].to_numpy(bool).sum())
    return ", ".join(out) + (f" ({n} rejected component(s) left out)" if n else "")


def _rejected(g: pd.DataFrame) -> str:
    """The rejected components of one point or photo, e.g. 'Y' or 'X Z' ('' for none)."""
    return " ".join(g.loc[g["rejected"].to_numpy(bool), "component"].astype(str))


def distortion_parts(res: Results, cal: pd.DataFrame) -> list[Part]:
    """Per camera whose model has estimated coefficients (and needs no constants): the
    correction of the adjusted camera model over the measured image area, vectors on a grid
    and the size in µm (block/camera_models.py: the model's delta, in mm in the image)."""
    from baarda.block.camera_models import get_model

    out = []
    obs = res.obs
    img = obs[(obs["kind"] == "image") & obs["x_mm"].notna()]
    for cam, rows in cal.groupby("camera", sort=False):
        model = get_model(str(rows["model"].iloc[0]))
        coef_rows = rows[rows["parameter"].isin(model.params)]
        if model.constants or not model.params or not coef_rows["estimated"].any():
            continue
        vals = dict(zip(rows["parameter"], rows["value"], strict=True))
        coef = np.array([[vals[p] for p in model.params]], float)
        c, pp = vals["c"], np.array([vals["x0"], vals["y0"]])
        if len(img) < 3:
            continue
        lo = img[["x_mm", "y_mm"]].min().to_numpy(float)
        hi = img[["x_mm", "y_mm"]].max().to_numpy(float)
        gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 15), np.linspace(lo[1], hi[1], 11))
        xy = np.column_stack([gx.ravel(), gy.ravel()])
        u = (xy - pp) / c if model.normalized else xy - pp
        delta = model.correction(u, coef)[0] * (c if model.normalized else 1.0) * 1e3  # µm

        def draw(xy=xy, delta=delta, cam=cam, gx=gx):
            fig, ax = plt.subplots(figsize=(6.0, 4.2))
            size = np.hypot(delta[:, 0], delta[:, 1])
            cs = ax.contourf(xy[:, 0].reshape(gx.shape), xy[:, 1].reshape(gx.shape),
                             size.reshape(gx.shape), levels=12, cmap="viridis")
            ax.quiver(xy[:, 0], xy[:, 1], delta[:, 0], delta[:, 1], color="white",
                      angles="xy")
            fig.colorbar(cs, ax=ax, label="correction µm")
            ax.set_xlabel("x mm")
            ax.set_ylabel("y mm")
            ax.set_aspect("equal")
            ax.set_title(f"distortion of camera {cam}"[:60], fontsize=9)
            return fig

        big = float(np.max(np.hypot(delta[:, 0], delta[:, 1])))
        out.append(Part("figure", f"distortion of camera {cam}",
                        text=f"The correction of the adjusted {model.name} model over the "
                        f"measured image area (largest {big:.1f} µm): direction and size.",
                        figure=draw))
    return out


def camera_parts(res: Results) -> list[Part]:
    cal = res.summary.get("calibration") or []
    corr = res.summary.get("camera_correlations") or []
    parts = [Part("heading", "Camera calibration")]
    if not cal:
        return parts + [Part("text", text="No camera parameter was estimated (the cameras "
                             "were held at their given values).")]
    t = pd.DataFrame(cal)
    t["sigma"] = t["sigma"].astype(float)
    t["value / sigma"] = np.where(t["estimated"], t["value"].abs() / t["sigma"], np.nan)
    t["initial"] = t.get("initial", pd.Series(np.nan, index=t.index)).astype(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        t["change %"] = np.where(t["estimated"] & (t["initial"] != 0),
                                 100 * (t["value"] - t["initial"]) / t["initial"].abs(), np.nan)
    px = pixel_um(res)
    cols = ["camera", "model", "parameter", "initial", "value", "change %", "sigma"]
    if px:  # c, x0, y0 in pixels as well (the nominal pixel size of the reader)
        mm = t["parameter"].isin(["c", "x0", "y0"])
        t["value px"] = np.where(mm, t["value"] * 1e3 / px, np.nan)
        t["sigma px"] = np.where(mm, t["sigma"] * 1e3 / px, np.nan)
        cols += ["value px", "sigma px"]
    parts.append(Part("text", text="Every parameter as given (initial) and adjusted, the "
                      "change in % of the initial value, the standard deviation (a posteriori, "
                      "scaled by sigma0); c, x0, y0 in mm, the coefficients in the camera "
                      "model's units; held parameters have no standard deviation."))
    parts.append(Part("table", "camera parameters", table=t[
        cols + ["value / sigma", "estimated"]],
        fmt={"initial": ".6g", "value": ".6g", "change %": "+.2f", "sigma": ".3g",
             "value / sigma": ".1f", "value px": ".2f", "sigma px": ".2f"}))
    parts += distortion_parts(res, t)
    for c in corr:
        names = c["parameters"]
        m = np.asarray(c["matrix"], float)
        ct = pd.DataFrame(m, columns=names)
        ct.insert(0, "parameter", names)
        parts.append(Part("table", f"correlations of camera {c['camera']}", table=ct,
                          fmt={n: "+.3f" for n in names}))

        def draw(m=m, names=names, cam=c["camera"]):
            fig, ax = plt.subplots(figsize=(1.2 + 0.55 * len(names), 1.0 + 0.5 * len(names)))
            im = ax.imshow(m, vmin=-1, vmax=1, cmap="RdBu_r")
            ax.set_xticks(range(len(names)), names, rotation=90)
            ax.set_yticks(range(len(names)), names)
            for i in range(len(names)):
                for j in range(len(names)):
                    ax.text(j, i, f"{m[i, j]:.2f}", ha="center", va="center", fontsize=7,
                            color="white" if abs(m[i, j]) > 0.6 else "black")
            fig.colorbar(im, ax=ax, shrink=0.8)
            ax.set_title(f"correlations: {cam}"[:60], fontsize=9)
            return fig

        parts.append(Part("figure", f"correlation heat map of camera {c['camera']}",
                          text="Correlation coefficients of the estimated parameters "
                          "(red +1, blue -1): |r| near 1 means the block cannot tell the two "
                          "apart.", figure=draw))
    high = res.summary.get("high_correlations") or []
    if high:
        parts.append(Part("text", text="High correlations (|r| > 0.95): " + "; ".join(high)))
    return parts


def control_parts(res: Results) -> list[Part]:
    parts = [Part("heading", "Ground control and check points")]
    obs = res.obs
    ctrl = obs[obs["kind"] == "control"]
    if len(ctrl):
        rows = []
        for pt, g in ctrl.groupby("point", sort=False):
            row = {"point": pt, "role": "control", "rejected": _rejected(g)}
            for _, o in g.iterrows():
                c = o["component"]
                row[f"v{c} m"] = o["residual"]
                row[f"w {c}"] = o["w"]
                row[f"r {c}"] = o["redundancy"]
                row[f"MDB {c} m"] = o["mdb"]
            rows.append(row)
        t = pd.DataFrame(rows)
        from baarda.report.facts import gcp_images

        g = gcp_images(res)
        if len(g):  # the images each GCP is measured on and its reprojection error
            t = t.merge(g, on="point", how="left")
        parts.append(Part("text", text="Control points (GCPs used as observations): residual "
                          "v = adjusted - given per axis, w-test, redundancy number r (0: the "
                          "point is not checked by the rest of the block) and the minimal "
                          "detectable bias. RMS: " + _rms_per_axis(ctrl)))
        wcols = [c for c in t.columns if c.startswith("w ")]
        parts.append(Part("table", "control points", table=t,
                          fmt={c: (".3f" if c.startswith(("v", "MDB")) else ".2f")
                               for c in t.columns if c not in ("point", "role", "rejected",
                                                               "images")},
                          order=t[wcols].abs().max(axis=1).to_numpy(float) + 1e3 * (
                              t["rejected"] != ""), rows_are="control points"))
    pts = res.points
    if pts is not None and "role" in pts and (pts["role"] == "check").any():
        chk = pts[pts["role"] == "check"]
        have = chk[["dX", "dY", "dZ"]].notna().all(axis=1) if "dX" in chk else \
            pd.Series(False, index=chk.index)
        if have.any():
            c = chk[have]
            t = c[["point", "X", "Y", "Z", "dX", "dY", "dZ"]]
            parts.append(Part("text", text="Check points (GCPs not used in the adjustment): "
                              "adjusted - given coordinates. RMS: " + ", ".join(
                                  f"{a[1]} {_rms(c[a]):.3f} m" for a in ("dX", "dY", "dZ"))))
            parts.append(Part("table", "check points", table=t,
                              fmt={"X": ".3f", "Y": ".3f", "Z": ".3f", "dX": ".3f",
                                   "dY": ".3f", "dZ": ".3f"}))
        missing = list(chk.loc[~have, "point"])
        if missing:
            parts.append(Part("text", text=f"Check points without a comparison: "
                              f"{', '.join(map(str, missing))} (a free network or inner "
                              "datum needs 3 check points for the similarity onto them; a "
                              "point on one photo cannot be intersected)"))
    if len(parts) == 1:
        parts.append(Part("text", text="No control or check points."))
    return parts


def _per_photo(g: pd.DataFrame) -> pd.DataFrame:
    """One row per photo of its GNSS or IMU rows: v, w and r per component, and the
    rejected ones named."""
    t = g.pivot_table(index="photo", columns="component",
                      values=["residual", "w", "redundancy"], sort=False)
    t.columns = [f"{'v' if a == 'residual' else a} {c}" for a, c in t.columns]
    t = t.reset_index()
    rejected = {ph: _rejected(r) for ph, r in g.groupby("photo", sort=False)}
    t["rejected"] = [rejected.get(ph, "") for ph in t["photo"]]
    return t


def gnss_parts(res: Results) -> list[Part]:
    g = res.obs[res.obs["kind"] == GNSS.name]
    if not len(g):
        return []
    t = _per_photo(g)
    return [Part("heading", GNSS.title),
            Part("text", text="Residual v = adjusted - observed (m), w-test and redundancy "
                 "number per axis. RMS: " + _rms_per_axis(g)),
            Part("table", "GNSS residuals", table=t,
                 fmt={c: ".3f" if c.startswith("v") else ".2f" for c in t.columns
                      if c not in ("photo", "rejected")},
                 order=t[[c for c in t.columns if c.startswith("w ")]].abs().max(axis=1)
                 .to_numpy(float) + 1e3 * (t["rejected"] != ""), rows_are="photos")]


def imu_parts(res: Results) -> list[Part]:
    g = res.obs[res.obs["kind"] == IMU.name]
    if not len(g):
        return []
    unit = res.units.get(IMU.name, "")
    t = _per_photo(g)
    used = g[~g["rejected"].to_numpy(bool)]
    rms = ", ".join(f"{c} {_rms(used.loc[used['component'] == c, 'residual']):.3f} {unit}"
                    for c in ("omega", "phi", "kappa") if (used["component"] == c).any())
    return [Part("heading", IMU.title),
            Part("text", text=f"Residual v = adjusted - observed ({unit}), w-test and "
                 f"redundancy number per angle. RMS: {rms or '-'}"),
            Part("table", "IMU residuals", table=t,
                 fmt={c: ".3f" if c.startswith("v") else ".2f" for c in t.columns
                      if c not in ("photo", "rejected")},
                 order=t[[c for c in t.columns if c.startswith("w ")]].abs().max(axis=1)
                 .to_numpy(float) + 1e3 * (t["rejected"] != ""), rows_are="photos")]


def image_parts(res: Results) -> list[Part]:
    x, y = pair_xy(res.obs)  # one row per image point, x and y aligned
    ax = ~x["rejected"].astype(bool).to_numpy()
    ay = ~y["rejected"].fillna(True).astype(bool).to_numpy() & y["residual"].notna().to_numpy()
    if not (ax.any() or ay.any()):
        return []
    px = pixel_um(res)
    unit = "px" if px else "µm"
    scale = 1.0 / px if px else 1.0
    vx = x["residual"].to_numpy(float) * scale
    vy = y["residual"].to_numpy(float) * scale
    both = ax & ay  # the error vector needs both components
    rows = []
    for ph, i in x.groupby("photo", sort=False).indices.items():
        e = np.hypot(vx[i][both[i]], vy[i][both[i]])
        n = len(e)
        rows.append({"photo": ph, "points": n, f"RMS x {unit}": _rms(vx[i][ax[i]]),
                     f"RMS y {unit}": _rms(vy[i][ay[i]]),
                     f"mean error {unit}": float(np.mean(e)) if n else np.nan,
                     f"median error {unit}": float(np.median(e)) if n else np.nan,
                     f"max error {unit}": float(np.max(e)) if n else np.nan})
    t = pd.DataFrame(rows)
    note = (f"1 px = {px:g} µm" if px else
            "in µm in the image plane")
    return [Part("heading", "Reprojection errors per image"),
            Part("text", text=f"Image residuals of the adjusted block (rejected observations "
                 f"left out), {note}; error = length of the residual vector."),
            Part("table", "reprojection errors", table=t,
                 fmt={c: ".3f" for c in t.columns if c not in ("photo", "points")},
                 order=t[f"RMS x {unit}"].fillna(0).to_numpy(float) ** 2
                 + t[f"RMS y {unit}"].fillna(0).to_numpy(float) ** 2, rows_are="photos")]


def observation_parts(res: Results) -> list[Part]:
    o = res.obs
    lname, lf = length = length_unit(res)
    unit, f = row_units(res, o["kind"], length)
    t = pd.DataFrame({c: o[c] for c in ("kind", "photo", "point", "component") if c in o})
    t["unit"] = unit  # one unit per row: residual, sigma and MDB are in it
    for c, name in (("residual", "residual"), ("sigma", "sigma"), ("mdb", "MDB")):
        if c in o:
            t[name] = o[c].to_numpy(float) * f
    for c in ("redundancy", "w"):
        if c in o:
            t[c] = o[c]
    if "external_max" in o:
        t[f"external {lname}"] = o["external_max"].to_numpy(float) * lf
    for c in ("rejected", "flagged"):
        if c in o:
            t[c] = o[c]
    worst = t.reindex(t["w"].abs().sort_values(ascending=False).index).head(WORST)
    fmt = {"residual": ".4g", "sigma": ".3g", "redundancy": ".3f", "w": ".2f", "MDB": ".3g",
           f"external {lname}": ".3g"}
    n = min(WORST, len(t))
    parts = [Part("heading", "Every observation: redundancy number, w-test, MDB"),
             Part("text", text=f"{len(t)} observation components (observations.csv holds "
                  "them all, with tau, p-values and the external reliability). redundancy: "
                  "the share of an error that shows in its own residual; w: the standardised "
                  f"residual (critical |w| {res.k_w:.2f}); MDB: the smallest error the test "
                  "finds with 80 % power; residual, sigma and MDB in the row's unit, the "
                  f"external reliability (the largest effect of an MDB on a point) in "
                  f"{lname}. The {n} largest |w|:"),
             Part("table", f"the {n} largest |w|", table=worst, fmt=fmt,
                  ident="observations")]

    def draw():
        fig, ax = plt.subplots(1, 2, figsize=(8, 2.8))
        r = t["redundancy"].to_numpy(float)
        ax[0].hist(r[np.isfinite(r)], bins=40, color="#1f5fa8")
        ax[0].set_xlabel("redundancy number")
        w = t["w"].to_numpy(float)
        ax[1].hist(np.clip(w[np.isfinite(w)], -8, 8), bins=64, color="#1f5fa8")
        ax[1].axvline(res.k_w, color="#d62728")
        ax[1].axvline(-res.k_w, color="#d62728")
        ax[1].set_xlabel("w (clipped to +-8)")
        return fig

    parts.append(Part("figure", "redundancy numbers and w", text="Distribution of the "
                      "redundancy numbers and of w (red: critical values).", figure=draw))
    return parts


def snooping_parts(res: Results) -> list[Part]:
    log = res.summary.get("rejection_log") or []
    parts = [Part("heading", "Data snooping log")]
    if not log:
        return parts + [Part("text", text="No data snooping in this run (baarda adjust "
                             "--snoop), or nothing rejected.")]
    rows = [{k: v for k, v in r.items() if k != "sigma0 before"} for r in log_rows(res.summary)]
    return parts + [Part("table", "snooping log", table=pd.DataFrame(rows),
                         fmt={"value": ".2f"}, order=-np.arange(len(rows)), rows_are="steps",
                         which="first")]


def reliability_parts(res: Results) -> list[Part]:
    o = res.obs
    if "external_max" not in o or not o["external_max"].notna().any():
        return []
    e = o[(o["kind"] == "image") & np.isfinite(o["external_max"].to_numpy(float))]
    if not len(e):
        return []
    lname, lf = length_unit(res)
    per = e.groupby("point")["external_max"].max().sort_values(ascending=False) * lf
    col = f"largest effect {lname}"
    t = pd.DataFrame({"point": per.index, col: per.to_numpy()}).head(20)
    return [Part("heading", "External reliability of the ground points"),
            Part("text", text="The largest effect an undetected error of the size of its MDB "
                 "in one of a point's image observations has on the adjusted coordinates "
                 f"({lname}). Median over {len(per)} points {float(per.median()):.3g} "
                 f"{lname}, 95 % below {float(per.quantile(0.95)):.3g} {lname}; the "
                 f"{len(t)} weakest:"),
            Part("table", "external reliability", table=t, fmt={col: ".3g"})]


def summary_parts(res: Results) -> list[Part]:
    s = res.summary
    lines = [f"project {res.title}, source {s.get('source', '?')}",
             f"sigma0 a posteriori {s.get('sigma0', float('nan')):.4f}, redundancy "
             f"{s.get('redundancy')}, {s.get('n_observations')} observations, "
             f"{s.get('n_unknowns')} unknowns, "
             + ("converged" if s.get("converged") else "NOT CONVERGED")]
    lines += res.global_test_lines()
    notes = run_notes(res)
    out = ([Part("alert", text=f) for f in failures(res.summary)]
           + [Part("heading", "Summary"), Part("text", text="\n".join(lines))])
    if notes:
        out.append(Part("text", title="notes", text="Notes of the run:\n"
                        + "\n".join(f"- {n}" for n in notes)))
    return out


def geometry_parts(res: Results) -> list[Part]:
    """The geometry figures of the adjustment report (camera centres with their ellipses,
    the GCP and check-point vectors, the overlap per ground cell), drawn once."""
    from baarda.report.geometry import centres, ground_vectors, overlap

    figs = [f for f in (centres(res), ground_vectors(res), overlap(res)) if f is not None]
    if not figs:
        return []
    return [Part("heading", "Geometry")] + [Part("figure", f.title, text=f.caption, png=f.png)
                                            for f in figs]


def calibration_parts(res: Results) -> list[Part]:
    """The camera, control, GNSS and IMU parts (the main HTML report shows them too)."""
    return camera_parts(res) + control_parts(res) + gnss_parts(res) + imu_parts(res)


def quality_content(res: Results, calibration: list[Part] | None = None) -> list[Part]:
    """Every part of the quality report; `calibration`: calibration_parts(res) when they
    are at hand."""
    cal = calibration_parts(res) if calibration is None else calibration
    return (summary_parts(res) + cal + geometry_parts(res) + image_parts(res)
            + observation_parts(res) + snooping_parts(res) + reliability_parts(res))
