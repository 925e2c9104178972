"""Geometry figures of the reports, from the result files: the camera centres with their
error ellipses and the GNSS residual vectors, the residual vectors of the control and check
points, the image overlap (photos per ground cell from the footprints; photos per point on a
hexagonal grid where there are none: oblique images), the rays per point and the image residuals
averaged on a grid per camera.  Exaggerations are stated in the captions; tick labels are
plain coordinates (no offsets)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from baarda.io.result_folder import Results
from baarda.kinds import GNSS
from baarda.report.maps import _nice
from baarda.report.plots import COLORS, Plot, plt, to_png

SIZE = (5.6, 4.3)  # inches at 96 dpi: three figures side by side on a 1400 px page
LABELS = 8  # labels for the largest vectors only
NADIR_SHARE = 0.25  # footprints overlapping on less of their area: not nadir photos


def _plain(ax, unit: str = "m") -> None:
    """Plain coordinates (no offset) with their unit on the axes, at most 4 ticks along X
    (long coordinates do not collide)."""
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.tick_params(labelsize=8)
    ax.set_aspect("equal")
    ax.grid(alpha=0.2)
    ax.xaxis.set_major_locator(plt.MaxNLocator(4))
    ax.set_xlabel(f"X {unit}", fontsize=8)
    ax.set_ylabel(f"Y {unit}", fontsize=8)


def _spacing(x: np.ndarray, y: np.ndarray) -> float:
    """The median distance to the nearest other position (m)."""
    from scipy.spatial import cKDTree

    p = np.column_stack([x, y])
    p = p[np.isfinite(p).all(axis=1)]
    if len(p) < 2:
        return 1.0
    d, _ = cKDTree(p).query(p, k=2)
    return float(np.median(d[:, 1])) or 1.0


def _arrow(ax, length: float, scale: float, label: str) -> None:
    """A scale arrow of `length` (drawn length * scale) in the lower left corner."""
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    ax.annotate("", xy=(x0 + 0.05 * (x1 - x0) + length * scale, y0 + 0.05 * (y1 - y0)),
                xytext=(x0 + 0.05 * (x1 - x0), y0 + 0.05 * (y1 - y0)),
                arrowprops={"arrowstyle": "->", "lw": 1.5})
    ax.text(x0 + 0.05 * (x1 - x0), y0 + 0.08 * (y1 - y0), label, fontsize=8)


def _xy_residuals(obs: pd.DataFrame, kind: str, key: str) -> pd.DataFrame:
    """The X and Y residuals of the active observations of `kind` per `key` (photo or
    point)."""
    o = obs[(obs["kind"] == kind) & ~obs["rejected"].to_numpy(bool)]
    t = o.pivot_table(index=key, columns="component", values="residual", aggfunc="first")
    return t.reindex(columns=["X", "Y"]).dropna()


def centres(res: Results) -> Plot | None:
    """Camera centres with their error ellipses (sigma X0, Y0) and GNSS residual vectors."""
    ph = res.photos
    if ph is None or not {"sigma_X0", "sigma_Y0"} <= set(ph.columns) or not len(ph):
        return None
    from matplotlib.collections import EllipseCollection

    x, y = ph["X0"].to_numpy(float), ph["Y0"].to_numpy(float)
    sx, sy = ph["sigma_X0"].to_numpy(float), ph["sigma_Y0"].to_numpy(float)
    space = _spacing(x, y)
    med = float(np.nanmedian(np.hypot(sx, sy))) or 1e-9
    ex = _nice(0.25 * space / med)
    fig, ax = plt.subplots(figsize=SIZE)
    ax.scatter(x, y, s=4, c="black", zorder=2)
    ax.add_collection(EllipseCollection(2 * sx * ex, 2 * sy * ex, np.zeros(len(x)),
                                        units="xy", offsets=np.column_stack([x, y]),
                                        offset_transform=ax.transData, facecolors="none",
                                        edgecolors=COLORS["active"], linewidths=0.8))
    cap = (f"{len(ph)} camera centres with their 1-sigma error ellipses (X0, Y0) enlarged "
           f"{ex:g} times; median sigma {med:.3g} m")
    g = _xy_residuals(res.obs, GNSS.name, "photo")
    if len(g):
        at = ph.set_index(ph["photo"].astype(str)).reindex(g.index.astype(str))
        v = np.hypot(g["X"], g["Y"]).to_numpy(float)
        gex = _nice(0.4 * space / max(float(np.percentile(v, 95)), 1e-9))
        ax.quiver(at["X0"], at["Y0"], g["X"] * gex, g["Y"] * gex, angles="xy",
                  scale_units="xy", scale=1, color=COLORS["rejected"], width=0.004, zorder=3)
        ref = _nice(float(np.percentile(v, 95)))
        ax.autoscale_view()
        _arrow(ax, ref, gex, f"GNSS residual {ref:g} m")
        cap += (f"; red: GNSS residual vectors (adjusted - observed) enlarged {gex:g} times, "
                f"largest {v.max():.3g} m")
    ax.autoscale_view()
    _plain(ax)
    ax.set_title("Camera centres and GNSS residuals", fontsize=10)
    return Plot("centres", "Camera centres", to_png(fig), cap)


def ground_vectors(res: Results) -> Plot | None:
    """Residual vectors of the control points (v, used components) and the misses of the
    check points (adjusted - given), with a scale arrow; labels for the largest."""
    pts = res.points
    if pts is None:
        return None
    c = _xy_residuals(res.obs, "control", "point")
    pos = pts.set_index(pts["point"].astype(str))
    chk = pts[(pts["role"] == "check") & pts.get("dX", pd.Series(np.nan, index=pts.index))
              .notna()] if "dX" in pts else pts.iloc[:0]
    if not len(c) and not len(chk):
        return None
    rows = [pd.DataFrame({"point": c.index.astype(str), "dx": c["X"].to_numpy(float),
                          "dy": c["Y"].to_numpy(float), "role": "control"}),
            pd.DataFrame({"point": chk["point"].astype(str), "dx": chk["dX"].to_numpy(float),
                          "dy": chk["dY"].to_numpy(float), "role": "check"})]
    t = pd.concat(rows, ignore_index=True)
    t = t[t["point"].isin(pos.index)]
    t["X"] = pos.loc[t["point"], "X"].to_numpy(float)
    t["Y"] = pos.loc[t["point"], "Y"].to_numpy(float)
    t["len"] = np.hypot(t["dx"], t["dy"])
    if not len(t):
        return None
    space = max(float(np.ptp(pos["X"].to_numpy(float))), float(np.ptp(pos["Y"].to_numpy(
        float))), 1.0)
    p95 = max(float(np.percentile(t["len"], 95)), 1e-9)
    ex = _nice(0.08 * space / p95)
    fig, ax = plt.subplots(figsize=SIZE)
    ax.scatter(pos["X"], pos["Y"], s=1, c="#bbbbbb", zorder=1)
    for role, col in (("control", COLORS["control"]), ("check", COLORS["check"])):
        s = t[t["role"] == role]
        if len(s):
            ax.quiver(s["X"], s["Y"], s["dx"] * ex, s["dy"] * ex, angles="xy",
                      scale_units="xy", scale=1, color=col, width=0.004, zorder=3,
                      label=f"{role} ({len(s)})")
    for r in t.nlargest(LABELS, "len").itertuples():
        ax.annotate(f"{r.point} {r.len:.2g} m", (r.X, r.Y), fontsize=7, xytext=(3, 3),
                    textcoords="offset points")
    ax.autoscale_view()
    ref = _nice(p95)
    _arrow(ax, ref, ex, f"{ref:g} m")
    _plain(ax)
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title("Control residuals and check-point misses (X, Y)", fontsize=10)
    cap = (f"blue: residual vectors of {int((t['role'] == 'control').sum())} control points "
           f"(adjusted - given), green: misses of {int((t['role'] == 'check').sum())} check "
           f"points, enlarged {ex:g} times; the {min(LABELS, len(t))} largest labelled")
    return Plot("ground_vectors", "Control and check point vectors", to_png(fig), cap)


def area_words(m2: float) -> str:
    """An area in words: km^2 from 1 km^2, ha from 1 ha, else m^2."""
    if m2 >= 1e6:
        return f"{m2 / 1e6:.3g} km²"
    return f"{m2 / 1e4:.3g} ha" if m2 >= 1e4 else f"{m2:.3g} m²"


def overlap(res: Results) -> Plot | None:
    """Photos per ground cell from the footprints (report/coverage.py); without footprints
    (no camera, oblique photos) photos per point (points.csv rays) on a hexagonal grid."""
    from matplotlib.colors import BoundaryNorm

    from baarda.report.coverage import coverage
    from baarda.report.footprint import photo_outlines

    cov = coverage(photo_outlines(res)[0])
    if cov is None or not cov.share(2) >= NADIR_SHARE:  # not a block of overlapping nadirs
        return _overlap_per_point(res)
    n = cov.counts
    top = max(int(n.max()), 1)
    fig, ax = plt.subplots(figsize=SIZE)
    cmap = plt.get_cmap("viridis", top).with_extremes(bad="white")
    ny, nx = n.shape
    im = ax.imshow(np.ma.masked_equal(n, 0), origin="lower", cmap=cmap,
                   norm=BoundaryNorm(np.arange(0.5, top + 1.5), cmap.N), interpolation="nearest",
                   extent=(cov.x0, cov.x0 + nx * cov.cell, cov.y0, cov.y0 + ny * cov.cell))
    cb = fig.colorbar(im, ax=ax, shrink=0.85, label="photos per ground cell")
    cb.set_ticks(np.unique(np.linspace(1, top, min(top, 8)).round().astype(int)).tolist())
    _plain(ax)
    ax.set_title("Image overlap: photos per ground cell", fontsize=10)
    cap = (f"the photos whose footprint (the measured image area at the points' median "
           f"height) covers each ground cell of {cov.cell:.3g} m; covered "
           f"{area_words(cov.area_m2)}, of it {100 * cov.share(2):.0f} % seen by two or more "
           f"photos and {100 * cov.share(3):.0f} % by three or more; white: no photo")
    return Plot("overlap", "Image overlap", to_png(fig), cap)


def _overlap_per_point(res: Results) -> Plot | None:
    """Photos per point (points.csv rays), averaged on a hexagonal grid."""
    pts = res.points
    if pts is None or "rays" not in pts or not len(pts):
        return None
    r = pts["rays"].to_numpy(float)
    ok = np.isfinite(r)
    fig, ax = plt.subplots(figsize=SIZE)
    hb = ax.hexbin(pts["X"].to_numpy(float)[ok], pts["Y"].to_numpy(float)[ok], C=r[ok],
                   gridsize=30, reduce_C_function=np.mean, cmap="viridis", mincnt=1)
    fig.colorbar(hb, ax=ax, label="photos per point (mean)", shrink=0.85)
    _plain(ax)
    ax.set_title("Image overlap: photos per point", fontsize=10)
    cap = (f"the number of photos that see each of {int(ok.sum())} points, averaged on a "
           f"hexagonal grid (no photo footprints: no camera or oblique photos); median "
           f"{np.median(r[ok]):.0f}, minimum {r[ok].min():.0f}")
    return Plot("overlap", "Image overlap", to_png(fig), cap)


def rays(res: Results) -> Plot | None:
    """Histogram of the rays per point."""
    pts = res.points
    if pts is None or "rays" not in pts or not len(pts):
        return None
    r = pts["rays"].to_numpy(float)
    r = r[np.isfinite(r)].astype(int)
    k, n = np.unique(r, return_counts=True)
    fig, ax = plt.subplots(figsize=SIZE)
    ax.bar(k, n, color=COLORS["active"])
    ax.set_xlabel("rays (photos) per point")
    ax.set_ylabel("points")
    ax.grid(axis="y", alpha=0.3)
    ax.tick_params(labelsize=8)
    ax.set_title("Rays per point", fontsize=10)
    cap = "; ".join(f"{a} rays: {b}" for a, b in zip(k[:8], n[:8], strict=True))
    return Plot("rays", "Rays per point", to_png(fig), cap)


def image_grid(res: Results, cells: int = 8) -> Plot | None:
    """Image residuals of the first camera averaged on a cells x cells grid of the image."""
    o = res.obs
    img = o[(o["kind"] == "image") & o["x_mm"].notna() & ~o["rejected"].to_numpy(bool)]
    if not len(img):
        return None
    x = img[img["component"] == "x"]
    y = img[img["component"] == "y"]
    t = x[["photo", "point", "x_mm", "y_mm", "residual"]].merge(
        y[["photo", "point", "residual"]], on=["photo", "point"], suffixes=("_x", "_y"))
    if not len(t):
        return None
    ext = max(float(np.abs(t["x_mm"]).max()), float(np.abs(t["y_mm"]).max()), 1e-6)
    edges = np.linspace(-ext, ext, cells + 1)
    i = np.clip(np.digitize(t["x_mm"], edges) - 1, 0, cells - 1)
    j = np.clip(np.digitize(t["y_mm"], edges) - 1, 0, cells - 1)
    g = t.assign(i=i, j=j).groupby(["i", "j"]).agg(vx=("residual_x", "mean"),
                                                  vy=("residual_y", "mean"),
                                                  n=("residual_x", "size")).reset_index()
    g = g[g["n"] >= 3]
    if not len(g):
        return None
    cx = 0.5 * (edges[g["i"]] + edges[g["i"] + 1])
    cy = 0.5 * (edges[g["j"]] + edges[g["j"] + 1])
    v = np.hypot(g["vx"], g["vy"]).to_numpy(float)
    ex = _nice(0.6 * (edges[1] - edges[0]) / max(float(v.max()) * 1e-3, 1e-12))
    fig, ax = plt.subplots(figsize=SIZE)
    ax.quiver(cx, cy, g["vx"] * 1e-3 * ex, g["vy"] * 1e-3 * ex, angles="xy",
              scale_units="xy", scale=1, color=COLORS["active"], width=0.005)
    ax.set_xlim(-1.1 * ext, 1.1 * ext)
    ax.set_ylim(-1.1 * ext, 1.1 * ext)
    ref = _nice(float(v.max()))
    _arrow(ax, ref * 1e-3, ex, f"{ref:g} µm")
    _plain(ax, "mm")
    ax.set_xlabel("x mm", fontsize=8)
    ax.set_ylabel("y mm", fontsize=8)
    ax.set_title("Image residuals averaged on a grid", fontsize=10)
    cap = (f"mean image residual of the cells with 3 or more points ({cells} x {cells} "
           f"grid over every photo), enlarged {ex:g} times; largest mean {v.max():.2f} µm: "
           "a pattern here is a lens distortion or an interior orientation not modelled")
    return Plot("image_grid", "Image residuals on a grid", to_png(fig), cap)


def geometry_plots(res: Results) -> dict[str, Plot | None]:
    return {"centres": centres(res), "ground_vectors": ground_vectors(res),
            "overlap": overlap(res), "rays": rays(res), "image_grid": image_grid(res)}
