"""Fuzzing the argument vectors of every command (issue 29), in this process.

Each example is a command line drawn from the commands' own parsers (cli.build_parser: every
option of every command, with its nargs and choices), the values of each option drawn from
hostile tokens of its kind (numbers: 0, -1, nan, inf, 1e309, text ...; integers; comma
lists; paths: missing, a file, the input itself) and from small valid ones, so that most
lines end at parsing and those that run stay cheap (tiny inputs, few trials).  Sizes that
are valid but large (a 1000-strip block) are not drawn: they are legitimate and slow.

The properties: exit code 0, 2 or 3 (or argparse's 0 for --help), no traceback, every input
byte-identical (a FIFO, a link loop and a dangling link among them: none opened, replaced or
followed into new folders; no device node is named), the output folder absent (or, when it
held an earlier run, that run as it was) or one complete run, no staging folder and no
temporary file left."""

from __future__ import annotations

import argparse
import io
import os
import shutil
import sys
import tempfile
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import pytest
from fuzz.fuzzing import ADJUST_DEADLINE_MS, _record, check_output, fuzz_settings, snapshot
from hypothesis import given
from hypothesis import strategies as st

from baarda.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[2]

# ---------------------------------------------------------------------- tokens
NUMBERS = ["0", "-0", "1", "-1", "2", "0.5", "0.05", "0.001", "0.999", "1.0", "3", "1e-300",
           "5e-324", "1e9", "-1e9", "1e308", "-1e308", "1e309", "nan", "NaN", "inf", "-inf",
           "abc", "", " ", "1,5", "0x10", "1_0", "١", "--", "-"]
INTEGERS = ["0", "-0", "1", "2", "3", "-1", "-2", "1.5", "1e3", "nan", "abc", "", "0x2",
            "9" * 30, "-" + "9" * 30, "1 ", " 2", "٣"]
# (no NUL: a command line cannot hold one, execve ends each argument there)
TEXT = ["", " ", "x", "x,y", "X,Y,Z", "1,2,3", "1", ",", ",,", "all", "none", "a\tb",
        "\u2028", "é", "-", "--", "'", '"', "%s", "{}", "$HOME", "*", "x" * 5000]
LISTS = {
    "stages": ["1", "1,2", "3,2,1", "2", "9", "1,1", "0", "1,,2", ""],
    "blunder_kinds": ["x", "x,y", "X,Y,Z", "y,Z", "q", "x,x", "x,", ""],
    "strategies": ["snoop", "tau", "robust", "screen", "modified", "bogus", "snoop,tau",
                   ""],
    "deformations": ["all", "none", "twist", "bogus", "all,none", ""],
    "calibrate": ["all", "none", "c", "c,x0,y0", "k1,k2", "zz", "c,c", ""],
    "check_gcp": ["alternate", "1", "zz", "", ","],
    "crs": ["EPSG:32632", "EPSG:4326", "EPSG:0", "garbage", "+proj=nonsense", ""],
    "table": ["baarda", "gruen", "missing.csv", ""],
    "encoding": ["utf-8", "latin-1", "cp1252", "bogus-enc", "utf-16", ""],
    "scheduler": ["", "bogus", "tcp://", "tcp://host", "host:0", "host:99999", "::1"],
    "name": ["p", "", "a b", "a\nb", 'q"t', "x" * 300],
    "deformation": ["twist=5", "bogus=1", "twist=", "twist=nan", "=", "twist=1e309"],
}
# integers whose valid values make long runs: only small ones are drawn
SMALL = {"strips": ["1", "2", "3"], "photos": ["2", "3"], "models": ["1", "2", "3"],
         "trials": ["1", "2"], "pattern": ["2", "3"], "workers": ["1"], "jobs": [],
         "vector_photos": ["0", "2"], "max_points": ["10", "1000"], "max_rows": ["5"],
         "top": ["0", "5"], "line_width": ["5", "60"], "worst": ["0", "3"],
         "check_points": ["1", "12", "1000"], "blunders": ["1", "3", "100000"],
         "control_spacing": ["1", "2"], "height_chains": ["0", "1"]}


