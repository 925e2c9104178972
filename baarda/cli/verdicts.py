"""The one closing line of a command (the verdict on stderr that `-q` keeps): what a user
must not miss, taken from the result's summary.json fields."""

from __future__ import annotations


def adjustment_verdict(d: dict) -> str:
    """'NOT CONVERGED ...' or 'sigma0 1.051 (global test accepted), 4 rejected, 4 check
    points RMS X 0.059 Y 0.046 Z 0.117 m' from an adjustment's to_dict()."""
    parts = []
    if d.get("converged") is False:
        parts.append(f"NOT CONVERGED after {d.get('iterations')} iterations")
    if d.get("snooping_incomplete"):  # data snooping stopped at its step limit
        parts.append(str(d["snooping_incomplete"]).split(";")[0].upper())
    sigma0 = d.get("sigma0")
    if isinstance(sigma0, float):
        gt = d.get("global_test") or {}
        test = ""
        if "passed" in gt:
            test = " (global test " + ("accepted" if gt["passed"] else "REJECTED") + ")"
        parts.append(f"sigma0 {sigma0:.4g}{test}")
    if d.get("n_rejected") is not None:
        parts.append(f"{d['n_rejected']} rejected")
    if d.get("n_flagged"):
        parts.append(f"{d['n_flagged']} flagged")
    if d.get("n_check_points"):
        rms = [d.get(f"check_rms_{a}") for a in "XYZ"]
        shown = " ".join(f"{a} {v:.3f}" for a, v in zip("XYZ", rms, strict=True)
                         if isinstance(v, float))
        parts.append(f"{d['n_check_points']} check points RMS {shown} m")
    return ", ".join(parts) or "done"


def models_verdict(d: dict) -> str:
    """The verdict of an independent-model adjustment (BlockQuality.to_dict()): each
    adjustment's, then the decision on the hypotheses."""
    text = "; ".join(f"{name}: {adjustment_verdict(a)}"
                     for name, a in d.get("adjustments", {}).items())
    if d.get("decision"):
        text += f"; decision: {d['decision']}"
    return text or "done"
