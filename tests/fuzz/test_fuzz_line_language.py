"""The line languages of `baarda online` (model by model, relative/online_commands.py) and
`online --bundle` (online/commands.py) fed every Python attribute name of their interpreter
classes as a command (with and without underscores), a byte-order mark, and hostile
numbers: each line is a documented command or an "unknown command" LineError, the
interpreter's state is unchanged by a refused line, and it goes on (issue 43: a word reached
private methods and `__init__` through getattr)."""

import itertools
from pathlib import Path

import pytest

import baarda
from baarda.online.bundle import OnlineBundle
from baarda.online.commands import COMMANDS, KEYWORDS, BundleInterpreter
from baarda.options import TestOptions
from baarda.relative.online_commands import KEYWORDS as RELATIVE_KEYWORDS
from baarda.relative.online_commands import Interpreter, LineError

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo"
STRIP = ROOT / "examples" / "online" / "strip.txt"


def attribute_words(*objects) -> list[str]:
    """Every attribute name of the objects and their classes, as written and with one,
    two or all leading underscores (and a prefix _do_) taken off."""
    names = set()
    for obj in objects:
        names |= set(dir(obj)) | set(dir(type(obj))) | set(getattr(obj, "__dict__", {}))
    words = set()
    for n in names:
        words |= {n, n.lstrip("_"), n[1:], n[2:], n.removeprefix("_do_")}
    return sorted(w for w in words if w)


@pytest.fixture(scope="module")
def bundle():
    return OnlineBundle(baarda.read(DEMO), TestOptions())


def test_the_table_names_exactly_the_documented_commands():
    assert sorted(COMMANDS) == sorted(KEYWORDS)
    doc = BundleInterpreter.__module__
    import importlib

    text = importlib.import_module(doc).__doc__
    for word in KEYWORDS:
        assert f"    {word}" in text or f"| {word}" in text or f" {word} " in text


def test_bundle_language_refuses_every_attribute_name(bundle):
    said: list[str] = []
    interp = BundleInterpreter(bundle, said.append)
    words = [w for w in attribute_words(interp, bundle) if w.lower() not in KEYWORDS]
    assert {"_tell", "tell", "_dict__", "_class__", "_init__", "gnss_sigma", "_repr__",
            "_getattribute__"} <= set(words)
    state = (bundle.m.n_rows if hasattr(bundle.m, "n_rows") else None, len(interp.answers),
             interp.collecting, interp.done, interp.ob, interp.say)
    for word, args in itertools.product(words, ["", " a b", " 1 2 3"]):
        with pytest.raises(LineError, match=f"unknown command '{word.lower()}'"):
            interp.feed(word + args)
    assert (bundle.m.n_rows if hasattr(bundle.m, "n_rows") else None, len(interp.answers),
            interp.collecting, interp.done, interp.ob, interp.say) == state
    assert said == [said[0]] if said else True  # only the block's first answer
    interp.feed("status")  # it goes on
    assert said[-1] == bundle.status()


def test_relative_language_refuses_every_attribute_name():
    said: list[str] = []
    interp = Interpreter(said.append, focal=152.0)
    words = [w for w in attribute_words(interp) if w.lower() not in RELATIVE_KEYWORDS]
    for word in words:
        with pytest.raises(LineError, match="unknown command"):
            interp.feed(word + " 1 2")
    assert interp.session is None and not interp.done and interp.collecting is None
    for line in STRIP.read_text().splitlines():
        interp.feed(line)
    interp.finish()
    assert interp.session is not None and len(interp.session.accepted) == 3


@pytest.mark.parametrize("line, column", [
    ("control 001001 1 2 3 -1 -1 -1", "sX"),
    ("control 001001 1 2 3 1e308 1e308 1e308", "sX"),
    ("control 001001 1 2 3 0.01 0 0.01", "sY"),
    ("control 001001 1e308 2 3", "X"),
    ("gnss 01001 1 2 3 -0.1 0.1 0.1", "sX"),
    ("point 01001 001001 1 2 -5", "sigma"),
    ("point 01001 001001 1e300 2", "x"),
    ("remeasure 01001 001001 1 2 1e300", "sigma"),
])
def test_bundle_language_bounds_its_numbers(bundle, line, column):
    interp = BundleInterpreter(bundle, lambda s: None)
    with pytest.raises(LineError) as e:
        interp.feed(line)
    assert e.value.column == column


def test_a_byte_order_mark_before_the_first_line(bundle, tmp_path):
    from baarda.cli.common import feed_lines

    said: list[str] = []
    interp = BundleInterpreter(bundle, said.append)
    feed_lines(interp, ["\ufeffstatus", "help"], "<stdin>")
    assert said[-2] == bundle.status()
    rel = Interpreter(lambda s: None)
    lines = STRIP.read_text().splitlines()
    feed_lines(rel, ["\ufeff" + lines[0], *lines[1:]], "strip.txt")
    assert len(rel.session.accepted) == 3