class Inputs:
    """The inputs the command lines name (made once; checked unchanged after each line)."""

    def __init__(self, root: Path):
        from baarda.output.project_files import write_model_project, write_project
        from baarda.simulate.aerial import FlightPlan, simulate_block
        from baarda.simulate.model_blocks import ModelPlan, simulate_models

        self.root = root
        self.project = root / "tiny"
        block, _ = simulate_block(FlightPlan(strips=2, photos_per_strip=3, check_points=1,
                                             seed=2))
        write_project(block, self.project)
        self.models = root / "models"
        write_model_project(simulate_models(ModelPlan(strips=1, models_per_strip=2))[0],
                            self.models)
        self.results = root / "results"
        assert main(["adjust", str(self.project), "-o", str(self.results), "--snoop",
                     "-qq"]) == 0
        self.strip = root / "strip.txt"
        shutil.copy(ROOT / "examples" / "online" / "strip.txt", self.strip)
        self.pattern = root / "pattern.csv"
        self.pattern.write_text("name,x,y,tie\n1,0,90,1\n2,0,0,1\n3,0,-90,1\n4,90,90,0\n"
                                "5,90,0,0\n6,90,-90,0\n")
        self.file = root / "notes.txt"
        self.file.write_text("not a project\n")
        self.empty = root / "empty"
        self.empty.mkdir()
        self.loop = root / "loop"  # a symbolic link loop
        self.loop.symlink_to("loop")
        self.fifo = root / "pipe"  # a FIFO: never opened (it would block), never replaced
        os.mkfifo(self.fifo)
        self.dangling = root / "dangling"  # a link into folders that do not exist
        self.dangling.symlink_to(root / "missing" / "deeper" / "x")
        self.folders = [self.project, self.models, self.results, self.empty]
        self.before = snapshot(root)

    def paths(self) -> list[str]:
        """Input paths of any kind: valid, of another kind, missing, hostile."""
        missing = self.root / "missing"
        return [str(p) for p in (self.project, self.models, self.results, self.strip,
                                 self.pattern, self.file, self.empty, missing,
                                 self.results / "observations.csv", self.results /
                                 "summary.json", self.loop)] + [
            "", "-", str(self.fifo), str(self.dangling), "/proc", "x" * 5000,
            str(self.root / ("y" * 300))]

    def unchanged(self) -> None:
        assert snapshot(self.root) == self.before, "a command changed an input"
        assert self.fifo.is_fifo() and self.loop.is_symlink() and self.dangling.is_symlink()
        assert not (self.root / "missing").exists(), "a link's missing folders were made"


@pytest.fixture(scope="session")
def inputs(work) -> Inputs:
    return Inputs(work / "argv-inputs")


# ---------------------------------------------------------------------- the grammar
def commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


# `review` serves until Ctrl-C (and opens a browser): its command line is tested as a
# process in tests/review/test_review_cli.py, not drawn here
COMMANDS = {name: p for name, p in commands().items() if name != "review"}
# positional inputs of each command (the first value drawn is the usual one)
POSITIONAL = {"adjust": "project", "snoop": "project", "screen": "project",
              "convert": "project", "modified-snoop": "project", "models": "models",
              "report": "results", "residuals": "observations", "online": "strip",
              "pattern": "spec", "check": "results"}
SINGLE_FILE_OUTPUTS = {"svg", "derive_table", "quality", "pdf"}


def _kind(action: argparse.Action) -> str:
    """What values an option takes: 'flag', 'choice', 'integer', 'number', 'path', a key
    of LISTS, or 'text'."""
    if action.nargs == 0:
        return "flag"
    if action.choices is not None:
        return "choice"
    name = getattr(action.type, "__name__", "")
    if action.type is int or name == "integer":
        return "integer"
    if action.type is float or name == "number":
        return "number"
    if action.dest in LISTS:
        return action.dest
    if action.type is Path or action.dest in ("file", "files", "camera", "clusters",
                                               "hypotheses", "project"):
        return "path"
    return "text"


@st.composite
def values(draw, action: argparse.Action, inputs: Inputs, work: Path,
           own: list[str] | None = None) -> list[str]:
    """Values of an option; `own`: the command's input paths (an output may name them)."""
    others = {str(inputs.strip), str(inputs.pattern), str(inputs.results / "observations.csv")}
    kind = _kind(action)
    if kind == "flag":
        return []
    n = action.nargs
    count = n if isinstance(n, int) else (draw(st.integers(1, 3)) if n == "+" else 1)
    out = []
    for _ in range(count):
        if kind == "choice":
            pool = [str(c) for c in action.choices] + ["bogus", ""]
        elif kind == "integer":
            pool = SMALL.get(action.dest, ["1", "2"]) + INTEGERS
        elif kind == "number":
            pool = NUMBERS
        elif kind == "path" and (action.dest in SINGLE_FILE_OUTPUTS or action.dest == "out"):
            # a file to write: new, in a new folder, a folder, the command's input (never
            # another file: that would be overwritten as asked)
            pool = [str(work / "new.out"), str(work / "sub" / "new.out"), str(inputs.results),
                    str(inputs.project), str(inputs.results / "observations.csv"),
                    str(inputs.strip), str(inputs.pattern), "", "/proc/new.out",
                    str(inputs.loop), str(inputs.fifo), str(inputs.dangling),
                    str(work / ("z" * 5000))]
            pool = [v for v in pool if v not in others or v in (own or [])]
        elif kind == "path":
            pool = inputs.paths()
        else:
            pool = LISTS.get(kind, TEXT) + TEXT
        out.append(draw(st.sampled_from(pool)))
    return out


