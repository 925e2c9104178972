"""Separability of the w-tests: their correlations and the minimal separable bias.

Under H_j (an error b in observation j) E(w_i) = rho_ij E(w_j), with rho_ij = q_vv,ij /
sqrt(q_vv,ii q_vv,jj) the correlation of w_i and w_j (Baarda 1968; Foerstner 1983).  When
|rho_ij| is near one the two w-tests move together: the largest |w| then points at i or at
j almost at random, whatever the size of the error (Teunissen 2018, "Distributional theory
for the DIA method": detection is not identification).

Minimal separable bias.  Data snooping identifies j in one step when |w_j| > k and |w_j| is
the largest |w|.  For j against one other test i with correlation rho (taken >= 0: the sign
of w_i does not matter for |w_i|), with w_j = x the other is N(rho x, 1 - rho^2) whatever
the error, so

    P_ji(delta) = int_{|x| > k} phi(x - delta) P(|w_i| < |x| | x) dx,
    P(|w_i| < |x| | x) = Phi((|x| - rho x) / s) - Phi((-|x| - rho x) / s),  s = sqrt(1 - rho^2)

with delta = E(w_j) = b sqrt(r_j) / sigma_j.  The probability of correct identification
among all tests is at most min_i P_ji, so the bias at which P_ji reaches beta0 for the most
correlated partner (rho_max) is a lower bound of the minimal identifiable bias: the minimal
separable bias (Imparato, Teunissen & Tiberius 2019), MSB = delta_s(rho_max) sigma /
sqrt(r) = MDB delta_s(rho_max) / delta0.  At rho = 0, P_ji is the power less the small
chance that a noise |w_i| beats |w_j|, so MSB >= MDB always; as rho -> 1, delta_s grows as
sqrt(2) Phi^-1(beta0) / sqrt(1 - rho): inseparable pairs cannot be identified at any size.

Correlations of pairs that share a point or a frame (photo, model) are computed exactly
(`w_correlations`, from the model's cofactors of those pairs); farther pairs are left out
(docs/quality.md says how rarely they matter).
"""

from __future__ import annotations

import functools
from collections.abc import Iterable

import numpy as np
import pandas as pd
from scipy import special

from baarda.linalg._jit import kernel

RHO_INSEPARABLE = 0.99  # |rho| from which two w-tests are called not separable
_NODES = 160  # Gauss-Legendre nodes of P_ji over delta +- 10
_GRID = 512  # nodes of the table of delta_s in u = sqrt(1 - rho)


def _phi(x):
    return np.exp(-0.5 * x * x) / np.sqrt(2 * np.pi)


def _big_phi(x):
    return special.ndtr(x)


