"""The invariants of a result folder, checked from its files alone (`baarda check OUT`).

For every adjustment of the run, from observations.csv (or .parquet) and summary.json:

* the observations are the rows not rejected, and redundancy = observations - unknowns;
* the redundancy numbers of those rows add up to the redundancy (r_i = (Qvv P)_ii), for
  an adjustment that converged (one that did not is said to be so, and the rest checked);
* v'Pv = sum (v / sigma)^2 over those rows, and sigma0 = sqrt(v'Pv / redundancy), which is
  also the global test's statistic sigma0^2;
* every RMS line of the summary and of the quality report (image x and y, control, GNSS,
  check points) recomputed from the rows it covers, to its printed digits;
* the top-level figures of summary.json (those the quality report prints) as those of the
  adjustment they repeat;
* every used row: its residual, sigma, redundancy number and sigma_residual present, sigma >
  0, 0 <= r <= 1, sigma_residual = sigma sqrt(r), w = -v / sigma_residual, MDB = delta0
  sigma / sqrt(r), its kind and component one of the observation groups;
* every file run.json lists present, with its size and SHA-256 (a changed or missing file
  does not hold: exit 5, as a broken invariant).

A folder that passes was written by a run whose numbers agree with each other; one that
fails names the number, what it should be and what it is.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import pandas as pd

from baarda.io.result_folder import Results
from baarda.kinds import GNSS

RTOL = 1e-6  # relative agreement of recomputed sums (the files hold every digit)


@dataclass(frozen=True)
class Finding:
    """One invariant: what the files say (`stated`) against what their rows give."""

    adjustment: str
    name: str
    stated: float
    recomputed: float
    ok: bool
    detail: str = ""  # said instead of the two numbers (a file, the first row that breaks)
    verdict: str = ""  # said instead of ok / DOES NOT HOLD (e.g. "not converged")

    def line(self) -> str:
        where = f"{self.adjustment}: " if self.adjustment else ""
        verdict = self.verdict or ("ok" if self.ok else "DOES NOT HOLD")
        said = self.detail or (f"stated {self.stated:.10g}, recomputed "
                               f"{self.recomputed:.10g}")
        return f"{verdict:>13}  {where}{self.name}: {said}"


def _close(a: float, b: float, rtol: float = RTOL, atol: float = 0.0) -> bool:
    return bool(np.isfinite(a) and np.isfinite(b) and abs(a - b) <= atol + rtol * abs(b))


def _printed(text: str, value: float) -> bool:
    """Whether `text` (a number as printed) is `value` rounded to the digits it shows."""
    decimals = len(text.split(".")[1]) if "." in text else 0
    return abs(float(text) - value) <= 0.5 * 10.0**-decimals * (1 + 1e-9) + 1e-12


def _rms(x: pd.Series) -> float:
    x = pd.to_numeric(x, errors="coerce").dropna()
    return float(np.sqrt(np.mean(x.to_numpy(float) ** 2))) if len(x) else float("nan")


def _adjustments(res: Results) -> dict[str, tuple[dict, pd.DataFrame]]:
    """Each adjustment's figures and rows; the top level of summary.json too (the figures
    the quality report prints), with the rows of the adjustment it names (or the only
    one)."""
    parts = res.summary.get("adjustments") or {"": res.summary}
    obs = res.obs
    out = {}
    for name, p in parts.items():
        if not isinstance(p, dict):
            continue
        rows = obs[obs["adjustment"] == name] if "adjustment" in obs and name and \
            (obs["adjustment"] == name).any() else obs
        out[name] = (p, rows)
    main = res.summary.get("adjustment")
    if "" not in out and (main in out or len(out) == 1):
        top = {k: res.summary.get(k) for k in ("n_observations", "n_unknowns", "redundancy",
                                               "vtpv", "sigma0", "global_test")}
        if any(v is not None for v in top.values()):
            out["summary.json (top level)"] = (top, out[main if main in out else
                                                        next(iter(out))][1])
    return out


#: the adjustment's statistics of a row, from its residual v, sigma and redundancy number r
#: (docs/quality.md): sigma_residual = sigma sqrt(r), w = -v / sigma_residual,
#: MDB = delta0 sigma / sqrt(r)
NEEDED = ("residual", "sigma", "redundancy", "sigma_residual")


def _row_relations(label: str, used: pd.DataFrame, delta0, rtol: float,
                   groups: dict | None) -> list[Finding]:
    """The relations that tie each used row's statistics to its residual and sigma, the
    columns they need, and the kind and component of every row."""
    out: list[Finding] = []
    add = out.append

    def col(c: str) -> np.ndarray:
        return pd.to_numeric(used[c], errors="coerce").to_numpy(float) if c in used else \
            np.full(len(used), np.nan)

    def first_bad(mask: np.ndarray, what: str) -> str:
        i = int(np.flatnonzero(mask)[0])
        line = used["line"].iloc[i] if "line" in used else None
        where = f"line {int(line)}" if line is not None and pd.notna(line) else f"row {i + 1}"
        return f"{int(mask.sum())} row(s) do not, first at observations {where} ({what})"

    def said(bad: np.ndarray, what: str) -> str:
        return first_bad(bad, what) if bad.any() else f"all {len(used)} rows"

    v, sigma, r, sv = (col(c) for c in NEEDED)
    missing = [c for c, x in zip(NEEDED, (v, sigma, r, sv), strict=True)
               if len(x) and not np.isfinite(x).all()]
    add(Finding(label, f"every used row has {', '.join(NEEDED)}", 0, len(missing),
                not missing, f"all {len(used)} rows" if not missing else
                "missing or empty: " + ", ".join(missing)))
    bad = ~((sigma > 0) & (r >= -1e-9) & (r <= 1 + 1e-9))
    add(Finding(label, "sigma > 0 and 0 <= r <= 1 in every used row", 0, int(bad.sum()),
                not bad.any(), said(bad, "sigma or r")))
    ok = np.isfinite(sv) & np.isfinite(sigma) & np.isfinite(r) & (r >= 0)
    bad = ok & ~np.isclose(sv, sigma * np.sqrt(np.clip(r, 0, None)), rtol=rtol, atol=0)
    add(Finding(label, "sigma_residual = sigma sqrt(r) in every used row", 0, int(bad.sum()),
                not bad.any(), said(bad, "sigma_residual")))
    w = col("w")
    has_w = np.isfinite(w) & np.isfinite(sv) & (sv > 0)
    bad = has_w & ~np.isclose(w, -v / np.where(sv > 0, sv, 1), rtol=rtol, atol=rtol)
    tested = (r > 1e-3) & np.isfinite(r)
    lost = tested & ~np.isfinite(w) if "w" in used else tested
    bad = bad | lost
    add(Finding(label, "w = -v / sigma_residual in every used row", 0, int(bad.sum()),
                not bad.any(), said(bad, "w")))
    if delta0 is not None and "mdb" in used:
        mdb = col("mdb")
        with np.errstate(divide="ignore", invalid="ignore"):
            want = delta0 * sigma / np.sqrt(r)
        has = np.isfinite(mdb) & np.isfinite(want)
        bad = has & ~np.isclose(mdb, want, rtol=rtol, atol=0) | (tested & ~np.isfinite(mdb))
        add(Finding(label, "MDB = delta0 sigma / sqrt(r) in every used row", 0,
                    int(bad.sum()), not bad.any(), said(bad, "mdb")))
    if groups:
        pairs = list(zip(used["kind"].astype(str), used["component"].astype(str),
                         strict=True))
        bad = np.array([c not in (groups.get(k) or {}) for k, c in pairs], dtype=bool)
        add(Finding(label, "every row's kind and component is one of summary.json's "
                    "observation groups", 0, int(bad.sum()), not bad.any(),
                    said(bad, "kind or component")))
    return out


def check_manifest(folder) -> list[Finding]:
    """Every file run.json lists is there, with its size and checksum."""
    from pathlib import Path

    from baarda.io.run_manifest import MANIFEST, file_record, read_manifest

    folder = Path(folder)
    if not (folder / MANIFEST).is_file():
        return []
    files = read_manifest(folder / MANIFEST)["files"]
    out = []
    for name, record in sorted(files.items()):
        p = folder / name
        if not p.is_file():
            out.append(Finding("", f"{name} (listed in run.json)", 0, 0, False,
                               "missing"))
            continue
        same = file_record(p) == record
        out.append(Finding("", f"{name} (listed in run.json)", 0, 0, same,
                           "size and SHA-256 as listed" if same else
                           "size or SHA-256 differ from run.json: changed since the run"))
    return out


def check_results(res: Results, rtol: float = RTOL) -> list[Finding]:
    """Every invariant of every adjustment of a result folder (module docstring); sums
    recomputed from the rows agree with the figures stated to `rtol` (relative)."""
    findings: list[Finding] = []
    several = len(_adjustments(res)) > 1
    for name, (p, rows) in _adjustments(res).items():
        label = name if several else ""
        used = rows[~rows["rejected"].to_numpy(bool)]
        n, red = len(used), p.get("redundancy")
        add = findings.append
        if p.get("n_observations") is not None:
            add(Finding(label, "observations (components not rejected)",
                        p["n_observations"], n, p["n_observations"] == n))
            if p.get("n_unknowns") is not None and red is not None:
                add(Finding(label, "redundancy = observations - unknowns", red,
                            n - p["n_unknowns"], red == n - p["n_unknowns"]))
        if red is None or red <= 0:
            continue
        r = pd.to_numeric(used["redundancy"], errors="coerce") if "redundancy" in used else None
        if r is not None and r.notna().any():
            s = float(r.sum())
            if p.get("converged", res.summary.get("converged")) is False:
                # the statistics of the last iteration of an adjustment that did not
                # converge: the counts, vTPv and sigma0 of its rows hold; trace(Qvv P) =
                # redundancy only where the normal equations were solved well
                add(Finding(label, "the adjustment did not converge: the sum of the "
                            "redundancy numbers is not checked (its statistics are those of "
                            "the last iteration)", red, s, True, verdict="not converged"))
            else:
                add(Finding(label, "sum of the redundancy numbers = redundancy", red, s,
                            _close(s, red, rtol, rtol)))
        z = (used["residual"].to_numpy(float) / used["sigma"].to_numpy(float))
        vtpv = float(np.sum(z**2))
        if p.get("vtpv") is not None:
            add(Finding(label, "vTPv = sum (v / sigma)^2 of the observations", p["vtpv"], vtpv,
                        _close(p["vtpv"], vtpv, rtol)))
        s0 = float(np.sqrt(vtpv / red))
        if p.get("sigma0") is not None:
            add(Finding(label, "sigma0 = sqrt(vTPv / redundancy)", p["sigma0"], s0,
                        _close(p["sigma0"], s0, rtol)))
        gt = p.get("global_test") or {}
        if gt.get("statistic") is not None:
            add(Finding(label, "global test statistic = sigma0^2", gt["statistic"], s0**2,
                        _close(gt["statistic"], s0**2, rtol)))
        if name != "summary.json (top level)":
            delta0 = p.get("delta0", res.summary.get("delta0"))
            findings += _row_relations(label, used, delta0, max(rtol, 1e-9),
                                       res.summary.get("observation_groups"))
            findings += _summary_rms(res, label, used, several)
    findings += _report_rms(res)
    return findings


_IMAGE_RMS = re.compile(r"RMS image residuals x ([0-9.]+) µm, y ([0-9.]+) µm")
_CHECK_RMS = re.compile(r"check points \d+: RMS X ([0-9.]+) m, Y ([0-9.]+) m, Z ([0-9.]+) m")
_AXIS_RMS = re.compile(r"\b([XYZ]) ([0-9.]+) m")


def _summary_rms(res: Results, label: str, used: pd.DataFrame,
                 several: bool) -> list[Finding]:
    """The summary's RMS lines (a bundle: image x and y, check points)."""
    if several:
        return []
    out = []
    lines = [line for s in res.sections for line in s.lines]
    img = used[used["kind"] == "image"]
    for line in lines:
        m = _IMAGE_RMS.search(line)
        if m:
            for c, text in zip("xy", m.groups(), strict=True):
                v = _rms(img.loc[img["component"] == c, "residual"])
                out.append(Finding(label, f"RMS image residuals {c} (µm, as printed)",
                                   float(text), v, _printed(text, v)))
        m = _CHECK_RMS.search(line)
        if m and res.points is not None and "dX" in res.points:
            chk = res.points[res.points["role"] == "check"]
            for c, text in zip("XYZ", m.groups(), strict=True):
                v = _rms(chk[f"d{c}"])
                out.append(Finding(label, f"RMS of the check points {c} (m, as printed)",
                                   float(text), v, _printed(text, v)))
    return out


