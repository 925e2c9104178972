"""Map figures of the report: block map, image residual vectors, redundancy and reliability.

All values come from the output folder (observations.csv, points.csv, photos.csv); the
figures only place them.  Each Plot's `marked` lists the observations drawn as rejected.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.collections import PolyCollection
from matplotlib.ticker import MaxNLocator

from baarda.io.result_folder import Results
from baarda.report.front import length_unit
from baarda.report.plots import COLORS, Plot, to_png
from baarda.report.stats import obs_label, pair_xy


def point_summary(res: Results) -> pd.DataFrame:
    """Per ground point: position, role and what its observations say (min r, max MDB of the
    image observations, max external effect, rejected / flagged / uncontrolled)."""
    if res.points is None:
        return pd.DataFrame(columns=["point", "X", "Y", "role"])
    o = res.obs[[c for c in ("kind", "photo", "model", "point", "component", "w",
                             "redundancy", "mdb", "external_max", "external_point", "rejected",
                             "flagged") if c in res.obs]]  # a few columns of millions of rows
    act = ~o["rejected"].to_numpy(bool)
    w = o["w"].to_numpy(float)
    tested = act & np.isfinite(w)
    img = o["kind"].to_numpy(str) == "image"
    codes, names = pd.factorize(o["point"])  # once: the groups of every column below
    names = np.asarray(names, dtype=object)

    def per_point(col: str | np.ndarray, sel: np.ndarray, how: str) -> pd.Series:
        v = o[col].to_numpy() if isinstance(col, str) else col
        sel = sel & (codes >= 0)
        r = getattr(pd.Series(v[sel]).groupby(codes[sel]), how)()
        return pd.Series(r.to_numpy(), index=names[r.index.to_numpy()])

    pts = res.points[["point", "X", "Y", "role"]].copy().set_index("point", drop=False)
    pts["r_min"] = per_point("redundancy", tested, "min")
    pts["mdb_max"] = per_point("mdb", tested & img, "max")
    sel = tested & np.isfinite(o["external_max"].to_numpy(float))
    ext = o.loc[sel, ["point", "external_point", "external_max"]]
    key = np.where(ext["external_point"].astype(str) != "", ext["external_point"].astype(str),
                   ext["point"].astype(str))
    pts["ext_max"] = ext.groupby(key)["external_max"].max()
    every = np.ones(len(o), bool)
    pts["uncontrolled"] = per_point(act & ~np.isfinite(w), every, "any")
    pts["rejected"] = per_point("rejected", every, "any")
    pts["flagged"] = per_point("flagged", every, "any")
    rej = o[o["rejected"]]
    pts["rejected_labels"] = rej.assign(label=obs_label(rej)).groupby("point")["label"].agg(
        list)
    for c in ("uncontrolled", "rejected", "flagged"):
        pts[c] = pts[c].astype("boolean").fillna(False).astype(bool)
    pts["rejected_labels"] = [v if isinstance(v, list) else [] for v in pts["rejected_labels"]]
    return pts.reset_index(drop=True)


SAMPLE_SEED = 0


def sample_points(pts: pd.DataFrame, max_points: int | None) -> tuple[pd.DataFrame, str]:
    """The points of a map: all of them, or beyond max_points a deterministic random sample
    of max_points (seed SAMPLE_SEED) with every control and check point and every point with
    a rejected, flagged or uncontrolled observation; the words for the caption ('' when all
    are drawn)."""
    if max_points is None or len(pts) <= max_points:
        return pts, ""
    keep = ((pts["role"] != "tie") | pts["rejected"] | pts["flagged"]
            | pts["uncontrolled"]).to_numpy(bool, copy=True)
    pick = np.random.default_rng(SAMPLE_SEED).choice(len(pts), size=max_points, replace=False)
    keep[pick] = True
    return pts[keep], (f"; {int(keep.sum())} of {len(pts)} points drawn (a deterministic random "
                       f"sample of {max_points}, seed {SAMPLE_SEED}, and every control, check, "
                       "rejected, flagged and uncontrolled point)")


def _points(ax, pts: pd.DataFrame, small: float = 5) -> None:
    style = {"tie": ("o", small, COLORS["tie"]), "check": ("s", 30, COLORS["check"]),
             "control": ("^", 45, COLORS["control"])}
    for role, (m, s, c) in style.items():
        sel = pts["role"] == role
        if sel.any():
            ax.scatter(pts.loc[sel, "X"], pts.loc[sel, "Y"], marker=m, s=s, c=c,
                       label=f"{role} ({int(sel.sum())})", zorder=3)


def block_map(res: Results, outlines: dict[str, np.ndarray], annotate: int = 40,
              pts: pd.DataFrame | None = None, max_points: int | None = None) -> Plot:
    """Photo outlines, photo centres, control/check/tie points; rejected observations in red
    rings (annotated when few), flagged ones in orange.  pts: point_summary(res) when
    already made; max_points: sample_points."""
    pts = point_summary(res) if pts is None else pts
    n_all = len(pts)
    pts, sampled = sample_points(pts, max_points)
    fig, ax = plt.subplots(figsize=(9, 7))
    strip_of = res.strip_of()
    strips = sorted({str(s) for s in strip_of.values()})
    cmap = plt.get_cmap("tab10")
    if outlines:
        polys = list(outlines.values())
        cols = [cmap(strips.index(str(strip_of.get(p, ""))) % 10 if strips else 0)
                for p in outlines]
        ax.add_collection(PolyCollection(polys, facecolors=[(*c[:3], 0.06) for c in cols],
                                         edgecolors=cols, linewidths=0.8, zorder=1))
    if res.photos is not None:
        ph = res.photos
        ax.scatter(ph["X0"], ph["Y0"], marker="+", s=30, c="black", label="photo centre",
                   zorder=2)
        if len(ph) <= 80:
            for p, x, y in zip(ph["photo"], ph["X0"], ph["Y0"], strict=True):
                ax.annotate(str(p), (x, y), fontsize=6, xytext=(3, 3),
                            textcoords="offset points")
    _points(ax, pts)
    rej = pts[pts["rejected"]]
    fl = pts[pts["flagged"] & ~pts["rejected"]]
    marked = [lab for labs in rej["rejected_labels"] for lab in labs]
    if len(rej):
        ax.scatter(rej["X"], rej["Y"], s=180, facecolors="none", edgecolors=COLORS["rejected"],
                   linewidths=1.8, label=f"rejected observation(s) ({len(marked)})", zorder=4)
        if len(marked) <= annotate:
            for _, r in rej.iterrows():
                txt = "\n".join(lab.replace("point ", "") for lab in r["rejected_labels"])
                ax.annotate(txt, (r["X"], r["Y"]), fontsize=6, color=COLORS["rejected"],
                            xytext=(6, -10), textcoords="offset points")
    if len(fl):
        ax.scatter(fl["X"], fl["Y"], s=180, facecolors="none", edgecolors=COLORS["flagged"],
                   linewidths=1.5, label=f"flagged |w| > k ({len(fl)} points)", zorder=4)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.ticklabel_format(useOffset=False, style="plain")  # coordinates as they are
    ax.set_xlabel("X [m]")
    ax.set_ylabel("Y [m]")
    ax.grid(alpha=0.2)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title("Block map" + (" (outlines: measured image area)" if outlines else ""),
                 fontsize=10)
    missing = sorted(set(res.obs.loc[res.obs["rejected"], "point"]) - set(pts["point"]))
    cap = (f"{len(outlines)} photo outlines, {n_all} points{sampled}; rejected observations "
           f"marked (red rings): {', '.join(marked) if marked else 'none'}")
    if missing:
        cap += f"; not on the map (no coordinates): {', '.join(missing)}"
    return Plot("block_map", "Block map", to_png(fig), cap, marked)


def _nice(x: float) -> float:
    """The largest of 1, 2, 5 x 10^k not above x."""
    if not x > 0:
        return 1.0
    e = np.floor(np.log10(x))
    for m in (5, 2, 1):
        if m * 10**e <= x:
            return float(m * 10**e)
    return float(10**e)


def _pairs(obs: pd.DataFrame) -> pd.DataFrame:
    """x and y of the image observations side by side (one row per image point)."""
    x, y = pair_xy(obs[["kind", "photo", "point", "component", "x_mm", "y_mm", "residual",
                        "rejected", "flagged", "w"]])
    return pd.DataFrame({
        "photo": x["photo"], "point": x["point"], "x": x["x_mm"], "y": x["y_mm"],
        "vx": x["residual"], "vy": y["residual"].to_numpy(),
        "rej_x": x["rejected"], "rej_y": y["rejected"].fillna(False).to_numpy(bool),
        "flag": x["flagged"].to_numpy(bool) | y["flagged"].fillna(False).to_numpy(bool),
        "absw": np.fmax(np.abs(x["w"].to_numpy(float)), np.abs(y["w"].to_numpy(float)))})


def choose_photos(pairs: pd.DataFrame, limit: int) -> list[str]:
    """Photos with rejected observations first, then flagged, then the largest |w|."""
    g = pairs.groupby("photo")
    score = pd.DataFrame({"rej": g["rej_x"].any() | g["rej_y"].any(), "flag": g["flag"].any(),
                          "w": g["absw"].max().fillna(0)})
    score = score.sort_values(["rej", "flag", "w"], ascending=False)
    return sorted(score.index[:limit].astype(str))


def residual_vectors(res: Results, exaggeration: float | None = None, limit: int = 12,
                     cols: int = 4) -> Plot | None:
    """Image residual vectors on each photo, exaggerated; rejected red, flagged orange."""
    pairs = _pairs(res.obs)
    pairs = pairs[pairs["x"].notna()]
    if pairs.empty:
        return None
    photos = choose_photos(pairs, limit)
    ext = max(float(np.nanmax(np.abs(pairs["x"]))), float(np.nanmax(np.abs(pairs["y"]))), 1.0)
    act = ~(pairs["rej_x"] | pairs["rej_y"])
    v = np.hypot(pairs.loc[act, "vx"], pairs.loc[act, "vy"])
    p95 = float(np.percentile(v, 95)) if len(v) else 1.0
    if exaggeration is None:
        exaggeration = _nice(0.25 * ext / max(p95 * 1e-3, 1e-9))
    ref = _nice(p95) if p95 > 0 else 1.0
    rows = int(np.ceil(len(photos) / cols))
    ncol = min(cols, len(photos))
    fig, axes = plt.subplots(rows, ncol, figsize=(2.9 * ncol, 2.9 * rows), squeeze=False)
    marked = []
    s = 1e-3 * exaggeration  # µm -> drawn mm
    for ax, p in zip(axes.ravel(), photos, strict=False):
        d = pairs[pairs["photo"].astype(str) == p]
        rej = (d["rej_x"] | d["rej_y"]).to_numpy()
        fl = d["flag"].to_numpy() & ~rej
        for sel, c in ((~rej & ~fl, COLORS["active"]), (fl, COLORS["flagged"]),
                       (rej, COLORS["rejected"])):
            if sel.any():
                ax.quiver(d["x"][sel], d["y"][sel], d["vx"][sel] * s, d["vy"][sel] * s,
                          angles="xy", scale_units="xy", scale=1, color=c, width=0.006)
        ax.scatter(d["x"], d["y"], s=4, c="black")
        for r in d[rej].itertuples():
            comps = [c for c, f in (("x", r.rej_x), ("y", r.rej_y)) if f]
            marked += [f"photo {p} point {r.point} {c}" for c in comps]
            ax.annotate(f"{r.point} {''.join(comps)}", (r.x, r.y), fontsize=6,
                        color=COLORS["rejected"], xytext=(3, -8), textcoords="offset points")
        ax.quiver([-0.9 * ext], [-1.05 * ext], [ref * s], [0], angles="xy", scale_units="xy",
                  scale=1, color="black", width=0.008)
        ax.text(-0.9 * ext, -1.0 * ext, f"{ref:g} µm", fontsize=7)
        ax.set_xlim(-1.15 * ext, 1.15 * ext)
        ax.set_ylim(-1.15 * ext, 1.15 * ext)
        ax.set_aspect("equal")
        ax.set_title(f"photo {p}", fontsize=9)
        ax.tick_params(labelsize=6)
        ax.xaxis.set_major_locator(MaxNLocator(4))
        ax.yaxis.set_major_locator(MaxNLocator(4))
    for ax in axes.ravel()[len(photos):]:
        ax.axis("off")
    fig.suptitle(f"Image residual vectors × {exaggeration:g} (x, y in mm); red: rejected, "
                 "orange: flagged", fontsize=10)
    fig.subplots_adjust(left=0.06, right=0.98, bottom=0.04, top=1 - 0.55 / (rows * 2.9),
                        wspace=0.25, hspace=0.3)
    n_all = pairs["photo"].nunique()
    cap = (f"{len(photos)} of {n_all} photos (those with rejected or flagged observations "
           f"first); vectors exaggerated {exaggeration:g} times; rejected observations "
           f"marked: {', '.join(marked) if marked else 'none'}")
    return Plot("vectors", "Image residual vectors", to_png(fig, tight=False), cap, marked)


HEXBIN_FROM = 3000  # tie points from which a colour map bins them on a hexagonal grid


def _colour_map(ax, fig, pts, col, label, cmap, vmin=None, vmax=None, worst=np.max):
    """Points coloured by `col`: tie points one by one, or beyond HEXBIN_FROM binned on a
    hexagonal grid (each cell the `worst` of its points); control and check points always
    on top; uncontrolled points on a layer of their own, as rings under the colours."""
    have = pts[np.isfinite(pts[col].to_numpy(float))]
    ax.scatter(pts["X"], pts["Y"], s=3, c="#cccccc", zorder=1)
    unc = pts[pts["uncontrolled"]]
    if len(unc):
        ax.scatter(unc["X"], unc["Y"], marker="o", s=40, facecolors="none",
                   edgecolors="#c2187a", linewidths=0.9, zorder=1.5,
                   label=f"uncontrolled (r < 0.001): {len(unc)}")
    sc = None
    tie = have["role"] == "tie"
    if tie.sum() > HEXBIN_FROM:
        sc = ax.hexbin(have.loc[tie, "X"], have.loc[tie, "Y"], C=have.loc[tie, col],
                       reduce_C_function=worst, gridsize=60, cmap=cmap, vmin=vmin, vmax=vmax,
                       mincnt=1, zorder=2, linewidths=0.2)
        roles = (("check", "s", 30), ("control", "^", 50))
    else:
        roles = (("tie", "o", 14), ("check", "s", 30), ("control", "^", 50))
    for role, m, s in roles:
        sel = have["role"] == role
        if sel.any():
            sc = ax.scatter(have.loc[sel, "X"], have.loc[sel, "Y"], c=have.loc[sel, col],
                            marker=m, s=s, cmap=cmap, vmin=vmin, vmax=vmax, zorder=3,
                            edgecolors="black" if role != "tie" else "none", linewidths=0.4)
    if len(have) and sc is not None:
        lo = vmin if vmin is not None else float(have[col].min())
        hi = vmax if vmax is not None else float(have[col].max())
        sc.set_clim(lo, hi)
        fig.colorbar(sc, ax=ax, label=label, shrink=0.8)
    if len(unc):
        ax.legend(fontsize=7, loc="upper left")
    ax.set_aspect("equal")
    ax.ticklabel_format(useOffset=False, style="plain")  # coordinates as they are
    ax.set_xlabel("X [m]")
    ax.set_ylabel("Y [m]")


def redundancy_map(res: Results, pts: pd.DataFrame | None = None,
                   max_points: int | None = None) -> Plot:
    pts = point_summary(res) if pts is None else pts
    drawn, sampled = sample_points(pts, max_points)
    fig, ax = plt.subplots(figsize=(8, 6))
    _colour_map(ax, fig, drawn, "r_min", "smallest redundancy number r", "RdYlGn", 0.0, 1.0,
                worst=np.min)
    ax.set_title("Redundancy numbers: smallest r of each point's observations (triangles: "
                 "control)", fontsize=10)
    n_unc = int(pts["uncontrolled"].sum())
    cap = (f"{int(np.isfinite(pts['r_min']).sum())} points coloured by their smallest "
           f"redundancy number (beyond {HEXBIN_FROM} tie points: the smallest of each "
           f"hexagonal cell); {n_unc} with an uncontrolled observation (magenta rings)"
           f"{sampled}")
    return Plot("redundancy_map", "Map of redundancy numbers", to_png(fig), cap)


def reliability_map(res: Results, pts: pd.DataFrame | None = None,
                    max_points: int | None = None) -> Plot:
    pts = point_summary(res) if pts is None else pts
    drawn, sampled = sample_points(pts, max_points)

    def scale(col: str) -> tuple[float | None, float | None]:  # of every point, not the drawn
        v = pts[col].to_numpy(float)
        v = v[np.isfinite(v)]
        return (float(v.min()), float(v.max())) if sampled and len(v) else (None, None)

    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    _colour_map(axes[0], fig, drawn, "mdb_max", "largest MDB of the image observations [µm]",
                "viridis", *scale("mdb_max"))
    axes[0].set_title("Internal reliability: MDB (boundary value) [µm]", fontsize=10)
    _colour_map(axes[1], fig, drawn, "ext_max", "largest effect of an MDB on the point [m]",
                "magma_r", *scale("ext_max"))
    axes[1].set_title("External reliability: effect of an undetected MDB [m]", fontsize=10)
    fig.tight_layout()
    mdb = pts["mdb_max"].to_numpy(float)
    ext = pts["ext_max"].to_numpy(float)
    lname, lf = length_unit(res)
    cap = (f"largest MDB {np.nanmax(mdb):.1f} µm, largest external effect "
           f"{np.nanmax(ext) * lf:.3g} {lname}" if np.isfinite(mdb).any()
           and np.isfinite(ext).any() else "no tested observations") + sampled
    return Plot("reliability_map", "Maps of internal and external reliability", to_png(fig), cap)
