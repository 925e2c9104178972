"""What a client expects to read about a block before its accuracy (as Pix4D's and
Metashape's reports give it), from the result files where the input allows: the photos
and cameras, the flying height above ground, the ground sampling distance, the covered
area, the measured image area in mm and px, the processing time, the mean and spread of
the orientation standard deviations, and the GCPs' images and reprojection errors.

Flying height H = median over the photos of Z0 - the points' median Z (nadir blocks: the
photos' footprints overlap); GSD = pixel size x H / c; area: report/coverage.py.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from baarda.io.result_folder import Results
from baarda.report.coverage import coverage
from baarda.report.footprint import image_extent, photo_outlines
from baarda.report.front import length_unit, pixel_um
from baarda.report.geometry import NADIR_SHARE, area_words


def project_facts(res: Results) -> list[tuple[str, str]]:
    """(what, value in words), for the metadata section and the PDF's first pages."""
    s = res.summary
    out: list[tuple[str, str]] = []
    ph = res.photos
    cams = s.get("cameras") or []
    if ph is not None and len(ph):
        out.append(("photos", f"{len(ph)} in {ph['strip'].astype(str).nunique()} strip(s), "
                    f"{len(cams)} camera(s)" if "strip" in ph else f"{len(ph)}"))
    px = pixel_um(res)
    ext = image_extent(res.obs, ph, res.cameras) if ph is not None and res.cameras else {}
    for cam, (hx, hy) in ext.items():
        size = f"{2 * hx:.1f} x {2 * hy:.1f} mm"
        if px:
            size += f" = {2e3 * hx / px:,.0f} x {2e3 * hy / px:,.0f} px of {px:g} µm"
        c = res.cameras.get(cam, {}).get("focal_mm")
        out.append((f"camera {cam}"[:60], (f"c {c:.3f} mm, " if c else "") + "measured "
                    f"image area {size}" + ("" if px else " (pixel size not stated)")))
    outlines, zg = photo_outlines(res)
    cov = coverage(outlines)
    if cov is not None and cov.share(2) >= NADIR_SHARE and ph is not None:
        h = float(np.median(ph["Z0"].to_numpy(float) - zg))
        out.append(("flying height above ground", f"{h:,.0f} m (the photos' median above "
                    "the points' median height)"))
        c = [float(x["focal_mm"]) for x in cams if x.get("focal_mm")]
        if px and c:
            gsd = px * 1e-3 * h / float(np.median(c))  # mm x m / mm = m on the ground
            out.append(("ground sampling distance", f"{100 * gsd:.3g} cm per pixel"))
        out.append(("covered area", f"{area_words(cov.area_m2)} ({100 * cov.share(2):.0f} % "
                    "seen by two or more photos)"))
    if s.get("seconds") is not None:
        out.append(("processing time", f"{float(s['seconds']):.1f} s (adjustment and tests)"))
    o = orientation_spread(res)
    if o:
        out.append(("orientation standard deviations (mean ± spread over the photos)", o))
    g = gcp_images(res)
    if len(g):
        unit = g.columns[-1].split()[-1]
        err = g[g.columns[-1]].to_numpy(float)
        out.append(("GCPs", f"{len(g)} measured on {int(g['images'].median())} images "
                    f"(median; {int(g['images'].min())} to {int(g['images'].max())}), "
                    f"reprojection error {np.nanmedian(err):.2f} {unit} (median of the "
                    f"GCPs' RMS)"))
    return out


def orientation_spread(res: Results) -> str:
    """'X0 0.12 ± 0.03 m, ...': the mean and standard deviation over the photos of each
    orientation element's standard deviation."""
    ph = res.photos
    if ph is None or "sigma_X0" not in ph:
        return ""
    parts = []
    lname, lf = length_unit(res)
    for c, unit in (("X0", lname), ("Y0", lname), ("Z0", lname), ("omega", res.angle_unit or ""),
                    ("phi", res.angle_unit or ""), ("kappa", res.angle_unit or "")):
        v = ph.get(f"sigma_{c}")
        if v is None:
            continue
        v = v.to_numpy(float) * (lf if unit == lname else 1.0)
        v = v[np.isfinite(v)]
        if len(v):
            parts.append(f"{c} {np.mean(v):.3g} ± {np.std(v):.2g} {unit}".rstrip())
    return ", ".join(parts)


def gcp_images(res: Results) -> pd.DataFrame:
    """Per control point: the images it is measured on and the RMS of its image residuals
    (px where the pixel size is known, else µm; rejected ones left out)."""
    pts = res.points
    if pts is None or "role" not in pts:
        return pd.DataFrame()
    gcp = set(pts.loc[pts["role"] == "control", "point"].astype(str))
    o = res.obs[(res.obs["kind"] == "image") & res.obs["point"].astype(str).isin(gcp)]
    if not len(o):
        return pd.DataFrame()
    px = pixel_um(res)
    unit = "px" if px else "µm"
    used = o[~o["rejected"].to_numpy(bool)]
    v = used["residual"].to_numpy(float) / (px or 1.0)
    rms = pd.Series(v * v).groupby(used["point"].astype(str).to_numpy()).mean() ** 0.5
    n = o.groupby(o["point"].astype(str))["photo"].nunique()
    return pd.DataFrame({"point": n.index, "images": n.to_numpy(),
                         f"reprojection RMS {unit}": rms.reindex(n.index).to_numpy()})
