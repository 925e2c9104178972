"""The fuzz suite's machinery: generated mutations of input files and the properties that
every generated case must have (issue 15).

The suite (tests/fuzz): 6,048 generated cases, the same on every run (CASES: 4,270 reads
through the public API, 575 runs of the command line on broken inputs and 1,200 generated
command lines of every command (test_fuzz_argv.py) in this process, 3 in a process of their
own); the command lines took 53 s on the 2-core development machine under the load of two
other test suites.  Every test of the suite is marked slow (left out by the quick subset,
pytest -m "not slow").  FUZZ_STATS=1 prints what the
cases ended with; FUZZ_SCALE=20 FUZZ_RANDOM=1 searches longer with other cases each run,
FUZZ_STRICT=1 also fails the command line on numpy's RuntimeWarnings.

A base input is a set of files (`Base`: relative path -> bytes, with the kind of each
file).  `mutations(base)` draws one to three mutations; `apply` makes the broken files:

* text: delete, duplicate, swap or insert lines, cut the file, replace / insert / delete /
  copy / quote a field (non-numbers, NaN, inf, huge, negative, other ids of the file),
  random or invalid UTF-8 bytes, byte-order marks (two of them: files joined), a NUL byte
  inside a field, CRLF / CR / other line ends, very long lines, header only, an empty
  file, random bytes, a deleted file;
* TOML: a key set to a value of another type or out of range, broken syntax;
* XML: element text and attribute values replaced, raw markup characters;
* binary (COLMAP .bin): flipped, overwritten, inserted or deleted bytes, a cut file, and
  counts, ids and numbers of the records overwritten with lies (0, 1, 2**31, 2**63, ...);
* bzip2 (BAL .bz2): the text mutations inside the stream, or the compressed bytes broken.

The properties (`check_read`, `check_cli`): reading through the public API returns a block
or raises ProjectError / GeometryError, never another exception, and a ProjectError names
an existing file (or the input, or a file that is not found) with a line inside it; the
command line ends with 0, 2 or 3 without a traceback, leaves the inputs byte-identical and
the output folder absent or one complete run (run.json lists every file, checksums match),
with no staging folder left beside it.
"""

from __future__ import annotations

import bz2
import io
import os
import re
import struct
import tempfile
import warnings
import zlib
from collections import Counter
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st

from baarda.block.model_block import ModelBlock
from baarda.block.photo_block import Block
from baarda.errors import GeometryError, ProjectError

# ---------------------------------------------------------------------- settings
# Examples of each test.  Reading costs 1-25 ms a case, the command line 5-200 ms (most
# broken inputs end at reading), a process of its own about 3 s.
CASES = {
    "project read": 800, "project adjust": 200, "project read_models": 50,
    "project two boms": 60, "project nul": 100,
    "models read": 400, "models command": 80,
    "colmap text read": 400, "colmap whole model read": 60, "colmap binary read": 500,
    "colmap text adjust": 50, "colmap binary adjust": 50,
    "bal read": 200, "bal adjust": 30,  # each for problem.txt and problem.txt.bz2
    "dbat read": 400, "dbat adjust": 25,
    "aicon read": 400, "aicon adjust": 50,
    "photomodeler read": 400, "photomodeler adjust": 30,
    "opensfm read": 300, "opensfm adjust": 30,
    "process": 3,
    "argv": 1200,  # command lines of every command (test_fuzz_argv.py)
}
TWICE = ("bal read", "bal adjust")


def total_cases() -> int:
    return sum(n * (2 if k in TWICE else 1) for k, n in CASES.items())


# Every test of the suite: a fixed seed (CI is deterministic), no example database, and a
# deadline per example far above what a case takes (the margin is for a loaded CI machine).
READ_DEADLINE_MS = 3000
ADJUST_DEADLINE_MS = 30000  # a models case took 12.9 s on a 2-core machine at load 9


# For a longer search on a developer's machine: FUZZ_SCALE=20 runs twenty times the cases,
# FUZZ_RANDOM=1 other ones on every run (CI runs neither).
SCALE = float(os.environ.get("FUZZ_SCALE", "1"))
RANDOM = bool(os.environ.get("FUZZ_RANDOM"))


