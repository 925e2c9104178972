"""numba kernels of the COLMAP readers and writers (imported only when a model is read or
written, so that the other readers do not load numba).

Text: `tokens` walks a byte buffer line by line, counts the blank-separated tokens of every
line and, in its second pass, converts them: integers exactly (at most 18 significant
digits), decimal floats copied into one contiguous buffer that pyarrow converts (correctly
rounded, as Python's float()).  It takes only what the line-by-line reader reads the same
way (ASCII digits, signs, '.', exponents, blanks, '#' comment lines of printable ASCII);
on anything else it returns the line and the caller reads the file line by line, which is
the reference and gives the exact error.

Binary: `walk_images` and `walk_points` find the records of images.bin and points3D.bin
(positions and counts only), every count checked against the bytes left before it is used;
`gather` and `interleave` copy byte segments.
"""

from __future__ import annotations

import numpy as np
from numba import njit

INT, FLOAT = 0, 1
SPACE, TAB, LF, CR, HASH = 32, 9, 10, 13, 35


@njit(cache=True)
def _token_char(c):
    return (48 <= c <= 57) or c == 43 or c == 45 or c == 46 or c == 101 or c == 69


@njit(cache=True)
def _digit(c):
    return 48 <= c <= 57


@njit(cache=True)
def _parse_int(buf, start, end):
    """(value, ok) of [+-]?digits with at most 18 significant digits."""
    j = start
    neg = False
    if buf[j] == 43 or buf[j] == 45:
        neg = buf[j] == 45
        j += 1
    if j == end:
        return 0, False
    v = 0
    nd = 0
    for q in range(j, end):
        c = buf[q]
        if not _digit(c):
            return 0, False
        if nd > 0 or c != 48:
            nd += 1
        v = v * 10 + np.int64(c - 48)
    if nd > 18:
        return 0, False
    return (-v if neg else v), True


@njit(cache=True)
def _is_float(buf, start, end):
    """Whether buf[start:end] is [+-]?(d+(.d*)?|.d+)([eE][+-]?d+)?."""
    j = start
    if buf[j] == 43 or buf[j] == 45:
        j += 1
    nd = 0
    while j < end and _digit(buf[j]):
        j += 1
        nd += 1
    if j < end and buf[j] == 46:
        j += 1
        while j < end and _digit(buf[j]):
            j += 1
            nd += 1
    if nd == 0:
        return False
    if j < end and (buf[j] == 101 or buf[j] == 69):
        j += 1
        if j < end and (buf[j] == 43 or buf[j] == 45):
            j += 1
        ne = 0
        while j < end and _digit(buf[j]):
            j += 1
            ne += 1
        if ne == 0:
            return False
    return j == end


@njit(cache=True)
def tokens(buf, skip_blank, head, tail, fill, counts, ints, fbuf, foff):
    """Tokens of the lines of `buf` (uint8; lines end at LF, the bytes after the last LF are
    a line).  Token t of a line is of kind head[t], or tail[(t - len(head)) % len(tail)]
    after the head (INT or FLOAT).  skip_blank: blank and '#' lines are skipped (a file);
    otherwise every line counts (blank = no tokens).

    Pass 1 (fill False) writes the token count of every kept line into `counts`; pass 2
    (fill True) writes the integers into `ints` and the float tokens into `fbuf` with
    offsets `foff` (sizes from pass 1).  Returns (kept lines, integers, floats, float
    bytes, 0), or (.., line) with the 1-based line of the first thing outside the fast
    path."""
    n = len(buf)
    nh = len(head)
    nt = len(tail)
    i = 0
    line = 1
    kept = 0
    nint = 0
    nflt = 0
    fpos = 0
    while True:
        while i < n and (buf[i] == SPACE or buf[i] == TAB):
            i += 1
        if skip_blank and i < n and buf[i] == HASH:
            while i < n and buf[i] != LF:
                c = buf[i]
                if c == CR:
                    if i + 1 < n and buf[i + 1] != LF:
                        return kept, nint, nflt, fpos, line
                elif c != TAB and (c < 32 or c > 126):
                    return kept, nint, nflt, fpos, line
                i += 1
        else:
            ntok = 0
            while i < n and buf[i] != LF:
                c = buf[i]
                if c == SPACE or c == TAB:
                    i += 1
                    continue
                if c == CR:
                    if i + 1 < n and buf[i + 1] != LF:
                        return kept, nint, nflt, fpos, line
                    i += 1
                    continue
                start = i
                while i < n and _token_char(buf[i]):
                    i += 1
                if i == start:
                    return kept, nint, nflt, fpos, line
                kind = head[ntok] if ntok < nh else tail[(ntok - nh) % nt]
                if kind == INT:
                    if fill:
                        v, ok = _parse_int(buf, start, i)
                        if not ok:
                            return kept, nint, nflt, fpos, line
                        ints[nint] = v
                    nint += 1
                else:
                    if fill:
                        if not _is_float(buf, start, i):
                            return kept, nint, nflt, fpos, line
                        fbuf[fpos:fpos + i - start] = buf[start:i]
                        foff[nflt + 1] = fpos + i - start
                    fpos += i - start
                    nflt += 1
                ntok += 1
            if ntok > 0 or not skip_blank:
                if not fill:
                    counts[kept] = ntok
                kept += 1
        if i >= n:
            break
        i += 1
        line += 1
    return kept, nint, nflt, fpos, 0


