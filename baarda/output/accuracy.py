"""The accuracy statement on the check points by the ASPRS Positional Accuracy Standards for
Digital Geospatial Data, Edition 2 (2023), with the legacy NSSDA figures beside it.

Edition 2 (adopted August 2023) states accuracy as RMSE only (no 95 % confidence figures):

- the product's fit to the check points: RMSE_X, RMSE_Y, RMSE_V1 = RMSE_Z of the misses
  (adjusted - given) and RMSE_H1 = sqrt(RMSE_X^2 + RMSE_Y^2);
- the check points' own survey accuracy: RMSE_H2 = sqrt(mean(sigma_X^2 + sigma_Y^2)) and
  RMSE_V2 = sqrt(mean(sigma_Z^2)) from the check points' sigmas (ground_points.csv);
- the product's accuracy: RMSE_H = sqrt(RMSE_H1^2 + RMSE_H2^2), RMSE_V likewise, and the
  three-dimensional RMSE_3D = sqrt(RMSE_H^2 + RMSE_V^2);
- at least 30 check points (at most 120 are needed on large projects); below 30 the
  reduced-checkpoint statement; here no figure at all from fewer than 3;
- the mean error per axis is investigated when it exceeds 25 % of that axis's RMSE;
- the class met: Edition 2's classes are open (an X-cm class: RMSE <= X cm); the statement
  names the smallest whole centimetre (below 1 cm: the smallest tenth) the figure meets.

Besides the standard's rule, the mean miss per axis is tested against its standard deviation
from the adjustment (bundle/check_mean.py: the adjusted check points are correlated, they
share the datum the control defines, so std / sqrt(n) understates it) plus the survey's.

Legacy (NSSDA, FGDC-STD-007.3-1998; ASPRS Edition 1, 2014): horizontal at 95 % = 1.7308
RMSE_r (for RMSE_X about equal to RMSE_Y), vertical at 95 % = 1.9600 RMSE_Z; CE90 = 1.5175
RMSE_r, LE90 = 1.6449 RMSE_Z; from the fit to the check points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from baarda.quality.special_distributions import norm_ppf

STANDARD = ("ASPRS Positional Accuracy Standards for Digital Geospatial Data, Edition 2 "
            "(2023)")
LEGACY = "NSSDA (FGDC-STD-007.3-1998) and ASPRS Positional Accuracy Standards, Edition 1 (2014)"
MIN_CHECK = 30  # Edition 2: at least 30 check points
MAX_CHECK = 120  # Edition 2: at most 120 are needed, however large the project
MIN_STATEMENT = 3  # no accuracy figure from fewer check points
MEAN_SHARE = 0.25  # Edition 2: a mean error above 25 % of the RMSE is investigated
MEAN_ALPHA = 0.05  # the two-sided test of the mean miss per axis
NSSDA_H95 = 1.7308
NSSDA_V95 = 1.9600
CE90 = 1.5175
LE90 = 1.6449

TABLE_FORMATS = {"mean m": ".3f", "std m": ".3f", "RMSE m": ".3f", "largest |d| m": ".3f",
                 "25 % of RMSE m": ".3f", "sd of mean m": ".3f", "mean / sd": ".1f"}

# datum of the comparison
CONTROL, FREE_SIMILARITY, FREE_NONE = "control", "free, similarity", "free, no similarity"


@dataclass(frozen=True)
class Survey:
    """The check points' survey accuracy: the RMS of their given standard deviations per axis
    (m; None where a check point lacks that sigma) and how many lack the horizontal
    (sigma_X, sigma_Y) and the vertical (sigma_Z) ones."""

    rms_x: float | None
    rms_y: float | None
    rms_z: float | None
    missing_h: int
    missing_v: int

    @property
    def rmse_h2(self) -> float | None:
        """RMSE_H2 = sqrt(mean(sigma_X^2 + sigma_Y^2)) (m)."""
        if self.rms_x is None or self.rms_y is None:
            return None
        return float(np.hypot(self.rms_x, self.rms_y))

    @property
    def rmse_v2(self) -> float | None:
        """RMSE_V2 = sqrt(mean(sigma_Z^2)) (m)."""
        return self.rms_z

    def to_dict(self) -> dict:
        return {"rms_sigma_m": [self.rms_x, self.rms_y, self.rms_z],
                "rmse_h2_m": self.rmse_h2, "rmse_v2_m": self.rmse_v2,
                "without_sigma_h": self.missing_h, "without_sigma_v": self.missing_v}

    @classmethod
    def from_dict(cls, d: dict | None) -> Survey | None:
        if not d or len(d.get("rms_sigma_m") or []) != 3:
            return None
        x, y, z = (None if v is None else float(v) for v in d["rms_sigma_m"])
        return cls(x, y, z, int(d.get("without_sigma_h", 0)), int(d.get("without_sigma_v", 0)))


def survey_accuracy(sigma: np.ndarray) -> Survey:
    """The survey accuracy from the given standard deviations (n, 3) of the check points'
    coordinates (m; NaN: not given); an axis is None unless every check point has it."""
    s = np.asarray(sigma, float).reshape(-1, 3)
    rms = [float(np.sqrt(np.mean(s[:, k] ** 2))) if len(s) and np.isfinite(s[:, k]).all()
           else None for k in range(3)]
    return Survey(rms[0], rms[1], rms[2], int((~np.isfinite(s[:, :2]).all(axis=1)).sum()),
                  int((~np.isfinite(s[:, 2])).sum()))


def accuracy_class_cm(rmse_m: float) -> float:
    """The smallest class (cm) an RMSE meets: whole centimetres, tenths below 1 cm."""
    cm = rmse_m * 100.0
    step = 1.0 if cm >= 1.0 else 0.1
    return round(math.ceil(round(cm / step, 9)) * step, 1)


def _num(v) -> float | None:
    return float(v) if v is not None and np.isfinite(v) else None


def _cm(v: float) -> str:
    return f"{v:g}"


@dataclass(frozen=True)
class Statement:
    """The accuracy statement of a result: `n` check points, `table` per axis (n, mean,
    std, RMSE, largest miss, 25 % of the RMSE, the mean's standard deviation from the
    adjustment), `figures` (m; None where not stated), the standard's sentences, the legacy
    figures, warnings (the reasons no figure is given among them) and the misses."""

    n: int
    datum: str
    table: pd.DataFrame
    figures: dict
    sentences: list[str]
    legacy: dict  # NSSDA / ASPRS 2014 (m): horizontal_95_m, vertical_95_m, ce90_m, le90_m
    warnings: list[str] = field(default_factory=list)
    misses: pd.DataFrame | None = None
    survey: Survey | None = None
    mean_covariance: np.ndarray | None = None

    @property
    def stated(self) -> bool:
        """Whether figures are stated (at least MIN_STATEMENT check points compared)."""
        return bool(self.figures)

    @property
    def statements(self) -> list[tuple[str, str]]:
        """(what, value) rows of the reports (lines)."""
        return self.lines()

    def lines(self) -> list[tuple[str, str]]:
        """(what, value) rows: the standard, the check points, the figures, the legacy."""
        if not self.stated:
            return [("standard", STANDARD)]
        f = self.figures
        many = (f"; more than the {MAX_CHECK} needed on the largest projects, all used"
                if self.n > MAX_CHECK else f" (at most {MAX_CHECK} on large projects)")
        out = [("standard", STANDARD),
               ("check points", f"{self.n}: Edition 2 asks for at least {MIN_CHECK}{many}")]
        for k, name in (("h", "RMSE_H (horizontal)"), ("v", "RMSE_V (vertical)")):
            fit, survey = f[f"rmse_{k}1_m"], f[f"rmse_{k}2_m"]
            u = k.upper()
            parts = (f"fit RMSE_{u}1 {fit:.4f} m, survey RMSE_{u}2 {survey:.4f} m"
                     if survey is not None else f"the fit (RMSE_{u}1) alone, no survey "
                     "accuracy")
            out.append((name, f"{f[f'rmse_{k}_m']:.3f} m: {parts}"))
        out.append(("RMSE_3D (three-dimensional)", f"{f['rmse_3d_m']:.3f} m"))
        lg = self.legacy
        out.append(("legacy (NSSDA 1998, ASPRS 2014)",
                    f"at 95 %: horizontal {lg['horizontal_95_m']:.3f} m, vertical "
                    f"{lg['vertical_95_m']:.3f} m; CE90 {lg['ce90_m']:.3f} m, LE90 "
                    f"{lg['le90_m']:.3f} m"))
        return out

    def statement_text(self) -> str:
        """The standard's sentences as one paragraph (the reduced-checkpoint statement's
        opening once)."""
        if not self.sentences:
            return ""
        if self.n >= MIN_CHECK:
            return " ".join(self.sentences)
        cut = self.sentences[0].index("This data set was produced to meet")
        return " ".join([self.sentences[0]] + [x[cut:] for x in self.sentences[1:]])

    def to_dict(self) -> dict:
        """summary.json's `accuracy`."""
        return {"standard": STANDARD, "n_check_points": self.n, "datum": self.datum,
                **({"minimum_check_points": MIN_CHECK, "maximum_check_points_needed":
                    MAX_CHECK} if self.stated else {}),
                "figures": dict(self.figures), "statements": list(self.sentences),
                "mean_error": [{"axis": r["axis"], "mean_m": _num(r["mean m"]),
                                "rmse_m": _num(r["RMSE m"]),
                                "quarter_rmse_m": _num(r["25 % of RMSE m"]),
                                "sd_of_mean_m": _num(r["sd of mean m"]),
                                "mean_over_sd": _num(r["mean / sd"])}
                               for r in self.table.to_dict("records")],
                "legacy": {"standard": LEGACY, **self.legacy} if self.stated else None,
                "warnings": list(self.warnings),
                "survey": self.survey.to_dict() if self.survey else None,
                "mean_covariance_m2": None if self.mean_covariance is None
                else np.asarray(self.mean_covariance).tolist()}