def fuzz_settings(case: str, deadline_ms: int = READ_DEADLINE_MS):
    """A decorator: the settings of the test of CASES[case], and the case named on the test
    (`fuzz_case`: test_fuzz_suite.py checks that every case has one test)."""
    chosen = settings(max_examples=max(1, round(CASES[case] * SCALE)), derandomize=not RANDOM,
                      database=None, deadline=deadline_ms, print_blob=False,
                      suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

    def decorate(test):
        test = pytest.mark.slow(chosen(test))  # the quick subset leaves the fuzz suite out
        test.fuzz_case = case
        return test

    return decorate


# ---------------------------------------------------------------------- the bases
class Base:
    """The files of a valid input: relative path -> bytes, the kind of each file (csv, text,
    toml, xml, bin, bz2), and for binary files the fields (offset, struct format) that a
    'lie' may overwrite."""

    def __init__(self, files: dict[str, bytes], kinds: dict[str, str],
                 fields: dict[str, list[tuple[int, str]]] | None = None):
        self.files, self.kinds, self.fields = files, kinds, fields or {}

    @property
    def names(self) -> list[str]:
        return list(self.files)

    def __repr__(self) -> str:  # the failing example names the base, not all its bytes
        return f"Base({', '.join(f'{n} ({len(d)} bytes)' for n, d in self.files.items())})"


def load_base(folder: Path, kinds: dict[str, str]) -> Base:
    """The files `kinds` names (relative to `folder`) as a Base."""
    return Base({n: (folder / n).read_bytes() for n in kinds}, dict(kinds))


def write_files(root: Path, files: dict[str, bytes]) -> None:
    for name, data in files.items():
        p = root / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)


def snapshot(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes()
            for p in sorted(root.rglob("*")) if p.is_file()}


# ---------------------------------------------------------------------- values
# Field values that readers must refuse or take: non-numbers, special and extreme numbers,
# integers beyond int32/int64/uint64, numbers in other scripts, markup, control characters.
HOSTILE = [
    "", " ", "nan", "NaN", "-nan", "inf", "-inf", "Infinity", "1e309", "-1e309", "1e308",
    "-1e308", "0", "-0", "0.0", "-1", "-1e-9", "1e-320", "5e-324", "2", "3", "1.5", "0.5",
    "1" + "0" * 400, "-" + "9" * 40, "9223372036854775807", "9223372036854775808",
    "-9223372036854775809", "18446744073709551615", "18446744073709551616", "4294967295",
    "4294967296", "2147483647", "2147483648", "-2147483649", "65536", "abc", "0x1F", "1_000",
    "1,5", "1e", "--1", "+", ".", "e5", "١٢٣", "１２", "𝟙", "²", "Ⅻ", "None", "null", "true",
    "[]", "{}", '"', '"1"', "'", "#", "#1", "\t", "\x00", "\x0b", "\x0c", "\x1c", "\x85",
    "\u00a0", "\u2028", "\ufeff", "é", "\U0001F600", "<", "&", "]]>", "control", "check",
    "tie", "gon", "deg", "rad", "pc", "point", "free", "brown_forward", "brown_backward",
    "PINHOLE", "OPENCV", "FULL_OPENCV", "FISHEYE", "1001", "1", "-2", "99999",
]
RAW = [b"\xff", b"\xfe\xff", b"\xc3", b"\xc3\x28", b"\xed\xa0\x80", b"\xf4\x90\x80\x80",
       b"\x80", b"\x00", b"\x00\x00\x00\x00", b"\r", b"\n", b"\r\n", b"\x1a", b"\xef\xbb\xbf"]
LINES = ["", "#", "# a comment", ",", ",,,,", ",,,,,,,,,,,,,,,,,,,,", " ", "\t", '"', '"a,b"',
         "1", "1 2", "1 2 3", "1,2,3,4,5,6,7,8,9", "a,b,c", "nan nan nan nan",
         "0 0 0 0 0 0 0 0 0 0 0", "1 1 1 1 1 1 1 1 1 1 1", "\x00\x00", "\u2028", "\x0c"]
