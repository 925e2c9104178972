"""The mean miss of true check points on simulated blocks (issue 42): the old test
(|mean| > 2 std / sqrt(n)) against the mean's standard deviation from the adjustment
(bundle/check_mean.py).  One JSON line per block.

    PYTHONPATH=$PWD python benchmarks/accuracy_mean_study.py STRIPS PHOTOS CHECKS BLOCKS

sd_mean_adjustment is at sigma0 1 (the a-priori one); the result folder's statement scales it
by sigma0 a posteriori.
"""

import json
import sys
import time

import numpy as np

from baarda import pipeline
from baarda.bundle.check_mean import check_mean_cofactor
from baarda.simulate.aerial import FlightPlan, simulate_block


def main(strips: int, per: int, ncheck: int, blocks: int) -> None:
    for seed in range(blocks):
        t = time.time()
        block, _ = simulate_block(FlightPlan(strips=strips, photos_per_strip=per,
                                             check_points=ncheck, seed=seed))
        res = pipeline.adjust(block)
        ids, d = res.check_points()
        n = len(d)
        mean, sd = d.mean(0), d.std(0, ddof=1)
        sd_corr = np.sqrt(np.diag(check_mean_cofactor(res)))
        index = res.block.point_index
        pc = res.point_covariance()[res.problem.remap[[index[i] for i in ids]]]
        sd_indep = np.sqrt(np.einsum("kaa->a", pc)) / n
        print(json.dumps({
            "seed": seed, "photos": len(block.photos), "n": n, "sigma0": round(res.sigma0, 4),
            "mean": mean.round(4).tolist(), "std/sqrt(n)": (sd / np.sqrt(n)).round(4).tolist(),
            "z_old": (mean / (sd / np.sqrt(n))).round(2).tolist(),
            "sd_mean_adjustment": sd_corr.round(4).tolist(),
            "sd_mean_if_independent": sd_indep.round(4).tolist(),
            "z_new": (mean / sd_corr).round(2).tolist(),
            "seconds": round(time.time() - t, 1)}), flush=True)


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:5]))
