"""The distribution functions of the tests (chi-square, non-central chi-square, F, t,
normal) as scipy.stats computes them, taken from scipy.special directly.

These are the functions scipy.stats' chi2, ncx2, f and t call for one value inside their
support, so the numbers are the same to the last bit (tests/quality/test_special_functions.py
compares them); importing scipy.stats instead would cost every command 0.4 s of start-up.
"""

from __future__ import annotations

from collections.abc import Callable

from scipy import special

try:  # Boost's non-central chi-square, as scipy.stats.ncx2 uses it
    from scipy.special._ufuncs import _ncx2_isf, _ncx2_sf
except ImportError:  # pragma: no cover - a SciPy without them: scipy.stats.ncx2 instead
    _ncx2_isf = _ncx2_sf = None

__all__ = ["chi2_cdf", "chi2_isf", "chi2_ppf", "chi2_sf", "f_isf", "f_sf", "ncx2_isf",
           "ncx2_sf", "norm_ppf", "t_isf"]


def chi2_isf(p: float, dof: float) -> float:
    """``chi2.isf``: the value exceeded with probability p."""
    return float(special.chdtri(dof, p))


def chi2_ppf(p: float, dof: float) -> float:
    """``chi2.ppf``: the p quantile."""
    return float(2.0 * special.gammaincinv(dof / 2.0, p))


def chi2_sf(x: float, dof: float) -> float:
    """``chi2.sf``: P(chi2(dof) > x)."""
    return float(special.chdtrc(dof, x))


def chi2_cdf(x: float, dof: float) -> float:
    """``chi2.cdf``: P(chi2(dof) <= x)."""
    return float(special.chdtr(dof, x))


def _noncentral(boost, method: str, central: Callable[[float, float], float], x: float,
                dof: float, lam: float) -> float:
    """scipy.stats.ncx2's `method` (its central chi-square where lam is 0)."""
    if lam == 0:
        return central(x, dof)
    if boost is None:  # pragma: no cover
        from scipy import stats

        return float(getattr(stats.ncx2, method)(x, dof, lam))
    return float(boost(x, dof, lam))


def ncx2_sf(x: float, dof: float, lam: float) -> float:
    """``ncx2.sf``: P(chi2'(dof, lam) > x)."""
    return _noncentral(_ncx2_sf, "sf", chi2_sf, x, dof, lam)


def ncx2_isf(p: float, dof: float, lam: float) -> float:
    """``ncx2.isf``: the value chi2'(dof, lam) exceeds with probability p."""
    return _noncentral(_ncx2_isf, "isf", chi2_isf, p, dof, lam)


def f_isf(p: float, dof1: float, dof2: float) -> float:
    """``f.isf``: the value F(dof1, dof2) exceeds with probability p."""
    return float(special.fdtri(dof1, dof2, 1.0 - p))


def f_sf(x: float, dof1: float, dof2: float) -> float:
    """``f.sf``: P(F(dof1, dof2) > x)."""
    return float(special.fdtrc(dof1, dof2, x))


def t_isf(p: float, dof: float) -> float:
    """``t.isf``: the value t(dof) exceeds with probability p."""
    return float(-special.stdtrit(dof, p))


def norm_ppf(p: float) -> float:
    """The standard normal quantile (scipy.stats.norm.ppf: special.ndtri)."""
    return float(special.ndtri(p))