LONG = [("9", 100_000), ("1,", 50_000), ("1 ", 50_000), ("x", 300_000), (",", 100_000)]
LINE_ENDS = [b"\r\n", b"\r", b"\n\n", b"\n \n", b"\n#\n"]
TWO_BOMS = b"\xef\xbb\xbf\xef\xbb\xbf"
PREFIXES = [b"\xef\xbb\xbf", TWO_BOMS, b"\xff\xfe", b"\xfe\xff", b"\x00",
            b"#", b"\n", b",", b" ", b"\t", b"\r\n"]

values = st.one_of(
    st.sampled_from(HOSTILE),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(2**70), 2**70).map(str),
    st.text(max_size=6),
)
raw_bytes = st.one_of(st.sampled_from(RAW), st.binary(min_size=1, max_size=12))
# positions (taken modulo the number of lines, fields, bytes): scrambled so that the small
# numbers hypothesis favours spread over the file instead of piling up on its first line
index = st.integers(0, 2**31).map(lambda v: (v * 2654435761 + (v >> 7)) % 2**31)

# TOML: keys of a project / model project, and values of every type
TOML_KEYS = ["name", "angle_unit", "image_unit", "crs", "datum", "sigma", "tests", "models",
             "image_um", "control_m", "alpha0", "beta0", "model_xy_um", "model_z_um",
             "pre_xy_um", "pre_z_um", "sigma.image_um", "sigma.control_m", "tests.alpha0",
             "tests.beta0", "sigma.model_xy_um", "models.pre_xy_um"]
TOML_VALUES = [
    '"gon"', '"deg"', '"rad"', '"grad"', '"GON"', '""', '"mm"', '"px"', '"control"',
    '"free"', '"none"', "0", "1", "-1", "2", "0.5", "0.999", "1e-300", "1e300", "nan", "inf",
    "-inf", "-0.0", "true", "false", "[]", "[1]", "[1, 2]", "[1, 2, 3]", "[0, 0, 0]",
    "[-1, 1, 1]", "[1, 2, 3, 4]", '[1, "a", 3]', "[[1], [2], [3]]", "[nan, inf, 1]", "{}",
    "{a = 1}", "{image_um = -1}", '"EPSG:25832"', '"EPSG:4326"', '"EPSG:4979"',
    '"EPSG:0"', '"EPSG:99999999"', '"foo"', '"+proj=garbage"', '"EPSG:5555"',
    '"EPSG:4326+5773"', "1979-05-27", "07:32:00", "1979-05-27T07:32:00Z",
    '"' + "x" * 10_000 + '"', "9223372036854775807", "-9223372036854775808",
    '"\\u0000"', "0x10", "1_000",
]
TOML_LINES = ["[sigma]", "[tests]", "[models]", "[[sigma]]", "[sigma.image_um]", "sigma = 5",
              "tests = \"x\"", "models = []", "sigma = []", "[", "]", "=", "a =", "= 1",
              'name = "unterminated', "name = '''", "[sigma", "x = 1 2", "a.b.c = 1",
              "angle_unit = 'deg'", 'datum = "free"', 'crs = "EPSG:4326"', "\x00",
              "image_um = 1\nimage_um = 2"]

# XML: values of element text and attributes, raw markup
XML_VALUES = ["", " ", "auto", "auto,auto", "0", "0,0", "-1", "nan", "inf", "1e309", "1,2,3",
              "1;2", "1 2", "a,b", "3", "1", "2", "keep", "remove", "mm", "px", "true",
              "$HERE", "$HERE/x", "../x", "/nonexistent/x.txt", "images/images.txt",
              "measurements/markpts.txt", "reference/camcal-fixed.txt", "id,x,y",
              "id,im,x,y", "im,id,x,y,sxy", "id,label,x,y,z", "id,label,x,y,z,sxyz",
              "id,x,y,z,sx,sy,sz", "id,path", "id", "x", "bogus", "<", "&", "&amp;", "&lol;",
              "]]>", "<a>", "</input>", "\x00", "é", "1" + "0" * 400, "1.1", "utf-16",
              "shift_jis", "cp1252", "latin-1", "rot13", "idna", "punycode", "nonsense"]

# COLMAP binary and other count fields: lies
LIES = [0, 1, 2, 3, 7, 255, 256, 65535, 2**31 - 1, 2**31, 2**32 - 1, 2**32, 2**40, 2**62,
        2**63 - 1, 2**63, 2**64 - 1]
