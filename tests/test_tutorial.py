"""docs/tutorial.md prints what the program prints: every `console` block is run and its
output compared (`[...]` within a line and a line `...` match anything)."""

import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

from baarda.cli import main

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "tutorial.md"


def console_blocks(text: str) -> list[list[tuple[str, list[str]]]]:
    """Each ```console block as [(command, expected output lines)]."""
    blocks = []
    for body in re.findall(r"```console\n(.*?)```", text, flags=re.S):
        steps: list[tuple[str, list[str]]] = []
        for line in body.splitlines():
            if line.startswith("$ "):
                steps.append((line[2:], []))
            else:
                steps[-1][1].append(line)
        blocks.append(steps)
    return blocks


def pattern(expected: list[str]) -> str:
    parts = []
    for line in expected:
        if line == "...":
            parts.append(r"(?:[^\n]*\n)*?")
        else:
            parts.append(".*?".join(re.escape(p) for p in line.split("[...]")) + r"\n")
    return "".join(parts)


def test_the_tutorial_has_console_blocks():
    blocks = console_blocks(TUTORIAL.read_text(encoding="utf-8"))
    assert len(blocks) >= 3 and sum(len(b) for b in blocks) >= 5


SHARED = ROOT.parent / "shared"


@pytest.mark.slow
def test_the_tutorial_prints_what_the_program_prints(tmp_path, monkeypatch):
    """Run from a checkout's root: examples/ beside, ../shared/data (real data sets that may
    not be copied) above; blocks that read ../shared are skipped when it is absent."""
    repo = tmp_path / "baarda"
    repo.mkdir()
    (repo / "examples").symlink_to(ROOT / "examples")
    if SHARED.is_dir():
        (tmp_path / "shared").symlink_to(SHARED)
    monkeypatch.chdir(repo)
    for block in console_blocks(TUTORIAL.read_text(encoding="utf-8")):
        if any("../shared" in c for c, _ in block) and not SHARED.is_dir():
            continue  # the real data sets are not beside this checkout
        for command, expected in block:
            argv = shlex.split(command)
            assert argv[0] == "baarda"
            out, err = io.StringIO(), io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = main(argv[1:])
            # what a terminal shows: the printout, then notes, warnings and the verdict on
            # stderr (the progress display shows only on a terminal: not here)
            shown = out.getvalue() + err.getvalue() if code == 0 else err.getvalue()
            if not re.fullmatch(pattern(expected), shown):
                pytest.fail(f"{command}: the tutorial shows\n" + "\n".join(expected)
                            + "\nbut baarda printed\n" + shown)


def test_the_prose_quotes_the_printout_s_iterations():
    """'converges in N Gauss-Newton iterations' is the printout's 'iterations N
    (converged)' shown above it (the prose said three where the printout says 4; the
    printout itself is run by test_the_tutorial_prints_what_the_program_prints)."""
    text = TUTORIAL.read_text(encoding="utf-8")
    printed = re.findall(r"^iterations (\d+) \(converged\)", text, flags=re.M)
    said = re.findall(r"converges in (\w+) Gauss-Newton iterations", text)
    assert printed and said
    words = {"one": "1", "two": "2", "three": "3", "four": "4", "five": "5", "six": "6"}
    assert [words.get(w, w) for w in said] == printed[:len(said)] == ["4"]