def _sentences(n: int, h: float, v: float, d3: float) -> list[str]:
    """The standard's statements: 'tested to meet' with 30 check points or more, else the
    reduced-checkpoint statement."""
    ch, cv, c3 = (_cm(accuracy_class_cm(x)) for x in (h, v, d3))
    th, tv, t3 = (f"{100 * x:.1f}" for x in (h, v, d3))
    if n >= MIN_CHECK:
        opening = f"This data set was tested to meet {STANDARD} for a "
        return [opening + f"{ch} (cm) RMSE_H Horizontal Positional Accuracy Class. The tested "
                f"horizontal positional accuracy was found to be RMSE_H = {th} (cm).",
                opening + f"{cv} (cm) RMSE_V Vertical Accuracy Class. NVA accuracy was found "
                f"to be RMSE_V = {tv} (cm).",
                opening + f"{c3} (cm) RMSE_3D Three-Dimensional Positional Accuracy Class. The "
                f"tested three-dimensional accuracy was found to be RMSE_3D = {t3} (cm)."]
    opening = (f"This data set was tested as required by {STANDARD}. Although the Standards "
               f"call for a minimum of thirty (30) checkpoints, this test was performed using "
               f"ONLY {n} checkpoints. This data set was produced to meet a ")
    tail = " using the reduced number of checkpoints."
    return [opening + f"{ch} (cm) RMSE_H Horizontal Positional Accuracy Class. The tested "
            f"horizontal positional accuracy was found to be RMSE_H = {th} (cm)" + tail,
            opening + f"{cv} (cm) RMSE_V Vertical Accuracy Class. NVA accuracy was found to "
            f"be RMSE_V = {tv} (cm)" + tail,
            opening + f"{c3} (cm) RMSE_3D Three-Dimensional Positional Accuracy Class. The "
            f"tested three-dimensional accuracy was found to be RMSE_3D = {t3} (cm)" + tail]