FLOAT_LIES = [0.0, -0.0, -1.0, 1e-320, 1e308, -1e308, float("inf"), float("-inf"),
              float("nan"), 1e18]

# ---------------------------------------------------------------------- operations
# (name, strategy of its arguments, weight): token mutations are the most frequent
TEXT_OPS: dict[str, tuple] = {
    "replace_field": (st.tuples(index, index, values), 8),
    "insert_field": (st.tuples(index, index, values), 2),
    "delete_field": (st.tuples(index, index), 2),
    "copy_field": (st.tuples(index, index, index, index), 3),
    "quote_field": (st.tuples(index, index, st.sampled_from(['"', "'", '""', '"x'])), 1),
    "raw_field": (st.tuples(index, index, raw_bytes), 1),
    "delete_lines": (st.tuples(index, st.integers(1, 6)), 2),
    "duplicate_line": (st.tuples(index, index), 2),
    "swap_lines": (st.tuples(index, index), 2),
    "insert_line": (st.tuples(index, st.sampled_from(LINES)), 1),
    "long_line": (st.tuples(index, st.sampled_from(LONG)), 1),
    "truncate": (st.tuples(index), 2),
    "insert_bytes": (st.tuples(index, raw_bytes), 1),
    "flip_bit": (st.tuples(index, st.integers(0, 7)), 1),
    "line_ends": (st.tuples(st.sampled_from(LINE_ENDS)), 1),
    "prefix": (st.tuples(st.sampled_from(PREFIXES)), 1),
    # issue 28: two byte-order marks (files joined) crashed the fast CSV reader or made ids
    # like 01001 integers; a NUL byte in an id made it another id
    "two_boms": (st.tuples(), 1),
    "nul_field": (st.tuples(index, index, index), 1),
    "header_only": (st.tuples(), 1),
    "whole": (st.tuples(st.one_of(st.sampled_from([b"", b"\n", b" ", b"\xef\xbb\xbf"]),
                                  st.binary(max_size=64))), 1),
    "delete_file": (st.tuples(), 1),
}
TOML_OPS = {
    "toml_set": (st.tuples(index, st.sampled_from(TOML_KEYS), st.sampled_from(TOML_VALUES)), 6),
    "toml_line": (st.tuples(index, st.sampled_from(TOML_LINES)), 2),
}
XML_OPS = {
    "xml_text": (st.tuples(index, st.sampled_from(XML_VALUES)), 6),
    "xml_attr": (st.tuples(index, st.sampled_from(XML_VALUES)), 3),
    "xml_drop": (st.tuples(index), 2),
}
BIN_OPS = {
    "lie": (st.tuples(index, st.one_of(st.sampled_from(LIES), st.integers(0, 2**64 - 1)),
                      st.sampled_from(FLOAT_LIES)), 6),
    "flip_bit": (st.tuples(index, st.integers(0, 7)), 2),
    "set_bytes": (st.tuples(index, raw_bytes), 2),
    "insert_bytes": (st.tuples(index, raw_bytes), 1),
    "delete_bytes": (st.tuples(index, st.integers(1, 64)), 1),
    "truncate": (st.tuples(index), 2),
    "whole": (st.tuples(st.binary(max_size=64)), 1),
    "delete_file": (st.tuples(), 1),
}
BZ2_RAW_OPS = {
    "bz2_flip_bit": (st.tuples(index, st.integers(0, 7)), 1),
    "bz2_truncate": (st.tuples(index), 1),
}
# numbers that every reader takes: the files stay readable, the geometry does not
NUMBERS = ["0", "-0", "1", "-1", "2", "0.001", "-0.001", "1e-9", "1e-300", "5e-324", "1e9",
           "-1e9", "1e15", "1e300", "-1e300", "1.7976931348623157e308", "123456789.123",
           "400", "-400", "3.14159", "6.2832", "200", "100", "1000000"]