@njit(cache=True)
def _int64(buf, p):
    """Little-endian 8-byte integer at p (negative when the unsigned value is >= 2**63)."""
    v = np.int64(0)
    for b in range(8):
        v |= np.int64(buf[p + b]) << np.int64(8 * b)
    return v


@njit(cache=True)
def walk_images(buf, n):
    """Records of images.bin after its count: header (64 bytes), NUL-terminated name,
    keypoint count (8 bytes), keypoints (24 bytes each).  Returns (record starts, name
    ends, keypoint counts, end, fail, k, byte): fail 0 = all n records read; 1 = the file
    ends inside record k's header, 2 = its name is unterminated, 3 = it ends inside its
    keypoint count, 4 = inside its keypoints (at `byte`).  The caller bounds n by what the
    file can hold: a count that claims more ends in a failure before record n."""
    size = len(buf)
    rec = np.empty(n, np.int64)
    name_end = np.empty(n, np.int64)
    count = np.empty(n, np.int64)
    pos = 8
    for k in range(n):
        if pos + 64 > size:
            return rec, name_end, count, pos, 1, k, pos
        rec[k] = pos
        q = pos + 64
        while q < size and buf[q] != 0:
            q += 1
        if q >= size:
            return rec, name_end, count, pos, 2, k, pos + 64
        name_end[k] = q
        p = q + 1
        if p + 8 > size:
            return rec, name_end, count, pos, 3, k, p
        c = _int64(buf, p)
        p += 8
        if c < 0 or c > (size - p) // 24:
            return rec, name_end, count, pos, 4, k, p
        count[k] = c
        pos = p + 24 * c
    return rec, name_end, count, pos, 0, n, pos


@njit(cache=True)
def walk_points(buf, n):
    """Records of points3D.bin after its count: header (51 bytes, the track length in its
    last 8), track (8 bytes per element).  Returns (record starts, track lengths, end,
    fail, k, byte): fail 1 = the file ends inside record k's header, 2 = inside its
    track (n bounded as in walk_images)."""
    size = len(buf)
    rec = np.empty(n, np.int64)
    count = np.empty(n, np.int64)
    pos = 8
    for k in range(n):
        if pos + 51 > size:
            return rec, count, pos, 1, k, pos
        rec[k] = pos
        c = _int64(buf, pos + 43)
        p = pos + 51
        if c < 0 or c > (size - p) // 8:
            return rec, count, pos, 2, k, p
        count[k] = c
        pos = p + 8 * c
    return rec, count, pos, 0, n, pos


@njit(cache=True)
def gather(buf, starts, lengths, total):
    """The segments buf[starts[k]:starts[k] + lengths[k]], one after the other."""
    out = np.empty(total, np.uint8)
    o = 0
    for k in range(len(starts)):
        s = starts[k]
        ln = lengths[k]
        out[o:o + ln] = buf[s:s + ln]
        o += ln
    return out


@njit(cache=True)
def interleave(a, a_off, b, b_off):
    """a[a_off[k]:a_off[k + 1]] followed by b[b_off[k]:b_off[k + 1]], for every k."""
    out = np.empty(len(a) + len(b), np.uint8)
    o = 0
    for k in range(len(a_off) - 1):
        ln = a_off[k + 1] - a_off[k]
        out[o:o + ln] = a[a_off[k]:a_off[k + 1]]
        o += ln
        ln = b_off[k + 1] - b_off[k]
        out[o:o + ln] = b[b_off[k]:b_off[k + 1]]
        o += ln
    return out


@njit(cache=True)
def repeated_in_image(offsets, rows, n_rows):
    """(K,) True for a keypoint whose point row (rows >= 0) an earlier keypoint of the same
    image already has; the keypoints of image k are offsets[k]:offsets[k + 1]."""
    out = np.zeros(len(rows), np.bool_)
    last = np.full(n_rows, -1, np.int64)  # the last image that saw each point row
    for k in range(len(offsets) - 1):
        for e in range(offsets[k], offsets[k + 1]):
            r = rows[e]
            if r >= 0:
                if last[r] == k:
                    out[e] = True
                else:
                    last[r] = k
    return out
