"""Argument types: every option's value is checked where argparse parses it, so a bad value
ends at once with exit 2 and a message naming the option and its valid range
("argument --strips: an integer >= 1, not '0'").  Each factory returns the `type=` callable
of an option; its name is what argparse prints for a value it cannot convert."""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Callable, Iterable


def _bad(kind: str, text: str) -> argparse.ArgumentTypeError:
    return argparse.ArgumentTypeError(f"{kind}, not {text!r}")


def integer(lo: int | None = None, hi: int | None = None) -> Callable[[str], int]:
    """An integer in [lo, hi] (either end may be open-ended: None)."""
    if lo is not None and hi is not None:
        kind = f"an integer from {lo} to {hi}"
    elif lo is not None:
        kind = f"an integer >= {lo}"
    elif hi is not None:
        kind = f"an integer <= {hi}"
    else:
        kind = "an integer"

    def parse(text: str) -> int:
        try:
            value = int(text.strip())
        except ValueError:
            raise _bad(kind, text) from None
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise _bad(kind, text)
        return value

    parse.__name__ = "integer"
    return parse


def number(lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
           hi_open: bool = False, unit: str = "") -> Callable[[str], float]:
    """A finite number in the interval from lo to hi, each end closed unless `*_open`
    (None: unbounded); `unit` is named in the message."""
    u = f" {unit}" if unit else ""
    if lo is not None and hi is not None:
        kind = (f"a number in {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
                f"{u}")
    elif lo is not None:
        kind = f"a number {'>' if lo_open else '>='} {lo:g}{u}"
    elif hi is not None:
        kind = f"a number {'<' if hi_open else '<='} {hi:g}{u}"
    else:
        kind = f"a finite number{u}"

    def parse(text: str) -> float:
        try:
            value = float(text.strip())
        except ValueError:
            raise _bad(kind, text) from None
        if not math.isfinite(value):
            raise _bad(kind, text)
        if lo is not None and (value < lo or (lo_open and value == lo)):
            raise _bad(kind, text)
        if hi is not None and (value > hi or (hi_open and value == hi)):
            raise _bad(kind, text)
        return value

    parse.__name__ = "number"
    return parse


def positive(unit: str = "", hi: float | None = None) -> Callable[[str], float]:
    """A finite number > 0 (and <= hi)."""
    return number(0.0, hi, lo_open=True, unit=unit)


def non_negative(unit: str = "", hi: float | None = None) -> Callable[[str], float]:
    """A finite number >= 0 (and <= hi)."""
    return number(0.0, hi, unit=unit)


#: a-priori standard deviations: of image coordinates (µm), of ground coordinates (m), and
#: cofactor ratios (from a millionth to a million: beyond, the weights overflow)
SIGMA_UM = number(1e-3, 1e4, unit="µm")
SIGMA_M = number(1e-6, 1e4, unit="m")
COFACTOR = number(1e-6, 1e6)
#: a significance level (alpha0 of the w-test, a global test's level; below 1e-12 the
#: B-method's non-centrality is beyond double precision) and a power (beta0)
alpha = number(1e-12, 0.5, hi_open=True)
power = number(0.5, 0.99999)
#: an overlap of neighbouring photos: from 0 up to (not including) 1
overlap = number(0.0, 1.0, hi_open=True)
#: a random seed (numpy's generators take integers >= 0)
seed = integer(0, 2**63 - 1)


def choices_list(allowed: Iterable[str], *, what: str = "values",
                 special: Iterable[str] = ()) -> Callable[[str], str]:
    """A comma list of `allowed` items (at least one, each at most once), or one of the
    `special` words alone; the text is returned as given (stripped)."""
    allowed, special = list(allowed), list(special)
    words = " or ".join(f"'{s}'" for s in special)
    kind = f"a comma list of {what} from {', '.join(allowed)}" + (f", or {words}"
                                                                  if words else "")

    def parse(text: str) -> str:
        t = text.strip()
        if t in special:
            return t
        items = [s.strip() for s in t.split(",")]
        if not items or any(s not in allowed for s in items) or len(set(items)) != len(items):
            raise _bad(kind, text)
        return ",".join(items)

    parse.__name__ = "list"
    return parse


def pattern_spec(named: Iterable[str], max_side: int) -> Callable[[str], str]:
    """A point pattern: a name, CxR[+corners|+edges] with 2 <= C, R <= max_side, or a CSV
    file (a name ending in .csv, or an existing file)."""
    import os

    named = list(named)
    kind = (f"one of {', '.join(named)}, CxR, CxR+corners or CxR+edges (2 to {max_side} "
            "columns and rows), or a CSV file")

    def parse(text: str) -> str:
        if text in named or text.lower().endswith(".csv") or os.path.isfile(text):
            return text
        m = re.fullmatch(r"(\d+)x(\d+)(\+corners|\+edges)?", text)
        if not m or not all(2 <= int(g) <= max_side for g in m.groups()[:2]):
            raise _bad(kind, text)
        return text

    parse.__name__ = "pattern"
    return parse


def text_encoding(text: str) -> str:
    """A text encoding Python knows (utf-8, cp1252, latin-1, ...)."""
    import codecs

    try:
        codecs.lookup(text)
    except LookupError:
        raise _bad("a text encoding such as utf-8, cp1252 or latin-1", text) from None
    return text


def scheduler_address(text: str) -> str:
    """A Dask scheduler's address: [PROTOCOL://]HOST:PORT."""
    m = re.fullmatch(r"(?:(tcp|tls|inproc|ucx|ws|wss)://)?([^\s:/]+|\[[0-9a-fA-F:]+\]):(\d+)",
                     text.strip())
    if not m or not 0 < int(m.group(3)) < 65536:
        raise _bad("an address PROTOCOL://HOST:PORT, e.g. tcp://host:8786", text)
    return text.strip()


class Pair(argparse.Action):
    """nargs=2 values LO HI that must satisfy LO <= HI (or LO < HI with `strict`)."""

    def __init__(self, *args, strict: bool = False, **kwargs):
        self.strict = strict
        super().__init__(*args, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        lo, hi = values
        if lo > hi or (self.strict and lo == hi):
            parser.error(f"argument {option_string}: {self.metavar[0]} must be "
                         f"{'<' if self.strict else '<='} {self.metavar[1]}, not {lo:g} "
                         f"{hi:g}")
        setattr(namespace, self.dest, list(values))