MILD_OPS = {  # on data lines only (not the header line of a CSV file)
    "data_replace_field": (st.tuples(index, index, st.one_of(
        st.sampled_from(NUMBERS), st.floats(allow_nan=False, allow_infinity=False).map(repr))),
        6),
    "data_copy_field": (st.tuples(index, index, index, index), 2),
    "data_delete_lines": (st.tuples(index, st.integers(1, 20)), 2),
}
OPS = {
    "csv": TEXT_OPS,
    "text": TEXT_OPS,
    "toml": {**TEXT_OPS, **TOML_OPS},
    "xml": {**{k: v for k, v in TEXT_OPS.items() if k in (
        "delete_lines", "duplicate_line", "swap_lines", "truncate", "insert_bytes",
        "flip_bit", "prefix", "line_ends", "whole", "raw_field", "delete_file", "two_boms",
        "nul_field")}, **XML_OPS},
    "bin": BIN_OPS,
    "bz2": {**TEXT_OPS, **BZ2_RAW_OPS},
}


def _weighted(ops: dict) -> list[str]:
    return [name for name, (_, w) in ops.items() for _ in range(w)]


@st.composite
def mutations(draw, base: Base, max_size: int = 3, files: list[str] | None = None,
              mild: bool = False):
    """One to `max_size` mutations (file, operation, arguments) of the files of `base`
    (or of `files` among them); `mild`: only numbers changed and lines deleted or swapped
    in text files (inputs that are read, and then adjusted)."""
    names = files or base.names
    if mild:  # text files, the longer ones more often
        names = [n for n in names if base.kinds[n] in ("csv", "text", "bz2")
                 for _ in range(1 + int(base.files[n].count(b"\n") ** 0.5))]
    out = []
    for _ in range(draw(st.integers(1, max_size))):
        name = draw(st.sampled_from(names))
        ops = MILD_OPS if mild else OPS[base.kinds[name]]
        op = draw(st.sampled_from(_weighted(ops)))
        out.append((name, op, draw(ops[op][0])))
    return out


def any_mutations(base: Base, files: list[str] | None = None):
    """Mutations of any kind, or (as often) mild ones: for the cases that are adjusted."""
    return st.one_of(mutations(base, files=files), mutations(base, files=files, mild=True))


def apply(base: Base, muts: list) -> dict[str, bytes]:
    """The files of `base` with the mutations applied (a deleted file is left out)."""
    files = dict(base.files)
    for name, op, args in muts:
        if name not in files:
            continue
        if op == "delete_file":
            del files[name]
            continue
        kind = base.kinds[name]
        data = files[name]
        if kind == "bz2" and not op.startswith("bz2_"):
            try:
                text = bz2.decompress(data)
            except (OSError, ValueError, EOFError):
                text = data
            files[name] = bz2.compress(_text_op(text, op, args))
        elif kind == "bz2":
            files[name] = _bytes_op(data, op[len("bz2_"):], args, [])
        elif kind == "bin":
            files[name] = _bytes_op(data, op, args, base.fields.get(name, []))
        elif op in TOML_OPS:
            files[name] = _toml_op(data, op, args)
        elif op in XML_OPS:
            files[name] = _xml_op(data, op, args)
        else:
            files[name] = _text_op(data, op, args, kind)
    return files


SEP = re.compile(rb"(,|[ \t]+)")


def _enc(v: str | bytes) -> bytes:
    return v if isinstance(v, bytes) else v.encode("utf-8", "surrogatepass")


def _fields(line: bytes) -> list[bytes]:
    """A line split into fields and separators (fields at the even positions)."""
    return SEP.split(line)


