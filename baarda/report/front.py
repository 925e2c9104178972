"""The first pages of every report, from the result files: the quality check
(output/verdict.py), the accuracy statement on the check points, the metadata a client
signs off, and the patterns in the rejections with advice.

Accuracy statement: the ASPRS Positional Accuracy Standards, Edition 2 (2023), with the
NSSDA figures as a legacy block (output/accuracy.py); from points.csv and what summary.json's
`accuracy` records beside it (the check points' survey accuracy, the covariance of their
mean from the adjustment, the datum of the comparison).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pandas as pd

from baarda.io.result_folder import Results
from baarda.kinds import EXTERIOR, GNSS
from baarda.output.accuracy import CONTROL, FREE_NONE, FREE_SIMILARITY, Statement, Survey, statement
from baarda.output.verdict import WORDS, Verdict, check_point_misses, verdict
from baarda.output.verdict import length_unit as verdict_length_unit


def pixel_um(res: Results) -> float | None:
    """The pixel size (µm) of a result folder (summary_pixel_um)."""
    return summary_pixel_um(res.summary)


def summary_pixel_um(summary: dict) -> float | None:
    """The pixel size (µm): the cameras' own where the source states it (DBAT, MicMac; one
    size for every camera), else the nominal one a reader stated in the notes (COLMAP, BAL,
    OpenSfM)."""
    sizes = {c.get("pixel_mm") for c in summary.get("cameras", [])}
    if len(sizes) == 1 and None not in sizes:
        return float(sizes.pop()) * 1e3
    lines = [line for s in summary.get("sections", []) for line in s.get("lines", [])]
    for n in list(summary.get("notes", [])) + lines:
        m = re.search(r"nominal pixel size ([0-9.eE+-]+) mm", str(n))
        if m:
            try:
                return float(m.group(1)) * 1e3
            except ValueError:
                return None
    return None


def length_unit(res: Results) -> tuple[str, float]:
    """The unit of the object's lengths in the report and its factor from metres
    (output/verdict.length_unit: the project's own, mm for a close-range network)."""
    return verdict_length_unit(res.summary, res.points)


def row_units(res: Results, kinds, length: tuple[str, float] | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """Per observation row of `kinds`: the unit its residual, sigma and MDB are shown in
    (the kind's own, lengths in metres in the project's length unit) and the factor from
    observations.csv's values to it.  length: `length_unit(res)` where the caller has it
    (not worked out again)."""
    name, f = length if length is not None else length_unit(res)
    units = res.units
    u = np.array([units.get(str(k), "") for k in kinds], dtype=object)
    factor = np.where(u == "m", f, 1.0)
    return np.where(u == "m", name, u), factor


def image_sigma_um(res: Results) -> float | None:
    """The a-priori image sigma (µm): the median of the image rows' sigma."""
    s = res.obs.loc[res.obs["kind"] == "image", "sigma"].to_numpy(float)
    s = s[np.isfinite(s)]
    return float(np.median(s)) if len(s) else None


def quality_check(res: Results) -> Verdict:
    return verdict(res.summary, res.points, pixel_um=pixel_um(res),
                   image_sigma_um=image_sigma_um(res))


def folder_quality_check(folder, image_sigma_um: float | None) -> Verdict:
    """The quality check of a result folder from its summary.json and points.csv alone (the
    console's last lines after a run: the same rows as the reports' first section, without
    reading observations.csv back); `image_sigma_um`: the median a-priori image sigma."""
    import json
    from pathlib import Path

    from baarda.output.verdict import verdict

    folder = Path(folder)
    summary = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    points = None
    if (folder / "points.csv").is_file():
        points = pd.read_csv(folder / "points.csv", dtype={"point": str, "role": str},
                             keep_default_na=False, na_values=[""])
        from baarda.io.run_manifest import written_excel_safe
        from baarda.io.table import unquoted_formulas

        if written_excel_safe(folder) and "point" in points:
            points["point"] = unquoted_formulas(points["point"].to_numpy(str))
    return verdict(summary, points, pixel_um=summary_pixel_um(summary),
                   image_sigma_um=image_sigma_um)


FALLBACK = {"control": "calibration", GNSS.name: "calibration", "camera": "calibration",
            "global": "summary", "log": "summary", "patterns": "log", "reliability": "observations",
            "observations": "summary", "accuracy": "check"}


def check_view(v: Verdict, ids: set[str] | None = None) -> dict:
    """The verdict for the template's `check` macro; `ids`: the element ids of the page
    (a row whose section the page lacks links to the nearest one it has)."""
    def target(s: str) -> str:
        seen = set()
        while ids is not None and s not in ids and s in FALLBACK and s not in seen:
            seen.add(s)
            s = FALLBACK[s]
        return s if ids is None or s in ids else "check"

    return {"status": v.status, "headline": v.headline,
            "rows": [{"status": r.status, "word": WORDS[r.status], "label": r.label,
                      "text": r.text, "section": target(r.section)} for r in v.rows]}


def run_notes(res: Results) -> list[str]:
    """The run's notes, each once: the readers' and the adjustment's (summary.json 'notes'
    and the summary's 'note:' lines: rows and points left out, defaults used) and the
    report's own about missing files."""
    lines = [line[len("note: "):] for s in res.sections for line in s.lines
             if line.startswith("note: ")]
    return list(dict.fromkeys(str(n) for n in [*lines, *res.summary.get("notes", []),
                                               *res.notes]))


def section_line(res: Results, start: str) -> str | None:
    """The first summary line that starts with `start` (e.g. 'datum:')."""
    return next((line for s in res.sections for line in s.lines if line.startswith(start)),
                None)


def accuracy(res: Results) -> Statement:
    """The accuracy statement on the check points (output/accuracy.py): the misses of
    points.csv, the survey accuracy, the mean's covariance and the datum summary.json
    records (a result folder without them: no survey accuracy and no test of the mean; the
    datum from the summary's datum line)."""
    miss = check_point_misses(res.points)
    rec = res.summary.get("accuracy") or {}
    datum = rec.get("datum")
    if datum not in (CONTROL, FREE_SIMILARITY, FREE_NONE):
        free = "FREE NETWORK" in (section_line(res, "datum:") or "").upper()
        compared = int(res.summary.get("n_check_points") or 0)
        datum = CONTROL if not free else FREE_SIMILARITY if compared >= 3 else FREE_NONE
    cov = rec.get("mean_covariance_m2")
    return statement(miss, datum, Survey.from_dict(rec.get("survey")),
                     None if cov is None else np.asarray(cov, float))


def metadata(res: Results) -> list[tuple[str, str]]:
    """What a client signs off: date, version, input and its checksum, CRS and heights,
    datum, a-priori sigmas, tests, options."""
    s, m = res.summary, res.manifest
    crs = s.get("crs") or {}
    inp = s.get("input") or {}
    out = [("project", res.title),
           ("processed", str(m.get("finished") or m.get("started") or "not recorded")),
           ("baarda version", str(m.get("baarda") or "not recorded")),
           ("run", str(res.run or "not recorded")),
           ("input", str(inp.get("path") or s.get("source") or "?")),
           ("input checksum (SHA-256)", f"{inp['sha256']} ({inp['files']} file(s), "
            f"{inp['bytes']:,} bytes)" if inp.get("sha256") else "not recorded")]
    if crs:
        name = crs.get("name", "?")
        epsg = f" (EPSG:{crs['epsg']})" if crs.get("epsg") else ""
        out.append(("coordinate reference system", f"{name}{epsg}"))
        out.append(("heights", f"{crs['heights']} heights" if crs.get("heights")
                    else "as given (vertical datum not stated)"))
        out.append(("adjusted in", str(crs.get("adjusted_in", ""))))
    else:
        out.append(("coordinate reference system", "none given: local coordinates as in "
                    "the input (vertical datum not stated)"))
    for key, start in (("datum definition", "datum:"), ("a-priori sigmas", "a-priori "
                                                                          "sigmas:")):
        line = section_line(res, start)
        if line:
            out.append((key, line[len(start):].strip()))
    if s.get("alpha0") is not None:
        gt = s.get("global_test") or {}
        out.append(("tests", f"alpha0 {s['alpha0']:g}, beta0 {s.get('beta0', 0):g} "
                    f"(w-test critical |w| {res.k_w:.2f}); global test at alpha "
                    f"{gt.get('alpha', float('nan')):g}"))
    if m.get("command"):
        out.append(("command", str(m["command"])))
    return out


@dataclass
class Advice:
    what: str
    remedy: str
    where: str


def _strip_of(res: Results, photos: pd.Series) -> np.ndarray:
    key = {str(k): str(v) for k, v in res.strip_of().items()}
    return np.array([key.get(p, "") for p in photos.astype(str)], dtype=object)


def rejected_table(res: Results) -> pd.DataFrame:
    """The rejected observations: kind, photo, strip, point, component, sign of the
    residual, w."""
    o = res.obs[res.obs["rejected"].to_numpy(bool)]
    t = pd.DataFrame({"kind": o["kind"].astype(str), "photo": o["frame"].astype(str),
                      "point": o["point"].astype(str), "component": o["component"].astype(str),
                      "sign": np.where(o["residual"].to_numpy(float) < 0, "-", "+"),
                      "w": o["w"].to_numpy(float)})
    t["strip"] = _strip_of(res, t["photo"])
    return t.reset_index(drop=True)


def patterns(res: Results) -> tuple[pd.DataFrame, list[Advice]]:
    """The rejections grouped by kind, component and sign, and by photo and strip (a
    table), and advice where they form a pattern (what, remedy, where)."""
    t = rejected_table(res)
    if not len(t):
        return pd.DataFrame(), []
    rows = []
    for (k, c, sg), g in t.groupby(["kind", "component", "sign"], sort=True):
        ph = g["photo"].value_counts()
        st = g["strip"].value_counts()
        rows.append({"kind": k, "component": c, "residual sign": sg, "rejected": len(g),
                     "photos": len(ph), "most on photo": f"{ph.index[0]} ({ph.iloc[0]})"
                     if ph.index[0] else "", "strips": ", ".join(
                         f"{s} ({n})" for s, n in st.items() if s)[:60]})
    groups = pd.DataFrame(rows).sort_values("rejected", ascending=False, kind="stable")
    advice: list[Advice] = []
    img = t[t["kind"] == "image"]
    if len(img) >= 4:
        cs = img.groupby(["component", "sign"]).size()
        (c, sg), top = cs.idxmax(), int(cs.max())
        if top >= 0.8 * len(img):
            advice.append(Advice(
                f"{top} of the {len(img)} image rejections are {c} with "
                f"{'negative' if sg == '-' else 'positive'} residuals: a systematic error, "
                "not random blunders",
                f"check the image coordinate system (a shifted or mirrored {c} axis, the "
                f"principal point {c}0) or estimate the interior orientation and distortion "
                "(self-calibration)", "image " + c))
        ph = img["photo"].value_counts()
        if ph.iloc[0] >= 3 and ph.iloc[0] >= 0.4 * len(img):
            advice.append(Advice(
                f"photo {ph.index[0]} holds {ph.iloc[0]} of the {len(img)} image rejections",
                "check this photo's measurements and interior orientation (fiducials, film "
                "or scan deformation, the camera assigned to it); re-measure its points",
                f"photo {ph.index[0]}"))
    for kind, name in ((k.name, k.words) for k in EXTERIOR):
        g = t[t["kind"] == kind]
        if len(g) < 3:
            continue
        by = g.groupby(["strip", "component"]).size()
        (s, c), top = by.idxmax(), int(by.max())
        n_strip = int((res.photos["strip"].astype(str) == s).sum()) if (
            res.photos is not None and s) else 0
        if s and top >= 3 and top >= 0.5 * n_strip:
            remedy = ('a shift per strip: [gnss] offsets = "strip" in the project settings '
                      "(an along-track GNSS error of the strip is then estimated, not "
                      "rejected)" if kind == GNSS.name else
                      "boresight or drift parameters per strip for the IMU attitudes")
            advice.append(Advice(f"{name} {c} of {top} of the {n_strip} photos of strip {s} "
                                 "rejected: a systematic error of the strip, not blunders",
                                 remedy, f"strip {s}"))
    c = t[t["kind"] == "control"]
    if len(c):
        pts = list(dict.fromkeys(c["point"]))
        advice.append(Advice(
            f"{len(c)} control component(s) rejected at {len(pts)} GCP(s)",
            "check these GCPs' given coordinates (a typing error, another datum) and their "
            "identification in the images (a moved or mis-identified marker); a GCP that "
            "is wrong should become a check point or be left out",
            ", ".join(f"GCP {p}" for p in pts[:10])))
    return groups, advice
