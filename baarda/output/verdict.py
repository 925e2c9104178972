"""The verdict of a run, from its result files: one row per question a client asks first
(did it converge, did snooping finish, does the model fit, how large is sigma0, what do
the check points say, how many rejections against the false alarms to expect, what is
not controlled, did the camera calibration move, which GCPs and GNSS positions are
suspicious), each green, amber or red (or a note: a design fact with its remedy).

Rejections: each of the n tested components is a false alarm with probability alpha0, so
the count of false alarms is binomial(n, alpha0); the row warns when at least that many
rejections are improbable as false alarms alone (P < REJECTIONS_P).  Uncontrolled
components (r < 0.001): an error there goes wholly into the result; when they lie on tie
points seen on two photos only, such an error moves only its own point, by at most
delta0 x sigma_P for an error of delta0 standard deviations (|dX_k| = |g_ki| grad <=
grad sigma_Xk / sigma_i, since sigma_Xk^2 = sum_j g_kj^2 sigma_j^2): a note with the
remedy, a warning when they are many (> UNCONTROLLED_SHARE) or lie elsewhere (control,
check points, GNSS, IMU).

`verdict(summary, points)` reads summary.json (and points.csv for the check points); the
reports show it as their first page and the console prints `Verdict.lines()` as its last
lines, so both say the same.  `failures(summary)` are the red lines that keep a run from
being a result (the reports' banner).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.special import bdtrc, erfc  # bdtrc: the binomial survival function (binom.sf)

from baarda.kinds import CONTROL, GNSS, IMAGE

PASS, WARN, FAIL, INFO = "pass", "warn", "fail", "info"
WORDS = {PASS: "PASS", WARN: "REVIEW", FAIL: "FAIL", INFO: "NOTE"}
NOT_CONVERGED = ("NOT CONVERGED: the adjustment stopped before its corrections became "
                 "negligible; the coordinates, residuals and tests in this report are not a "
                 "least-squares solution")
MATERIAL = 0.2  # sigma0 off 1 by more than this (and significantly): the sigmas are off
CHECK_MISS = 3.0  # a check point misses when |d| exceeds this many standard deviations
REJECTIONS_P = 0.05  # at least this many false alarms less probable: the data held errors
UNCONTROLLED_SHARE = 0.05  # more uncontrolled components than this share: a weak design
CAMERA_MOVED = 3.0  # a camera parameter moved by more than this many standard deviations


@dataclass(frozen=True)
class Row:
    key: str  # the question (also the anchor's stem)
    status: str  # pass, warn, fail, info
    label: str  # the question in words
    text: str  # the answer in words
    section: str  # the id of the report section that shows the evidence


@dataclass(frozen=True)
class Verdict:
    rows: tuple[Row, ...]

    @property
    def status(self) -> str:
        """fail if any row fails, else warn if any warns, else pass."""
        got = {r.status for r in self.rows}
        return FAIL if FAIL in got else WARN if WARN in got else PASS

    @property
    def headline(self) -> str:
        bad = [r.label for r in self.rows if r.status == self.status]
        if self.status == PASS:
            return "PASS: every check of this run passed"
        return f"{WORDS[self.status]}: " + ", ".join(bad)

    def lines(self) -> list[str]:
        """The verdict as console lines: the headline, then one line per row."""
        return [f"quality check {self.headline}"] + [
            f"  {WORDS[r.status]:<6} {r.label}: {r.text}" for r in self.rows]


def _parts(summary: dict) -> dict[str, dict]:
    parts = summary.get("adjustments") or {"": summary}
    return {k: p for k, p in parts.items() if isinstance(p, dict)}


def failures(summary: dict) -> list[str]:
    """What keeps this run from being a result, in words: an adjustment that did not
    converge (with the solver's reason), snooping that stopped at its step limit."""
    parts = _parts(summary)
    out = []
    for name, p in parts.items():
        of = f" ({name})" if name and len(parts) > 1 else ""
        if p.get("converged", True) is False:
            why = [n for n in p.get("notes", []) if "diverged" in str(n)
                   or "not converged" in str(n)]
            out.append(NOT_CONVERGED + of + (f": {why[0]}" if why else ""))
        text = str(p.get("snooping_incomplete") or "")
        if text:  # "snooping incomplete: N component(s) still significant ..."
            head, _, rest = text.partition(":")
            out.append(f"{head.upper()}{of}:{rest}")
    return out


def _convergence(summary: dict) -> Row:
    bad = [f for f in failures(summary) if f.startswith("NOT CONVERGED")]
    if bad:
        return Row("convergence", FAIL, "Convergence", "; ".join(bad), "summary")
    it = summary.get("iterations")
    re_ = summary.get("readjustments")
    text = "converged" + (f" in {it} iterations" if it is not None else "")
    if re_:
        text += f", then {re_} re-adjustment(s) by data snooping"
    return Row("convergence", PASS, "Convergence", text, "summary")


def _snooping(summary: dict) -> Row:
    bad = [f for f in failures(summary) if not f.startswith("NOT CONVERGED")]
    if bad:
        return Row("snooping", FAIL, "Data snooping", "; ".join(bad), "log")
    if summary.get("snooping_converged") is None:
        return Row("snooping", INFO, "Data snooping", "not run (baarda adjust --snoop "
                   "tests and removes errors one at a time)", "log")
    n = sum(1 for s in summary.get("rejection_log") or [] if s.get("action") == "reject")
    return Row("snooping", PASS, "Data snooping", f"complete: {n} step(s) of rejection, "
               "no component left significant", "log")


def _global_test(summary: dict) -> Row:
    gt = summary.get("global_test")
    if not gt:
        return Row("global", INFO, "Global test", "not available in the results", "global")
    sigma0 = summary.get("sigma0", float("nan"))
    lo, hi = (gt.get("sigma0_interval") or [np.nan, np.nan])[:2]
    if not gt["passed"]:
        said = (f"REJECTED, the residuals are {sigma0:.2f} times as large as the a-priori "
                "sigmas predict: an error is left in the data or the sigmas are too small")
    elif np.isfinite(hi) and hi < 1.0:
        said = ("accepted (the test is one-sided: the residuals are not larger than the "
                f"a-priori sigmas predict); sigma0 {sigma0:.3f} is significantly below 1 "
                f"(95 % interval {lo:.3f} .. {hi:.3f}): the a-priori sigmas are pessimistic")
    else:
        said = "accepted, the residuals agree with the a-priori sigmas"
    text = (f"sigma0^2 = {gt['statistic']:.4f} against the critical {gt['critical']:.4f} "
            f"(alpha {gt['alpha']:g}, p = {gt['p_value']:.3g}): " + said)
    b = summary.get("global_test_b_method")
    if b and bool(b.get("passed")) != bool(gt["passed"]):
        text += (f"; the B-method's test (alpha {b['alpha']:.3g}, coupled to the w-tests) "
                 f"{'accepts' if b['passed'] else 'rejects'}: not the verdict, it is "
                 "shown because it shares the w-tests' power")
    return Row("global", PASS if gt["passed"] else FAIL, "Global test", text, "global")


def _sigma0(summary: dict, pixel_um: float | None, image_sigma_um: float | None) -> Row:
    s0 = summary.get("sigma0")
    if s0 is None or not np.isfinite(s0):
        return Row("sigma0", INFO, "sigma0", "not available", "summary")
    gt = summary.get("global_test") or {}
    lo, hi = (gt.get("sigma0_interval") or [np.nan, np.nan])[:2]
    text = f"sigma0 a posteriori {s0:.3f}"
    if np.isfinite(lo):
        text += f" (95 % interval {lo:.3f} .. {hi:.3f})"
    if image_sigma_um:
        um = s0 * image_sigma_um
        # the global sigma0 scales every group: not the image group's own estimate
        text += (f"; sigma0 x the a-priori image sigma {um:.2f} µm"
                 + (f" = {um / pixel_um:.2f} px" if pixel_um else "")
                 + f" against {image_sigma_um:g} µm"
                 + (f" = {image_sigma_um / pixel_um:.2f} px" if pixel_um else "")
                 + " a priori")
    if np.isfinite(lo) and lo > 1.0 and s0 > 1.0 + MATERIAL:
        return Row("sigma0", WARN, "sigma0", text + ": larger than a priori (the a-priori "
                   "sigmas are optimistic, or errors are left)", "summary")
    if np.isfinite(hi) and hi < 1.0 and s0 < 1.0 - MATERIAL:
        return Row("sigma0", WARN, "sigma0", text + ": smaller than a priori (the a-priori "
                   "sigmas are pessimistic: the tests are weaker than stated)", "summary")
    return Row("sigma0", PASS, "sigma0", text, "summary")


def check_point_misses(points: pd.DataFrame | None) -> pd.DataFrame:
    """The check points with a comparison: point, dX, dY, dZ (m), d (3D miss, m), sigma
    (3D standard deviation of the adjusted point, m), ratio d / sigma; worst first."""
    cols = ["point", "dX", "dY", "dZ", "d", "sigma", "ratio"]
    if points is None or "role" not in points or "dX" not in points:
        return pd.DataFrame(columns=cols)
    c = points[(points["role"] == "check")
               & points[["dX", "dY", "dZ"]].notna().all(axis=1)].copy()
    d = c[["dX", "dY", "dZ"]].to_numpy(float)
    c["d"] = np.sqrt(np.sum(d * d, axis=1))
    if {"sigma_X", "sigma_Y", "sigma_Z"} <= set(c.columns):
        s = c[["sigma_X", "sigma_Y", "sigma_Z"]].to_numpy(float)
        c["sigma"] = np.sqrt(np.sum(s * s, axis=1))
    else:
        c["sigma"] = np.nan
    with np.errstate(divide="ignore", invalid="ignore"):
        c["ratio"] = c["d"] / c["sigma"]
    return c[cols].sort_values("d", ascending=False).reset_index(drop=True)


def _check_points(summary: dict, points: pd.DataFrame | None) -> Row:
    miss = check_point_misses(points)
    n = len(miss) if points is not None else int(summary.get("n_check_points") or 0)
    if n == 0:
        return Row("check", WARN, "Check points", "none measured: the accuracy of the "
                   "result is not verified by independent points", "accuracy")
    rms = [summary.get(f"check_rms_{a}") for a in "XYZ"]
    text = f"{n} check point(s)"
    if all(r is not None for r in rms):
        text += f", RMS X {rms[0]:.3f} m, Y {rms[1]:.3f} m, Z {rms[2]:.3f} m"
    far = miss[miss["ratio"] > CHECK_MISS]
    if len(far):
        w = far.iloc[0]
        return Row("check", FAIL, "Check points", text + f"; check point {w['point']} misses "
                   f"by {w['d']:.3g} m, {w['ratio']:.0f} times the standard deviation of "
                   f"its adjusted position ({w['sigma']:.2g} m): the block's georeference "
                   "disagrees with it by that much (or the point's given coordinates or "
                   "its identification in the images are wrong)", "accuracy")
    if n < 3:
        return Row("check", WARN, "Check points", text + ": fewer than 3, too few for an "
                   "accuracy statement", "accuracy")
    return Row("check", PASS, "Check points", text + ", each within "
               f"{CHECK_MISS:g} standard deviations of its adjusted position", "accuracy")


def _rejected_of(summary: dict, kind: str) -> list[str]:
    """The observations of `kind` rejected in the end (the log's rejections less its
    restorations)."""
    out: dict[str, None] = {}
    for s in summary.get("rejection_log") or []:
        for o in s.get("observations") or []:
            if not str(o).startswith(kind + " "):
                continue
            if s.get("action") == "reject":
                out[str(o)] = None
            elif s.get("action") == "restore":
                out.pop(str(o), None)
    return list(out)


def _rejections(summary: dict) -> Row:
    n = int(summary.get("n_rejected") or 0)
    alpha0 = summary.get("alpha0")
    m = summary.get("n_observations")
    if alpha0 is None or not m:
        return Row("rejections", INFO, "Rejections", f"{n} rejected", "log")
    tested = int(m) + n
    expect = float(alpha0) * tested
    p = float(bdtrc(n - 1, tested, float(alpha0))) if n else 1.0
    text = (f"{n} observation component(s) rejected; alpha0 x n = {alpha0:g} x {tested}"
            f" = {expect:.2g} false alarms expected" + (
                f", P(at least {n} false alarms) = {p:.2g}" if n else ""))
    if p >= REJECTIONS_P:
        return Row("rejections", PASS, "Rejections", text + (
            ": as many as chance alone gives" if n else ""), "log")
    return Row("rejections", WARN, "Rejections", text + ": more than false alarms explain, "
               "the data held errors (they were removed; see the patterns)", "patterns")


def _uncontrolled(summary: dict, points: pd.DataFrame | None) -> Row:
    n = int(summary.get("n_uncontrolled") or 0)
    label = "Uncontrolled observations"
    if not n:
        return Row("uncontrolled", PASS, label, "none: every observation is checked by the "
                   "others", "reliability")
    sep = summary.get("separability") or {}
    comps = sep.get("uncontrolled_components") or []
    share = sep.get("share_uncontrolled")
    pct = ("" if share is None else f"{100 * share:.1f}" if 100 * share >= 0.1 else
           f"{100 * share:.2g}")
    of = f" ({pct} % of the active ones)" if share is not None else ""
    text = (f"{n} observation component(s){of} with redundancy number below 0.001: an error "
            "in them cannot be detected and goes wholly into the result")
    roles = {}
    if points is not None and "role" in points:
        roles = dict(zip(points["point"].astype(str), points["role"].astype(str),
                         strict=True))
    tie = [c for c in comps if c.get("component") in IMAGE.components
           and roles.get(str(c.get("point")), "tie") == "tie"]
    elsewhere = len(comps) - len(tie) if comps else n
    two = set(sep.get("two_ray_points") or [])
    pts = sorted({str(c["point"]) for c in tie})
    remedy = ("; remedy: measure them on a third photo (in the triple overlap of a strip or "
              "its neighbour), or plan 60 % side overlap or cross strips (baarda plan)")
    effect = _uncontrolled_effect(pts, points, summary.get("delta0"),
                                  length_unit(summary, points))
    if elsewhere:
        other = [c for c in comps if c not in tie]
        named = "; ".join(f"{c.get('point') or ''} {c.get('component')}".strip()
                          for c in other[:3]) + ("; ..." if len(other) > 3 else "")
        return Row("uncontrolled", WARN, label, text + f"; {elsewhere} of them not on tie "
                   "points' image coordinates" + (f" ({named})" if named else "") + ": "
                   "control, check points, GNSS, IMU or distances, where an undetected error "
                   "moves the georeference or the scale" + remedy, "reliability")
    where = (f"; all on {len(pts)} tie point(s)"
             + (f", {len(two & set(pts))} of them seen on two photos only" if two else "")
             + ": an error there moves only its own point" + effect)
    if share is not None and share > UNCONTROLLED_SHARE:
        return Row("uncontrolled", WARN, label, text + where + f"; more than "
                   f"{100 * UNCONTROLLED_SHARE:g} % of the block is not checked" + remedy,
                   "reliability")
    return Row("uncontrolled", INFO, label, text + where + " (a design fact of the block, "
               "not an error found)" + remedy, "reliability")


def length_unit(summary: dict, points: pd.DataFrame | None) -> tuple[str, float]:
    """The unit in which the reports state lengths of the object and its factor from
    metres: the project's own, "mm" where the reader converted the object coordinates from
    mm (AICON: "object coordinates mm -> m") or the points span less than 10 m (a
    close-range network), else "m"."""
    said = [str(n) for n in summary.get("notes", [])] + [
        str(line) for s in summary.get("sections", []) for line in s.get("lines", [])]
    if any("coordinates mm -> m" in n for n in said):
        return "mm", 1e3
    if points is not None and len(points) > 1 and {"X", "Y", "Z"} <= set(points.columns):
        xyz = points[["X", "Y", "Z"]].to_numpy(float)
        span = np.nanmax(xyz, axis=0) - np.nanmin(xyz, axis=0)
        if np.isfinite(span).all() and 0 < float(np.max(span)) < 10.0:
            return "mm", 1e3
    return "m", 1.0


def _uncontrolled_effect(pts: list[str], points: pd.DataFrame | None, delta0,
                         unit: tuple[str, float] = ("m", 1.0)) -> str:
    """', by at most .. m (point ..) for an error of delta0 standard deviations': the bound
    delta0 x sigma_P (module docstring) over the uncontrolled tie points."""
    need = {"point", "sigma_X", "sigma_Y", "sigma_Z"}
    if not pts or points is None or not need <= set(points.columns) or not delta0:
        return ""
    p = points[points["point"].astype(str).isin(pts)]
    s = np.sqrt(np.sum(p[["sigma_X", "sigma_Y", "sigma_Z"]].to_numpy(float) ** 2, axis=1))
    if not np.isfinite(s).any():
        return ""
    i = int(np.nanargmax(s))
    return (f", by at most {float(delta0) * s[i] * unit[1]:.3g} {unit[0]} (point "
            f"{p['point'].iloc[i]}) for an "
            f"error of {float(delta0):.2f} standard deviations, the size the w-test finds "
            "in a checked observation")


def _suspicious(summary: dict, kind: str, label: str, section: str,
                n_tested: int | None = None) -> Row | None:
    """The rejected components of `kind`; with `n_tested` (the kind's tested components)
    a count that false alarms explain (P >= REJECTIONS_P) passes, named."""
    if kind not in (summary.get("observation_groups") or {}) and not _rejected_of(summary,
                                                                                  kind):
        return None
    rej = _rejected_of(summary, kind)
    if not rej:
        return Row(kind, PASS, label, "none rejected", section)
    shown = "; ".join(r[len(kind) + 1:] for r in rej[:6]) + ("; ..." if len(rej) > 6 else "")
    text = f"{len(rej)} component(s) rejected: {shown}"
    alpha0 = summary.get("alpha0")
    if n_tested and alpha0 is not None:
        n = max(n_tested, len(rej))
        p = float(bdtrc(len(rej) - 1, n, float(alpha0)))
        text += f"; P(at least {len(rej)} false alarms among {n} components) = {p:.2g}"
        if p >= REJECTIONS_P:
            return Row(kind, PASS, label, text + ": as many as chance alone gives (the "
                       "rejected component is left out; check it in the field if in doubt)",
                       section)
    return Row(kind, WARN, label, text, section)


def _suspicious_gcps(summary: dict, points: pd.DataFrame | None) -> Row | None:
    """The rejected control components (`_suspicious`) and the rejected image measurements
    of control and check points, named by GCP and photo (a GCP marked in the wrong place on
    an image, `--gcp-list`): a warning unless chance explains the largest |w| among the
    GCPs' image components (2 x their rays, points.csv): P(max |w| >= it) >= REJECTIONS_P
    passes, named."""
    row = _suspicious(summary, CONTROL.name, "Suspicious GCPs", CONTROL.name,
                      _control_components(summary, points))
    marks = _gcp_marks_rejected(summary, points)
    if not marks:
        return row
    shown = "; ".join(m for m, _ in marks[:6]) + ("; ..." if len(marks) > 6 else "")
    text = f"{len(marks)} image measurement(s) of GCPs rejected: {shown}"
    status = WARN
    assert points is not None  # marks come from its roles
    ws = [abs(v) for _, v in marks if np.isfinite(v)]
    if "rays" in points and ws:
        gcp = points["role"].isin(("control", "check")).to_numpy()
        n = max(2 * int(np.nansum(points.loc[gcp, "rays"].to_numpy(float))), len(marks))
        w = max(ws)
        p = float(-np.expm1(n * np.log1p(-erfc(w / np.sqrt(2)))))
        text += f"; P(|w| >= {w:.2f} among the GCPs' {n} image components) = {p:.2g}"
        if p >= REJECTIONS_P:
            status = PASS
            text += ": chance alone gives as much (left out; remeasure it if in doubt)"
    if status == WARN:
        text += ": marked in the wrong place on the image? remeasure it"
    if row is not None and row.text != "none rejected":
        text = f"{row.text}; {text}"
        status = WARN if row.status == WARN else status
    return Row(CONTROL.name, status, "Suspicious GCPs", text, CONTROL.name)


def _gcp_marks_rejected(summary: dict,
                        points: pd.DataFrame | None) -> list[tuple[str, float]]:
    """('GCP3 on photo IMG_0004 (x)', its w when rejected) for each image component of a
    control or check point rejected in the end (labels 'image photo P point Q c')."""
    if points is None or "role" not in points:
        return []
    gcp = set(points.loc[points["role"].isin(("control", "check")), "point"].astype(str))
    value = {str(o): float(st.get("value") or np.nan)
             for st in summary.get("rejection_log") or [] if st.get("action") == "reject"
             for o in st.get("observations") or []}
    out = []
    for label in _rejected_of(summary, IMAGE.name):
        head, _, comp = label.rpartition(" ")
        photo, sep, point = head.removeprefix(f"{IMAGE.name} photo ").partition(" point ")
        if sep and point in gcp:
            out.append((f"{point} on photo {photo} ({comp})", value.get(label, np.nan)))
    return out


def _control_components(summary: dict, points: pd.DataFrame | None) -> int | None:
    """The control components tested: the control points times the control axes."""
    axes = (summary.get("observation_groups") or {}).get(CONTROL.name) or {}
    if points is None or "role" not in points or not axes:
        return None
    return int((points["role"] == "control").sum()) * len(axes)


def _camera(summary: dict) -> Row | None:
    """The estimated camera parameters against their given values: a change of more than
    CAMERA_MOVED standard deviations means the given calibration does not hold for this
    block (the largest such change named)."""
    cal = [c for c in summary.get("calibration") or [] if c.get("estimated")
           and c.get("sigma") and c.get("initial") is not None]
    if not cal:
        return None
    moved = []
    for c in cal:
        d = float(c["value"]) - float(c["initial"])
        z = abs(d) / float(c["sigma"])
        rel = f", {100 * d / abs(float(c['initial'])):+.1f} %" if c["initial"] else ""
        moved.append((z, f"{c['parameter']} of camera {c['camera']} by {d:+.4g}{rel} "
                         f"({z:.1f} standard deviations)"))
    moved.sort(key=lambda m: -m[0])
    far = [t for z, t in moved if z > CAMERA_MOVED]
    n = len({c["camera"] for c in cal})
    if far:
        return Row("camera", WARN, "Camera calibration", f"moved from its given values by "
                   f"more than {CAMERA_MOVED:g} standard deviations: " + "; ".join(far[:3])
                   + ("; ..." if len(far) > 3 else "") + ": the given calibration does not "
                   "hold for this block (check the camera assigned to the photos; use the "
                   "adjusted calibration)", "camera")
    return Row("camera", PASS, "Camera calibration", f"{len(cal)} parameter(s) of {n} "
               f"camera(s) estimated, each within {CAMERA_MOVED:g} standard deviations of its "
               f"given value (largest: {moved[0][1]})", "camera")


def verdict(summary: dict, points: pd.DataFrame | None = None, *,
            pixel_um: float | None = None, image_sigma_um: float | None = None) -> Verdict:
    """The verdict of a run from summary.json and points.csv (for the check points;
    without it the check-point row gives the summary's RMS only); `pixel_um` and
    `image_sigma_um` put sigma0 in pixels."""
    rows = [_convergence(summary), _snooping(summary), _global_test(summary),
            _sigma0(summary, pixel_um, image_sigma_um), _check_points(summary, points),
            _rejections(summary), _uncontrolled(summary, points)]
    rows += [r for r in (_camera(summary),
                         _suspicious_gcps(summary, points),
                         _suspicious(summary, GNSS.name, "Suspicious GNSS positions", GNSS.name))
             if r is not None]
    return Verdict(tuple(rows))