def _text_op(data: bytes, op: str, args: tuple, kind: str = "text") -> bytes:
    if op.startswith("data_"):  # a data line: below the header line of a CSV file
        op = op[len("data_"):]
        if kind == "csv" and b"\n" in data:
            head, _, body = data.partition(b"\n")
            return head + b"\n" + _text_op(body, op, args)
    lines = data.split(b"\n")
    n = len(lines)
    if op in ("replace_field", "insert_field", "delete_field", "quote_field", "raw_field",
              "copy_field"):
        i = args[0] % n
        parts = _fields(lines[i])
        k = 2 * (args[1] % ((len(parts) + 1) // 2))
        if op == "replace_field":
            parts[k] = _enc(args[2])
        elif op == "raw_field":
            parts[k] = parts[k][:1] + args[2] + parts[k][1:]
        elif op == "insert_field":
            sep = b"," if b"," in lines[i] else b" "
            parts[k:k] = [_enc(args[2]), sep]
        elif op == "delete_field":
            del parts[k:k + 2]
        elif op == "quote_field":
            q = args[2].encode()
            parts[k] = q + parts[k] + (q if len(q) == 1 else b"")
        else:  # copy_field: a value from elsewhere in the file (ids, unknown references)
            other = _fields(lines[args[2] % n])
            parts[k] = other[2 * (args[3] % ((len(other) + 1) // 2))]
        lines[i] = b"".join(parts)
    elif op == "delete_lines":
        i = args[0] % n
        del lines[i:i + args[1]]
    elif op == "duplicate_line":
        lines.insert(args[1] % (n + 1), lines[args[0] % n])
    elif op == "swap_lines":
        i, j = args[0] % n, args[1] % n
        lines[i], lines[j] = lines[j], lines[i]
    elif op == "insert_line":
        lines.insert(args[0] % (n + 1), _enc(args[1]))
    elif op == "long_line":
        unit, count = args[1]
        lines.insert(args[0] % (n + 1), _enc(unit * count))
    elif op == "truncate":
        return data[:args[0] % (len(data) + 1)]
    elif op == "insert_bytes":
        k = args[0] % (len(data) + 1)
        return data[:k] + args[1] + data[k:]
    elif op == "flip_bit":
        if not data:
            return data
        k = args[0] % len(data)
        return data[:k] + bytes([data[k] ^ (1 << args[1])]) + data[k + 1:]
    elif op == "line_ends":
        return data.replace(b"\n", args[0])
    elif op == "prefix":
        return args[0] + data
    elif op == "two_boms":
        return TWO_BOMS + data
    elif op == "nul_field":
        i = args[0] % n
        parts = _fields(lines[i])
        k = 2 * (args[1] % ((len(parts) + 1) // 2))
        j = args[2] % (len(parts[k]) + 1)
        parts[k] = parts[k][:j] + b"\x00" + parts[k][j:]
        lines[i] = b"".join(parts)
    elif op == "header_only":
        keep = [s for s in lines if s.strip() and not s.lstrip().startswith(b"#")][:1]
        return b"\n".join(keep) + b"\n"
    elif op == "whole":
        return args[0]
    else:  # pragma: no cover
        raise AssertionError(op)
    return b"\n".join(lines)


def _bytes_op(data: bytes, op: str, args: tuple, fields: list[tuple[int, str]]) -> bytes:
    if op == "lie":
        if not fields:
            return data
        offset, fmt = fields[args[0] % len(fields)]
        if fmt.endswith("d"):
            value = struct.pack(fmt, args[2])
        else:
            size = struct.calcsize(fmt)
            value = (args[1] % (1 << (8 * size))).to_bytes(size, "little")
        return data[:offset] + value + data[offset + len(value):]
    if op == "set_bytes":
        k = args[0] % (len(data) + 1)
        return data[:k] + args[1] + data[k + len(args[1]):]
    if op == "delete_bytes":
        k = args[0] % (len(data) + 1)
        return data[:k] + data[k + args[1]:]
    return _text_op(data, op, args)  # flip_bit, insert_bytes, truncate, whole


def _toml_op(data: bytes, op: str, args: tuple) -> bytes:
    lines = data.split(b"\n")
    i = args[0] % (len(lines) + 1)
    if op == "toml_set":
        key, value = args[1], args[2]
        line = f"{key} = {value}".encode()
        j = args[0] % len(lines)
        if args[0] % 2 == 0:  # replace a line (an assignment, a table header), or insert
            lines[j] = line
        else:
            lines.insert(i, line)
    else:
        lines.insert(i, _enc(args[1]))
    return b"\n".join(lines)


XML_TEXT = re.compile(rb">([^<>]*)<")
XML_ATTR = re.compile(rb'="([^"]*)"')
XML_ELEMENT = re.compile(rb"<([A-Za-z_][\w.-]*)[^<>]*>[^<]*</\1>")


def _xml_op(data: bytes, op: str, args: tuple) -> bytes:
    pattern = {"xml_text": XML_TEXT, "xml_attr": XML_ATTR, "xml_drop": XML_ELEMENT}[op]
    found = list(pattern.finditer(data))
    if not found:
        return data
    m = found[args[0] % len(found)]
    if op == "xml_drop":
        return data[:m.start()] + data[m.end():]
    return data[:m.start(1)] + _enc(args[1]) + data[m.end(1):]


# ---------------------------------------------------------------------- properties
def _line_count(path: Path) -> int:
    """Lines of a file as an editor counts them (LF, CRLF or CR; inside a .bz2 file)."""
    data = path.read_bytes()
    if path.suffix == ".bz2":
        try:
            data = bz2.BZ2Decompressor().decompress(data, max_length=1 << 26)
        except (OSError, EOFError, ValueError):
            return 0
    return len(data.splitlines())


def check_error(err: ProjectError, inputs: list[Path]) -> None:
    """A ProjectError names an existing file or folder (or the input, or a file that was
    not found) and, for a text file, a line inside it."""
    p = Path(err.path)
    missing = "not found" in err.detail or "cannot be read" in err.detail
    named = missing or any(err.path == str(q) for q in inputs) or p.exists()
    assert named, f"ProjectError names no existing file: {err}"
    if err.line is not None:
        assert isinstance(err.line, int) and err.line >= 1, err
        if not missing and p.is_file():
            n = _line_count(p)
            assert err.line <= n + 1, f"line {err.line} beyond the end of {p} ({n} lines)"
    if err.column is not None:
        assert isinstance(err.column, str) and err.column, err


# what the cases ended with (FUZZ_STATS=1 prints it at the end of the session)
OUTCOMES: Counter = Counter()


def _record(what: str, outcome: str) -> None:
    if os.environ.get("FUZZ_STATS"):
        OUTCOMES[(what, outcome)] += 1


def check_read(read, path: Path, computes: bool = False):
    """`read(path)` returns a Block (ModelBlock) or raises ProjectError / GeometryError;
    any other exception propagates (and fails the test).  A reader that does not compute
    (`computes`: forming models does) does not overflow on the numbers it takes: a
    RuntimeWarning fails the test."""
    what = f"read {getattr(read, '__name__', 'read')}"
    try:
        with warnings.catch_warnings():
            if not computes:
                warnings.simplefilter("error", RuntimeWarning)
            result = read(path)
    except ProjectError as e:
        check_error(e, [path])
        _record(what, f"ProjectError: {re.sub(r'[0-9]+', 'N', e.detail)[:60]}")
        return e
    except GeometryError as e:
        _record(what, f"GeometryError: {str(e)[:50]}")
        return e
    assert isinstance(result, (Block, ModelBlock)), type(result)
    _record(what, "read")
    return result


def check_cli(command: list[str], path: Path, inputs: Path, out: Path) -> int:
    """`baarda COMMAND PATH -o OUT -q` in this process: exit code 0, 2 or 3, no traceback,
    the inputs byte-identical, OUT absent or one complete run, nothing staged left."""
    from baarda.cli import main

    before = snapshot(inputs)
    stdout, stderr = io.StringIO(), io.StringIO()
    with redirect_stdout(stdout), redirect_stderr(stderr), warnings.catch_warnings():
        if os.environ.get("FUZZ_STRICT"):  # a developer's search for numerical warnings
            warnings.simplefilter("error", RuntimeWarning)
        code = main([*command, str(path), "-o", str(out), "-q"])
    text = stdout.getvalue() + stderr.getvalue()
    assert code in (0, 2, 3), (code, text)
    assert "Traceback" not in text, text
    assert snapshot(inputs) == before, "the command changed its input"
    check_output(out, code, stderr.getvalue())
    _record(command[0], f"exit {code}: {re.sub(r'[0-9]+', 'N', stderr.getvalue())[15:75]}")
    return code


def check_output(out: Path, code: int, err: str) -> None:
    """OUT is absent after an error, else one complete run; no .partial/.old beside it."""
    import json

    from baarda.io.run_manifest import MANIFEST, verify_run

    left = [p.name for p in out.parent.iterdir() if p.name.endswith((".partial", ".old"))]
    assert not left, f"staging folders left: {left}"
    if code == 2:
        assert not out.exists(), "an error left an output folder"
        # the error's line (notes and warnings, kept by -q, may come before it)
        assert any(ln.startswith("baarda: error: ") for ln in err.splitlines()), err
        return
    assert (out / MANIFEST).is_file(), "a run without run.json"
    listed = json.loads((out / MANIFEST).read_text(encoding="utf-8"))["files"]
    present = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    assert present == set(listed) | {MANIFEST}, (present, set(listed))
    assert verify_run(out, sorted(listed)) is not None


# ---------------------------------------------------------------------- one case
def read_case(base: Base, muts: list, work: Path, read, entry: str | None = None,
              computes: bool = False):
    """Write the mutated files of `base` into a new folder and check `read` on it (the
    folder, or the file `entry` in it)."""
    with tempfile.TemporaryDirectory(dir=work) as d:
        root = Path(d) / "in"
        root.mkdir()
        write_files(root, apply(base, muts))
        return check_read(read, root / entry if entry else root, computes)


def cli_case(base: Base, muts: list, work: Path, command: list[str],
             entry: str | None = None) -> int:
    """Write the mutated files of `base` into a new folder and check the command on it."""
    with tempfile.TemporaryDirectory(dir=work) as d:
        root = Path(d) / "in"
        root.mkdir()
        write_files(root, apply(base, muts))
        return check_cli(command, root / entry if entry else root, root, Path(d) / "out")


# ---------------------------------------------------------------------- the tests of a format
def first_file(base: Base) -> str:
    """The entry of a base of one file: that file."""
    return base.names[0]


def _entry(entry, base: Base, data) -> str | None:
    """The file read in the base's folder: None (the folder), a name, a function of the base
    or a strategy drawn from."""
    if isinstance(entry, st.SearchStrategy):
        return data.draw(entry)
    return entry(base) if callable(entry) else entry


def _fuzz_test(case: str, base: str, deadline_ms: int, body):
    """The hypothesis test of CASES[case] on the session fixture `base` (named: requested by
    the test, so that a parametrised base gives one test per parameter); body(base, work,
    data) runs one example."""

    def test(request, data):
        body(request.getfixturevalue(base), request.getfixturevalue("work"), data)

    test = given(data=st.data())(test)
    if not RANDOM:  # a seed of each test's own (the tests of this factory share a source)
        test = seed(zlib.crc32(case.encode()))(test)
    return pytest.mark.usefixtures(base, "work")(fuzz_settings(case, deadline_ms)(test))


def read_test(case: str, base: str, read, *, entry=None, draw=mutations,
              computes: bool = False, deadline_ms: int = READ_DEADLINE_MS):
    """The test of CASES[case]: `read` (baarda.pipeline.read, read_models) of mutations
    (`draw`: mutations or any_mutations) of the fixture `base`, read from its folder or from
    `entry` in it (see _entry): check_read's properties."""

    def body(b: Base, work: Path, data) -> None:
        read_case(b, data.draw(draw(b)), work, read, _entry(entry, b, data), computes)

    return _fuzz_test(case, base, deadline_ms, body)


def cli_test(case: str, base: str, command=("adjust",), *, entry=None, draw=any_mutations,
             deadline_ms: int = ADJUST_DEADLINE_MS):
    """The test of CASES[case]: `baarda COMMAND` on mutations (`draw`) of the fixture
    `base` (its folder or `entry` in it): check_cli's properties."""

    def body(b: Base, work: Path, data) -> None:
        cli_case(b, data.draw(draw(b)), work, list(command), _entry(entry, b, data))

    return _fuzz_test(case, base, deadline_ms, body)


def format_tests(name: str, base: str, *, read=None, entry=None, command=("adjust",),
                 cli_name: str | None = None, cli_base: str | None = None, cli_entry=None,
                 cli_draw=any_mutations):
    """The pair of tests of an input format: reading mutations of the fixture `base`
    (CASES[f"{name} read"], through `read`, default baarda.pipeline.read) and the command
    line on them (CASES[cli_name], default f"{name} {command[0]}"; on `cli_base` and
    `cli_entry` when they differ from the reading's)."""
    if read is None:
        from baarda.pipeline import read
    return (read_test(f"{name} read", base, read, entry=entry),
            cli_test(cli_name or f"{name} {command[0]}", cli_base or base, command,
                     entry=entry if cli_entry is None else cli_entry, draw=cli_draw))
