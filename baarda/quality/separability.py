"""Separability of the w-tests: their correlations and the minimal separable bias.

Under H_j (an error b in observation j) E(w_i) = rho_ij E(w_j), with rho_ij = q_vv,ij /
sqrt(q_vv,ii q_vv,jj) the correlation of w_i and w_j (Baarda 1968; Foerstner 1983).  When
|rho_ij| is near one the two w-tests move together: the largest |w| then points at i or at
j almost at random, whatever the size of the error (Teunissen 2018, "Distributional theory
for the DIA method": detection is not identification).

Minimal separable bias.  One step of data snooping identifies j when |w_j| > k and |w_j|
is the largest |w| (Teunissen's DIA with the w-tests).  Against its most correlated
partner i (rho = rho_max, taken >= 0: the sign of w_i does not matter for |w_i|) and the
n other tests of the block taken as independent of both: given w_j = x, w_i is
N(rho x, 1 - rho^2) whatever the error, so

    P_j(delta) = int_{|x| > k} phi(x - delta) [Phi((|x| - rho x) / s)
                 - Phi((-|x| - rho x) / s)] (2 Phi(|x|) - 1)^n dx,  s = sqrt(1 - rho^2),

with delta = E(w_j) = b sqrt(r_j) / sigma_j.  The MSB is the bias at which P_j reaches
beta0: MSB = delta_s sigma / sqrt(r) = MDB delta_s / delta0 (Imparato, Teunissen &
Tiberius 2019 bound the minimal identifiable bias by the separability of pairs; the
others enter because the largest noise |w| of a block grows with its size).  Every factor
is at most the power, so MSB >= MDB; as rho -> 1, delta_s grows as sqrt(2) Phi^-1(beta0) /
sqrt(1 - rho): inseparable pairs cannot be identified at any size.  On the 3 x 8 block it
equals the Monte-Carlo bias of one-step identification within 3 % (rho_max < 0.9;
tests/quality/test_msb_monte_carlo.py): the pair alone would be 4-7 % low, the block's
noise, not the other correlated neighbours, makes the difference.

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
RHO_ONE = 1e-9  # |rho| within this of 1 is one test (1 +- rounding): MSB infinite
RHO_TIE = 1e-12  # two |rho| within this (relative) are a tie: the lower partner is taken
_NODES = 96  # Gauss-Legendre nodes of P_j over delta +- 9
_U = np.linspace(0.0, 1.0, 129)  # the table of delta_s: u = sqrt(1 - rho)


def _phi(x):
    return np.exp(-0.5 * x * x) / np.sqrt(2 * np.pi)


@functools.cache
def _gauss_legendre() -> tuple[np.ndarray, np.ndarray]:
    """The nodes and weights of :data:`_NODES`-point Gauss-Legendre (read-only; computed once:
    an eigenvalue problem of 96 x 96, about 15 ms)."""
    t, wt = np.polynomial.legendre.leggauss(_NODES)
    t.flags.writeable = False
    wt.flags.writeable = False
    return t, wt


def identification_probability(delta, rho, k: float, others=0) -> np.ndarray:
    """P_j(delta): the probability that |w_j| > k and |w_j| is larger than |w_i| and than
    every |w| of `others` further tests, when E(w_j) = delta, E(w_i) = rho delta, all of
    unit variance, w_i correlated with w_j by rho and the others independent of both
    (module docstring); vectorised over delta, rho and others."""
    delta, rho, others = np.broadcast_arrays(np.asarray(delta, float),
                                             np.abs(np.asarray(rho, float)),
                                             np.asarray(others, float))
    t, wt = _gauss_legendre()
    s = np.sqrt(np.clip(1.0 - rho**2, 0.0, None))[..., None]
    r = rho[..., None]
    m = others[..., None]
    out = np.zeros(delta.shape)
    d = delta[..., None]
    for lo, hi in ((np.maximum(d - 9.0, k), np.maximum(d + 9.0, k)),
                   (np.minimum(d - 9.0, -k), np.full_like(d, -k))):
        half = (hi - lo) / 2
        x = lo + half * (t + 1)
        ax = np.abs(x)
        with np.errstate(divide="ignore", invalid="ignore"):
            pair = np.where(s > 0, special.ndtr((ax - r * x) / s)
                            - special.ndtr((-ax - r * x) / s), (ax > np.abs(r * x)) * 1.0)
            rest = np.exp(m * np.log1p(-special.erfc(ax / np.sqrt(2))))
        out += np.sum(wt * _phi(x - d) * pair * rest * half, axis=-1)
    return out


def _separable_delta(rho, k: float, beta0: float, others) -> np.ndarray:
    """delta_s by regula falsi (Illinois; vectorised): P_j(delta_s) = beta0."""
    rho, others = np.broadcast_arrays(np.asarray(rho, float), np.asarray(others, float))
    u = np.sqrt(1.0 - rho)
    a = np.full(rho.shape, float(k))
    b = k + 14.0 + 3.0 / np.maximum(u, 1e-9)
    fa = identification_probability(a, rho, k, others) - beta0
    fb = identification_probability(b, rho, k, others) - beta0
    side = np.zeros(rho.shape)
    for _ in range(60):
        c = (a * fb - b * fa) / (fb - fa)
        fc = identification_probability(c, rho, k, others) - beta0
        left = fc * fb > 0  # c replaces b
        fa = np.where(left & (side == 1), fa / 2, fa)
        fb = np.where(~left & (side == -1), fb / 2, fb)
        a, fa = np.where(left, a, c), np.where(left, fa, fc)
        b, fb = np.where(left, c, b), np.where(left, fc, fb)
        side = np.where(left, 1, -1)
        if np.all(np.abs(b - a) < 1e-9 * b) or np.all(np.abs(fc) < 1e-12):
            break
    return np.where(np.abs(fa) < np.abs(fb), a, b)


@functools.lru_cache(maxsize=32)
def _table(k: float, beta0: float, others: int) -> np.ndarray:
    """g(u) = delta_s u on the grid _U (smooth; g(0) = sqrt(2) Phi^-1(beta0))."""
    g = np.empty(len(_U))
    g[0] = np.sqrt(2.0) * special.ndtri(beta0)
    g[1:] = _separable_delta(1.0 - _U[1:] ** 2, k, beta0, others) * _U[1:]
    return g


def separable_delta(rho, k: float, beta0: float, others: int = 0) -> np.ndarray:
    """delta_s(|rho|): E(w) at which one step of data snooping picks the component with
    probability beta0, its most correlated partner at `rho` and `others` further tests
    taken as independent (critical value k); inf for |rho| = 1 (within RHO_ONE: the
    cofactors' rounding makes a pair that is one test 1 +- 1e-14, whose finite MSB would be
    noise).  Interpolated in a table of its own (relative error below 1e-4)."""
    rho = np.abs(np.asarray(rho, float))
    u = np.sqrt(np.clip(1.0 - rho, 0.0, 1.0))
    g = _table(float(k), float(beta0), max(int(others), 0))
    with np.errstate(divide="ignore"):
        return np.where(rho < 1.0 - RHO_ONE, _cubic(u, g) / np.maximum(u, 1e-300), np.inf)


def _cubic(x: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Catmull-Rom interpolation of g on the uniform grid _U at x in [0, 1]."""
    n = len(g) - 1
    t = np.clip(x, 0.0, 1.0) * n
    i = np.clip(t.astype(np.int64), 0, n - 1)
    f = t - i
    gp = np.concatenate([[2 * g[0] - g[1]], g, [2 * g[-1] - g[-2]]])
    p0, p1, p2, p3 = gp[i], gp[i + 1], gp[i + 2], gp[i + 3]
    return 0.5 * (2 * p1 + (p2 - p0) * f + (2 * p0 - 5 * p1 + 4 * p2 - p3) * f**2
                  + (3 * (p1 - p2) + p3 - p0) * f**3)


# ------------------------------------------------------------------ correlations
@kernel
def _update(i, j, q, d, act, tested, best, partner):
    """best[i] = max |q_ij| / (d_i d_j) over the pairs (both tested, alike in being active);
    partner[i] = that j, the lowest j of those within RHO_TIE of it (relative: two partners
    of a two-ray point are 1 +- rounding both, and which one the rounding favours would
    depend on the order of a sum)."""
    for n in range(i.size):
        a = i[n]
        c = j[n]
        if a == c or not tested[a] or not tested[c] or act[a] != act[c]:
            continue
        r = abs(q[n]) / (d[a] * d[c])
        _take(r, a, c, best, partner)
        _take(r, c, a, best, partner)


def _take_partner(r, a, c, best, partner):
    """Partner c at |rho| r for component a (_update)."""
    if r > best[a] * (1.0 + RHO_TIE):
        best[a] = r
        partner[a] = c
    elif r >= best[a] * (1.0 - RHO_TIE):
        best[a] = max(best[a], r)
        if partner[a] > c:
            partner[a] = c


_take = kernel(_take_partner, inline="always")


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