def _report_rms(res: Results) -> list[Finding]:
    """The RMS sentences of the quality report's control and GNSS parts: over the
    components that were used (not rejected)."""
    from baarda.report.quality_report import control_parts, gnss_parts

    out = []
    obs = res.obs
    used = obs[~obs["rejected"].to_numpy(bool)]
    for kind, parts in (("control", control_parts(res)), (GNSS.name, gnss_parts(res))):
        texts = [p.text for p in parts if p.kind == "text" and "RMS:" in p.text
                 and not p.text.startswith("Check points")]
        for text in texts[:1]:
            rows = used[used["kind"] == kind]
            for axis, value in _AXIS_RMS.findall(text.split("RMS:")[1]):
                v = _rms(rows.loc[rows["component"] == axis, "residual"])
                out.append(Finding("", f"quality report: RMS of the {kind} {axis} residuals "
                                   "(m, as printed)", float(value), v, _printed(value, v)))
    return out


def check_folder(folder, rtol: float = RTOL) -> list[Finding]:
    """The files run.json lists (`check_manifest`), then check_results of the folder (read
    with io.result_folder.read_results); a folder whose files are not those of its run is
    not read further (its findings say which)."""
    from baarda.io.result_folder import read_results

    files = check_manifest(folder)
    if not all(f.ok for f in files):
        return files
    return files + check_results(read_results(folder), rtol)
