"""numba kernels of the fast CSV writer (output/tables.py): C's ``%.Pg`` of float64 values,
correctly rounded, and the rows of a table assembled from formatted cells.

``_digits`` finds, for each value, the P significant digits and the decimal exponent
that ``"%.Pg" % x`` prints: the value times a power of ten (exact up to 10^22) is one
correctly rounded product or quotient, at most 2^-53 relative from the exact one, so its
rounding to an integer is certain unless its fraction lies within `tol` of one half.  Those
values (and values beyond the exact powers of ten) are marked for Python's own formatting,
so every value is printed exactly as Python (and pandas' ``to_csv(float_format=...)``)
prints it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from baarda.linalg._jit import kernel, parallel_kernel

# status of a formatted value (_digits)
DIGITS, NEGATIVE, NAN, POS_INF, NEG_INF, ZERO, NEG_ZERO, PYTHON = range(8)

PAIRS = np.frombuffer(''.join(f'{k:02d}' for k in range(100)).encode(), np.uint8)
POW10 = np.array([10.0**k for k in range(23)])  # exact in float64


def _digits(x, precision, tol, lo, hi, pow10):
    """(status, digits, exponent) of one value: the P-digit integer and the decimal
    exponent that %.Pg prints (module docstring), or a status without digits."""
    a = abs(x)
    if a != a:
        return NAN, 0, 0
    if a == math.inf:
        return (POS_INF if x > 0 else NEG_INF), 0, 0
    if a == 0.0:
        return (NEG_ZERO if math.copysign(1.0, x) < 0 else ZERO), 0, 0
    e = int(math.floor(math.log10(a)))
    for _ in range(3):
        k = precision - 1 - e
        if k > 22 or k < -22:
            break
        s = a * pow10[k] if k >= 0 else a / pow10[-k]
        if s >= hi:
            e += 1
            continue
        if s < lo:
            e -= 1
            continue
        f = math.floor(s)
        frac = s - f
        if abs(frac - 0.5) <= tol:
            break
        d = np.int64(f)
        if frac > 0.5:
            d += 1
        if d == np.int64(hi):
            d = np.int64(lo)
            e += 1
        return (NEGATIVE if x < 0 else DIGITS), d, e
    return PYTHON, 0, 0


_digits = kernel(_digits, inline="always")


def _put_g(out, pos, d, e, precision, negative, scratch):
    """C's %.Pg of the number with P digits d and decimal exponent e (no '#' flag)."""
    if negative:
        out[pos] = 45  # '-'
        pos += 1
    t = np.uint64(d)
    q = precision
    while q >= 2:  # two digits at a time
        r = t % np.uint64(100)
        t //= np.uint64(100)
        scratch[q - 1] = PAIRS[2 * r + 1]
        scratch[q - 2] = PAIRS[2 * r]
        q -= 2
    if q == 1:
        scratch[0] = 48 + t
    nd = precision
    while nd > 1 and scratch[nd - 1] == 48:
        nd -= 1
    if e < -4 or e >= precision:
        out[pos] = scratch[0]
        pos += 1
        if nd > 1:
            out[pos] = 46  # '.'
            pos += 1
            for q in range(1, nd):
                out[pos] = scratch[q]
                pos += 1
        out[pos] = 101  # 'e'
        out[pos + 1] = 45 if e < 0 else 43
        pos += 2
        ae = -e if e < 0 else e
        if ae >= 100:
            out[pos] = 48 + ae // 100
            pos += 1
        out[pos] = 48 + (ae // 10) % 10
        out[pos + 1] = 48 + ae % 10
        return pos + 2
    if e >= 0:
        for q in range(e + 1):
            out[pos] = scratch[q]
            pos += 1
        if nd > e + 1:
            out[pos] = 46
            pos += 1
            for q in range(e + 1, nd):
                out[pos] = scratch[q]
                pos += 1
        return pos
    out[pos] = 48  # 0.000ddd
    out[pos + 1] = 46
    pos += 2
    for _ in range(-e - 1):
        out[pos] = 48
        pos += 1
    for q in range(nd):
        out[pos] = scratch[q]
        pos += 1
    return pos


_put_g = kernel(_put_g, inline="always")


def format_floats(values, precision, tol, cells, lengths):
    """%.Pg of a float64 matrix into fixed-width cells (bytes and lengths; an empty cell
    for NaN, length -1 where Python must format the value); rows in parallel."""
    n, m = values.shape
    pow10 = POW10
    hi = pow10[precision]
    lo = pow10[precision - 1]
    width = cells.shape[2]
    flat = cells.reshape(-1)
    scratch = np.zeros((n, 24), np.uint8)  # each row's digits, allocated once
    for i in prange(n):
        for j in range(m):
            st, d, e = _digits(values[i, j], precision, tol, lo, hi, pow10)
            if st == DIGITS or st == NEGATIVE:
                p0 = (i * m + j) * width
                lengths[i, j] = _put_g(flat, p0, d, e, precision, st == NEGATIVE,
                                       scratch[i]) - p0
                continue
            c = cells[i, j]
            if st == PYTHON:
                lengths[i, j] = -1
            elif st == POS_INF:
                c[0] = 105  # inf
                c[1] = 110
                c[2] = 102
                lengths[i, j] = 3
            elif st == NEG_INF:
                c[0] = 45
                c[1] = 105
                c[2] = 110
                c[3] = 102
                lengths[i, j] = 4
            elif st == ZERO:
                c[0] = 48
                lengths[i, j] = 1
            elif st == NEG_ZERO:
                c[0] = 45
                c[1] = 48
                lengths[i, j] = 2
            else:  # NAN: an empty cell
                lengths[i, j] = 0


format_floats = parallel_kernel(format_floats)


def assemble_rows(kinds, index, cells, lengths, cell_start, cell_len, pool, row_start, out):
    """The rows of a table into out (row i from row_start[i]): column c is float column
    index[c] (kinds[c] == 0: cells, lengths) or text column index[c] (kinds[c] == 1: bytes
    cell_start/cell_len in pool); ',' between cells, '\\n' after each row; rows in
    parallel."""
    n = row_start.shape[0] - 1
    ncol = kinds.shape[0]
    for i in prange(n):
        pos = row_start[i]
        for c in range(ncol):
            j = index[c]
            if kinds[c] == 1:
                s = cell_start[j, i]
                for t in range(cell_len[j, i]):
                    out[pos + t] = pool[s + t]
                pos += cell_len[j, i]
            else:
                for t in range(lengths[i, j]):
                    out[pos + t] = cells[i, j, t]
                pos += lengths[i, j]
            out[pos] = 44 if c < ncol - 1 else 10
            pos += 1


assemble_rows = parallel_kernel(assemble_rows)


def any_byte(data, values):
    """Whether data (uint8) holds any of the byte values."""
    table = np.zeros(256, np.bool_)
    for v in values:
        table[v] = True
    for b in data:
        if table[b]:
            return True
    return False


any_byte = kernel(any_byte)