@st.composite
def command_line(draw, inputs: Inputs, work: Path) -> tuple[list[str], str | None]:
    """(argv, the kind of -o given: None, 'new', 'earlier', 'foreign', 'input')."""
    name = draw(st.sampled_from(sorted(COMMANDS)))
    parser = COMMANDS[name]
    argv = [name]
    out_kind = None
    positional = [a for a in parser._actions if not a.option_strings]
    for a in positional:
        if a.dest == "spec":
            argv.append(draw(st.sampled_from(["9", "6", "3x3", "2x2+corners", "4x5+edges",
                                              "1x1", "30x30", "zz;;--", str(inputs.pattern),
                                              str(inputs.file), "missing.csv", ""])))
        else:  # never left out: `online` would read standard input
            usual = {"project": inputs.project, "models": inputs.models,
                     "results": inputs.results, "observations":
                     inputs.results / "observations.csv", "strip": inputs.strip}
            first = str(usual[POSITIONAL[name]])
            argv.append(draw(st.sampled_from([first] * 6 + [
                p for p in inputs.paths() if p != "-"])))
    options = [a for a in parser._actions if a.option_strings and
               not isinstance(a, argparse._HelpAction)]
    chosen = draw(st.lists(st.sampled_from(options), max_size=4, unique_by=id))
    out_action = next((a for a in options if a.dest == "out"), None)
    if out_action is not None and out_action.required and out_action not in chosen and \
            draw(st.integers(0, 9)):
        chosen.append(out_action)
    for a in chosen:
        flag = draw(st.sampled_from(a.option_strings))
        if a.dest == "out" and a.required:
            own = POSITIONAL.get(name) == "project"  # else the project is no input of it
            out_kind = draw(st.sampled_from(["new"] * 5 + ["earlier", "foreign"]
                                            + ["input"] * own))
            target = {"new": work / "out", "earlier": work / "out", "foreign": work / "out",
                      "input": inputs.project}[out_kind]
            argv += [flag, str(target)]
            continue
        argv += [flag, *draw(values(a, inputs, work, argv[1:len(positional) + 1]))]
        if isinstance(a, argparse._CountAction) and draw(st.booleans()):
            argv.append(flag)  # -q -q
    # cheap runs: few trials, no plots, no compiling
    if name == "evaluate" and not any(a.dest == "trials" for a in chosen):
        argv += ["--trials", draw(st.sampled_from(["1", "2", "0", "x"]))]
    if name == "plan" and draw(st.integers(0, 9)):
        argv.append("--no-plots")
    if name == "report" and not any(a.dest in ("out", "quality", "pdf") for a in chosen):
        argv.append("--text")
    if name == "compile":
        argv += ["-j", draw(st.sampled_from(["0", "-1", "x", "1.5", ""]))]
    if draw(st.integers(0, 19)) == 0:  # an unknown option or a stray value
        argv.insert(draw(st.integers(1, len(argv))), draw(st.sampled_from(
            ["--bogus", "-z", "stray", "--alpha0", "--", "-q=2"])))
    return argv, out_kind


def _prepare(out_kind: str | None, out: Path, inputs: Inputs) -> dict | None:
    """Put what -o names in place; its contents before the run (None: absent)."""
    if out_kind == "earlier":
        shutil.copytree(inputs.results, out)
    elif out_kind == "foreign":
        out.mkdir()
        (out / "thesis.tex").write_text("keep me")
    return snapshot(out) if out.exists() else None


# ---------------------------------------------------------------------- the test
@fuzz_settings("argv", 2 * ADJUST_DEADLINE_MS)  # a first compile of a kernel
@given(data=st.data())
def test_command_lines(inputs, work, data):
    with tempfile.TemporaryDirectory(dir=work) as d:
        d = Path(d)
        argv, out_kind = data.draw(command_line(inputs, d))
        out = d / "out"
        before = _prepare(out_kind, out, inputs)
        stdout, stderr = io.StringIO(), io.StringIO()
        closed = data.draw(st.integers(0, 7)) == 0  # `baarda ... >&-`: sys.stdout is None
        with redirect_stdout(None if closed else stdout), redirect_stderr(stderr):
            try:
                code = main(argv)
            except SystemExit as e:  # --help (argparse prints it and exits 0)
                code = e.code
            finally:
                if closed and sys.stdout is not None:
                    sys.stdout.close()  # the null device main() put in its place
        err = stderr.getvalue()
        _record(f"argv {argv[0] if argv else ''}", f"exit {code}")
        # 5: baarda check found an invariant that does not hold (a tolerance drawn too tight)
        # 4: a closed stdout where the printout is the result
        assert code in (0, 2, 3) or (code == 5 and argv[0] == "check") or (
            closed and code == 4 and "standard output is closed" in err), (code, err)
        assert "Traceback" not in err + stdout.getvalue(), err
        inputs.unchanged()
        tmp = [p.name for p in d.rglob("*") if p.name.endswith((".partial", ".old", ".tmp"))]
        assert not tmp, f"left behind: {tmp}"
        if code == 2:
            assert err.startswith(("baarda: error: ", "usage: ")) or "error:" in err, err
        if out_kind is None or out_kind == "input":
            return
        if code == 2 or "--help" in argv or "-h" in argv:
            assert (snapshot(out) if out.exists() else None) == before, \
                "an error changed the output folder"
        elif out.exists():  # the run went where -o says
            check_output(out, code, err)
