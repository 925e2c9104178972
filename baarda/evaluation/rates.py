"""Rates of a study with binomial confidence intervals (Clopper-Pearson, 95 %)."""

from __future__ import annotations

import numpy as np
from scipy.stats import beta

LEVEL = 0.95


def clopper_pearson(k: int, n: int, level: float = LEVEL) -> tuple[float, float]:
    """The exact binomial confidence interval of k successes in n trials."""
    if n == 0:
        return (float("nan"), float("nan"))
    a = (1 - level) / 2
    lo = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a, k + 1, n - k))
    return lo, hi


def _rate(k: int, n: int) -> dict:
    return {"k": k, "n": n, "rate": k / n if n else float("nan"),
            "ci": clopper_pearson(k, n)}


def study_rates(study) -> dict:
    """The rates of a Study (see Study.rates)."""
    b, t = study.blunders, study.trials
    out: dict = {"level": LEVEL, "strategies": {}}
    first = b.drop_duplicates(["trial", "kind", "photo", "point", "component"])
    planted = len(first)
    sig = int(first["significant_first"].sum()) if planted else 0
    one = t.drop_duplicates("trial")
    n_unplanted = int((one["n_tested_first"] - one["n_planted"]).sum())  # tested ones
    # components significant in the first adjustment that are not planted
    false_sig = int(one["n_significant_first"].sum()) - sig
    out["first_adjustment"] = {
        "planted": planted, "planted_significant": sig,
        "power": sig / planted if planted else float("nan"),
        "power_ci": clopper_pearson(sig, planted),
        "unplanted": n_unplanted, "unplanted_significant": false_sig,
        "false_share": false_sig / n_unplanted if n_unplanted else float("nan"),
        "false_ci": clopper_pearson(false_sig, n_unplanted),
        # with blunders planted the unplanted significant ones are mostly their correlated
        # neighbours (spill-over); without, false alarms: per block as well
        "meaning": "spill-over" if planted else "false alarms"}
    if not planted and len(one):
        alarms = int((one["n_significant_first"] > 0).sum())
        alpha0 = study.options.tests.alpha0
        n_tested = float(one["n_tested_first"].mean())
        out["first_adjustment"]["blocks_with_false_alarm"] = _rate(alarms, len(one))
        out["first_adjustment"]["blocks_with_false_alarm"]["independent_tests"] = \
            1.0 - (1.0 - alpha0) ** n_tested
    for name in study.options.strategies:
        tb, tt = b[b["strategy"] == name], t[t["strategy"] == name]
        k, n = int(tb["located"].sum()), len(tb)
        nf = int(tt["n_false"].sum())
        good = int((tt["n_observations"] - tt["n_planted"]).sum())
        sep = tb["separable"].to_numpy(bool)
        ident, first = tb["identified"].to_numpy(bool), tb["first"].to_numpy(bool)
        loc = tb["located"].to_numpy(bool)
        strict = tb["strict"].to_numpy(bool)
        out["strategies"][name] = {
            "planted": n, "located": k, "located_rate": k / n if n else float("nan"),
            "located_ci": clopper_pearson(k, n),
            "strict": _rate(int(strict.sum()), n),
            "identified": _rate(int(ident.sum()), n), "first": _rate(int(first.sum()), n),
            "separable_located": _rate(int(loc[sep].sum()), int(sep.sum())),
            "separable_strict": _rate(int(strict[sep].sum()), int(sep.sum())),
            "inseparable_strict": _rate(int(strict[~sep].sum()), int((~sep).sum())),
            "inseparable_located": _rate(int(loc[~sep].sum()), int((~sep).sum())),
            "inseparable_identified": _rate(int(ident[~sep].sum()), int((~sep).sum())),
            "false": nf, "false_per_trial": nf / max(len(tt), 1),
            "false_rate": nf / good if good else float("nan"),
            "false_ci": clopper_pearson(nf, good),
            "seconds_per_trial": float(np.mean(tt["seconds"])) if len(tt) else float("nan")}
        if "at_entry" in tb and tb["at_entry"].notna().any():  # the on-line replay
            e = int((tb["at_entry"] == "reject").sum())
            out["strategies"][name].update({
                "rejected_at_entry": e, "at_entry_rate": e / n if n else float("nan"),
                "at_entry_ci": clopper_pearson(e, n),
                "suspect_at_entry": int((tb["at_entry"] == "suspect").sum())})
    return out