def identification_probability(delta, rho, k: float) -> np.ndarray:
    """P_ji(delta): the probability that |w_j| > k and |w_j| > |w_i| when E(w_j) = delta,
    E(w_i) = rho delta, both of unit variance with correlation rho (module docstring);
    vectorised over delta and rho."""
    delta, rho = np.broadcast_arrays(np.asarray(delta, float), np.abs(np.asarray(rho, float)))
    t, wt = np.polynomial.legendre.leggauss(_NODES)
    s = np.sqrt(np.clip(1.0 - rho**2, 0.0, None))[..., None]
    r = rho[..., None]
    out = np.zeros(delta.shape)
    d = delta[..., None]
    for lo, hi in ((np.maximum(d - 10.0, k), np.maximum(d + 10.0, k)),
                   (np.minimum(d - 10.0, -k), np.full_like(d, -k))):
        half = (hi - lo) / 2
        x = lo + half * (t + 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inner = np.where(s > 0, _big_phi((np.abs(x) - r * x) / s)
                             - _big_phi((-np.abs(x) - r * x) / s),
                             (np.abs(x) > np.abs(r * x)).astype(float))
        out += np.sum(wt * _phi(x - d) * inner * half, axis=-1)
    return out


def _separable_delta(rho: np.ndarray, k: float, beta0: float) -> np.ndarray:
    """delta_s(rho) by bisection (vectorised): P_ji(delta_s) = beta0."""
    rho = np.asarray(rho, float)
    u = np.sqrt(1.0 - rho)
    lo = np.full(rho.shape, k)
    hi = np.full(rho.shape, k + 10.0) + 3.0 / np.maximum(u, 1e-9)
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        low = identification_probability(mid, rho, k) < beta0
        lo = np.where(low, mid, lo)
        hi = np.where(low, hi, mid)
    return 0.5 * (lo + hi)


@functools.lru_cache(maxsize=8)
def _table(k: float, beta0: float) -> tuple[np.ndarray, np.ndarray]:
    """g(u) = delta_s u on u = sqrt(1 - rho) in [0, 1] (smooth; g(0) = sqrt(2) Phi^-1(beta0))."""
    u = np.linspace(0.0, 1.0, _GRID + 1)
    g = np.empty_like(u)
    g[0] = np.sqrt(2.0) * special.ndtri(beta0)
    g[1:] = _separable_delta(1.0 - u[1:] ** 2, k, beta0) * u[1:]
    return u, g


def separable_delta(rho, k: float, beta0: float) -> np.ndarray:
    """delta_s(|rho|): E(w) at which one-step identification against a partner with
    correlation rho reaches beta0 (critical value k); inf for |rho| = 1.  Interpolated in
    a table (relative error below 1e-5)."""
    rho = np.abs(np.asarray(rho, float))
    u = np.sqrt(np.clip(1.0 - rho, 0.0, 1.0))
    grid, g = _table(float(k), float(beta0))
    with np.errstate(divide="ignore"):
        return np.where(u > 0, np.interp(u, grid, g) / u, np.inf)


# ------------------------------------------------------------------ correlations
@kernel
def _update(i, j, q, d, act, tested, best, partner):
    """best[i] = max |q_ij| / (d_i d_j) over the pairs (both tested, alike in being active);
    partner[i] = that j."""
    for n in range(i.size):
        a = i[n]
        c = j[n]
        if a == c or not tested[a] or not tested[c] or act[a] != act[c]:
            continue
        r = abs(q[n]) / (d[a] * d[c])
        if r > best[a] or (r == best[a] and partner[a] > c):
            best[a] = r
            partner[a] = c
        if r > best[c] or (r == best[c] and partner[c] > a):
            best[c] = r
            partner[c] = a


def _reduce(pairs: Iterable[tuple[np.ndarray, np.ndarray, np.ndarray]], d: np.ndarray,
            act: np.ndarray, tested: np.ndarray, best: np.ndarray,
            partner: np.ndarray) -> None:
    for i, j, q in pairs:
        _update(np.ascontiguousarray(i, np.int64), np.ascontiguousarray(j, np.int64),
                np.ascontiguousarray(q, float), d, act, tested, best, partner)


def w_correlations(model, qvv: np.ndarray, tested: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(rho_max (n,), partner (n,)): the largest |correlation| of each tested component's
    w-test with that of another tested component sharing a point or a frame, and that
    component (-1: none; rho_max NaN for untested components).

    The w of an active and of a rejected component are uncorrelated (the predicted residual
    of a rejected one does not depend on its own observation); two active ones have q_vv,ij
    = -q_ll,ij, two rejected ones +q_ll,ij.  Pairs of one point come from
    `model.point_pair_cofactors()`.  Pairs of one frame with different points are bounded
    first when the model gives the point-local part of q_ll (`local_cofactor_diag`):
    |q_vv,ij| <= sqrt(t_i t_j) with t = q_ll,ii - local_i (Cauchy-Schwarz on the frames'
    and globals' part, the only one such a pair shares), so only frames with a component
    whose bound could beat its rho_max so far are computed (`frame_pair_cofactors`).
    """
    n = model.n
    act = np.ascontiguousarray(model.active, np.bool_)
    tested = np.ascontiguousarray(tested & np.isfinite(qvv) & (qvv > 0), np.bool_)
    d = np.sqrt(np.where(tested, qvv, 1.0))
    best = np.zeros(n)
    partner = np.full(n, -1, np.int64)
    _reduce(model.point_pair_cofactors(), d, act, tested, best, partner)
    local = model.local_cofactor_diag()
    frame = np.asarray(model.frame, dtype=object)
    on_frame = tested & (frame != "")
    if local is not None and on_frame.any():
        qll = np.maximum(model.adjusted_cofactor_diag(), 0.0)
        t = np.maximum(qll - local, 0.0)
        u = np.where(on_frame, np.sqrt(t) / d, 0.0)
        f = pd.factorize(frame)[0]
        top = np.zeros(f.max() + 1)
        np.maximum.at(top, f, u)
        # the bound of the pairs with the largest u on the frame (which could be i itself:
        # then the second largest would do; the largest is safe)
        need = on_frame & (u * top[f] > best)
    else:
        need = on_frame
    if need.any():
        _reduce(model.frame_pair_cofactors(np.flatnonzero(need)), d, act, tested, best,
                partner)
    rho = np.where(tested, best, np.nan)
    return rho, np.where(tested, partner, -1)