def statement(misses: pd.DataFrame, datum: str = CONTROL, survey: Survey | None = None,
              mean_covariance: np.ndarray | None = None) -> Statement:
    """The accuracy statement on the check points' `misses` (output/verdict.py
    check_point_misses: point, dX, dY, dZ in m); `datum`: CONTROL, FREE_SIMILARITY (compared
    after a similarity onto the check points) or FREE_NONE (a free network with too few
    check points for that similarity); `survey`: their survey accuracy (survey_accuracy);
    `mean_covariance`: (3, 3) covariance (m^2) of the mean adjusted X, Y, Z of the check
    points from the adjustment (bundle/check_mean.py), scaled by sigma0."""
    n = len(misses)
    warn: list[str] = []

    def bare(reason: list[str]) -> Statement:
        return Statement(n, datum, pd.DataFrame(), {}, [], {}, warn + reason, misses, survey,
                         mean_covariance)

    if datum == FREE_NONE:
        warn.append(f"The datum is free (no control) and only {n} check point(s) were "
                    f"compared: the 7-parameter similarity transformation onto the check "
                    f"points needs at least 3 (not collinear), so none was applied; their "
                    "differences below refer to the arbitrary free datum and state no "
                    "accuracy.")
    elif datum == FREE_SIMILARITY:
        warn.append("The datum is free (no control): the check points are compared after a "
                    "7-parameter similarity transformation onto them, so these figures "
                    "describe the block's shape, not its georeference, and their mean is "
                    "zero by construction.")
    if n == 0:
        return bare(["No check points were measured: the accuracy of the result is not "
                     "verified by independent points; the standard deviations of the "
                     "adjusted points are the only statement of accuracy."])
    if n < MIN_STATEMENT or datum == FREE_NONE:
        return bare([f"Only {n} check point(s): fewer than {MIN_STATEMENT}, so no accuracy "
                     "figure is stated; the misses of the check points are listed below."]
                    if n < MIN_STATEMENT else [])
    d = misses[["dX", "dY", "dZ"]].to_numpy(float)
    rmse = np.sqrt(np.mean(d * d, axis=0))
    mean = d.mean(axis=0)
    std = d.std(axis=0, ddof=1)
    sd_mean = np.full(3, np.nan)
    if mean_covariance is not None and datum == CONTROL:
        var = np.diag(np.asarray(mean_covariance, float)).copy()
        if survey is not None:  # the survey's errors: independent per point
            rms = np.array([np.nan if r is None else r
                            for r in (survey.rms_x, survey.rms_y, survey.rms_z)])
            var += np.where(np.isfinite(rms), rms ** 2, 0.0) / n
        sd_mean = np.sqrt(var)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = mean / sd_mean
    table = pd.DataFrame({"axis": list("XYZ"), "n": n, "mean m": mean, "std m": std,
                          "RMSE m": rmse, "largest |d| m": np.abs(d).max(axis=0),
                          "25 % of RMSE m": MEAN_SHARE * rmse, "sd of mean m": sd_mean,
                          "mean / sd": z})
    h1, v1 = float(np.hypot(rmse[0], rmse[1])), float(rmse[2])
    h2 = survey.rmse_h2 if survey else None
    v2 = survey.rmse_v2 if survey else None
    h = float(np.hypot(h1, h2)) if h2 is not None else h1
    v = float(np.hypot(v1, v2)) if v2 is not None else v1
    d3 = float(np.hypot(h, v))
    figures = {"rmse_x_m": float(rmse[0]), "rmse_y_m": float(rmse[1]),
               "rmse_h1_m": h1, "rmse_v1_m": v1, "rmse_h2_m": h2, "rmse_v2_m": v2,
               "rmse_h_m": h, "rmse_v_m": v, "rmse_3d_m": d3,
               "class_h_cm": accuracy_class_cm(h), "class_v_cm": accuracy_class_cm(v),
               "class_3d_cm": accuracy_class_cm(d3)}
    missing = [] if survey is None else [
        f"{k} of the {n} check points lack {w}" for k, w in (
            (survey.missing_h, "sigma_X, sigma_Y"), (survey.missing_v, "sigma_Z")) if k
        and k < n]
    if h2 is None or v2 is None:
        which = " and ".join(x for x, s in (("horizontal", h2), ("vertical", v2)) if s is None)
        warn.append("No survey accuracy of the check points (sigma_X, sigma_Y, sigma_Z in "
                    "ground_points.csv" + (f"; {', '.join(missing)}" if missing else "")
                    + f"): Edition 2 includes it in the product's accuracy; the {which} "
                    "accuracy stated is the fit to the check points alone.")
    crit = norm_ppf(1 - MEAN_ALPHA / 2)
    big = [k for k in range(3) if abs(mean[k]) > MEAN_SHARE * rmse[k]]
    signif = [k for k in range(3) if np.isfinite(z[k]) and abs(z[k]) > crit]
    if datum == CONTROL and (big or signif):
        text = ""
        if big:
            text = ("Mean error larger than 25 % of the RMSE of its axis (Edition 2 asks for "
                    "its cause to be investigated): " + ", ".join(
                        f"{'XYZ'[k]} {mean[k]:+.3f} m > {MEAN_SHARE * rmse[k]:.3f} m"
                        for k in big) + ". ")
        if np.isfinite(z).all():
            text += ("Against its standard deviation from the adjustment (the control's "
                     "errors carried into the block): " + ", ".join(
                         f"{'XYZ'[k]} {abs(z[k]):.1f} sigma" for k in range(3)) + "; "
                     + (", ".join("XYZ"[k] for k in signif) + " significant at 5 %: a "
                        "systematic shift, which the figures include." if signif else
                        "none significant at 5 %: the adjustment's own precision explains "
                        "the mean."))
        warn.append(text.strip())
    lo, hi = sorted(rmse[:2])
    if hi > 0 and lo / hi < 0.6:
        warn.append(f"RMSE X and Y differ (ratio {lo / hi:.2f} < 0.6): NSSDA's 95 % "
                    "horizontal factor (legacy) assumes them about equal; that figure is "
                    "approximate.")
    legacy = {"horizontal_95_m": NSSDA_H95 * h1, "vertical_95_m": NSSDA_V95 * v1,
              "ce90_m": CE90 * h1, "le90_m": LE90 * v1}
    return Statement(n, datum, table, figures, _sentences(n, h, v, d3), legacy, warn, misses,
                     survey, mean_covariance)
