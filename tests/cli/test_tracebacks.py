"""Ways to a traceback found by the fault campaigns of issue 43, each now an exit code and
one message naming the thing: closed standard streams, an overlong argument, a memory limit,
Ctrl-C during start-up, `--opt=--`, --interval inf, a non-UTF-8 online file, user templates
(sandboxed, errors as "template FILE, line N"), malformed run.json and summary.json, a FIFO
where a file is expected."""

import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from baarda.cli import main

ROOT = Path(__file__).parents[2]
DEMO = ROOT / "examples" / "demo"
STRIP = ROOT / "examples" / "online" / "strip.txt"
TEMPLATES = ROOT / "baarda" / "report" / "templates"


def baarda(*args, preexec=None, shell_suffix: str = "", **kw) -> subprocess.CompletedProcess:
    """`python -m baarda ARGS` in a child (optionally through sh with `shell_suffix`, e.g.
    '>&-' to close its stdout)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if shell_suffix:
        cmd = " ".join([sys.executable, "-m", "baarda", *map(str, args)]) + " " + shell_suffix
        return subprocess.run(["sh", "-c", cmd], capture_output=True, text=True, env=env,
                              cwd=ROOT, timeout=300, **kw)
    return subprocess.run([sys.executable, "-m", "baarda", *map(str, args)],
                          capture_output=True, text=True, env=env, cwd=ROOT, timeout=300,
                          preexec_fn=preexec, **kw)


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    out = tmp_path_factory.mktemp("res") / "out"
    assert main(["adjust", str(DEMO), "-o", str(out), "-q"]) == 0
    return out


# ------------------------------------------------------------------ standard streams
def test_closed_stdout_writes_the_results_and_says_the_printout_is_lost(tmp_path):
    out = tmp_path / "out"
    p = baarda("adjust", DEMO, "-o", out, shell_suffix=">&-")
    assert p.returncode == 0, p.stderr
    assert "Traceback" not in p.stderr
    assert "standard output is closed: the printout is lost" in p.stderr
    assert json.loads((out / "summary.json").read_text())["redundancy"] == 172
    p = baarda("pattern", "3x3", shell_suffix=">&-")  # the printout is the result
    assert p.returncode == 4 and "Traceback" not in p.stderr
    assert "could not write the results to standard output (standard output is closed)" \
        in p.stderr


def test_closed_stdin(tmp_path):
    p = baarda("online", "-", shell_suffix="<&-")
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert "<stdin>: no measurements" in p.stderr
    p = baarda("online", "--bundle", DEMO, shell_suffix="<&-")
    assert p.returncode == 0 and "Traceback" not in p.stderr, p.stderr


# ------------------------------------------------------------------ arguments
def test_an_overlong_argument_is_bad_input(tmp_path, capsys):
    long = "x" * 5000
    for argv in (["pattern", long], ["pattern", long + ".csv"],
                 ["adjust", long, "-o", str(tmp_path / "o")],
                 ["adjust", str(DEMO), "-o", str(tmp_path / long)],
                 ["report", long, "--text"], ["check", long]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "Traceback" not in err and "error" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("argv", [["check", "{results}", "--rtol=--"],
                                  ["adjust", str(DEMO), "-o", "{tmp}/o", "--alpha0=--"],
                                  ["report", "{results}", "--text", "--top=--"],
                                  ["simulate", "-o", "{tmp}/s", "--strips=--"]])
def test_an_option_written_opt_equals_dashdash_is_bad_input(argv, results, tmp_path, capsys):
    argv = [a.format(results=results, tmp=tmp_path) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "not '--'" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value", ["inf", "1e309", "nan", "0", "-1"])
def test_watch_interval_must_be_a_finite_positive_number(value, tmp_path, capsys):
    assert main(["online", "--bundle", "--watch", str(tmp_path), "-o", str(tmp_path / "o"),
                 "--interval", value]) == 2
    err = capsys.readouterr().err
    assert "argument --interval: a number in (0, 86400] s" in err


# ------------------------------------------------------------------ memory, signals
@pytest.mark.slow
@pytest.mark.parametrize("megabytes", [150, 300, 450, 600, 1000, 1400, 1700])
def test_a_memory_limit_is_exit_4_out_of_memory(tmp_path, megabytes):
    """ulimit -v: either the run fits (exit 0) or it says 'out of memory (limit N MB)' with
    exit 4 and leaves nothing; never a traceback, never a crash in C.  Near 1000 MB numba's
    LLVM aborted the process ('LLVM ERROR: out of memory', std::bad_alloc: exit 134) or
    Python printed an ignored MemoryError's traceback, and at 1700 MB OpenBLAS' start-up
    retried its buffer's mmap for ever: below 2048 MB the kernels are not started, the
    message says what they need."""
    limit = megabytes * 2**20

    def limited():
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    out = tmp_path / "out"
    p = baarda("adjust", DEMO, "-o", out, "-q", preexec=limited)
    assert p.returncode in (0, 4), p.stderr[-2000:]
    assert "Traceback" not in p.stderr
    if p.returncode == 4:
        assert f"out of memory (limit {megabytes} MB, ulimit -v)" in p.stderr
        assert [q.name for q in tmp_path.iterdir()] == []
    if 1000 <= megabytes < 2048:
        assert p.returncode == 4 and "the numerical kernels (numba, LLVM) need at least " \
            "2048 MB of address space" in p.stderr, p.stderr[-2000:]


def _start(args, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen([sys.executable, "-m", "baarda", *map(str, args)], cwd=ROOT,
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.1, 0.25, 0.5, 1.0])
@pytest.mark.parametrize("times", [1, 2])
def test_ctrl_c_during_start_up(tmp_path, delay, times):
    """SIGINT while Python imports baarda and its libraries (once, or twice within a
    millisecond): exit 130 and the message of a later Ctrl-C, no traceback."""
    out = tmp_path / "out"
    p = _start(["adjust", DEMO, "-o", out], tmp_path)
    time.sleep(delay)
    for _ in range(times):
        p.send_signal(signal.SIGINT)
        time.sleep(0.0005)
    err = p.communicate(timeout=120)[1]
    if p.returncode == -signal.SIGINT or "init_import_site" in err:
        return  # Python's own start-up, before any code of baarda ran, or its shut-down
    if p.returncode == 0:  # a fast machine ended the run first: Python's shut-down drops it
        assert f"-> {out}" in err and "Traceback" not in err, err
        assert (out / "summary.json").is_file() and (out / "run.json").is_file()
        return
    assert p.returncode == 130, err
    assert "Traceback" not in err
    if "interrupted (after the results were written" in err:  # the run had ended first
        assert (out / "run.json").is_file()
        return
    assert "interrupted (nothing of this run was written)" in err
    assert not out.exists()


# ------------------------------------------------------------------ online files
def test_online_file_not_utf8_names_the_line_and_takes_encoding(tmp_path, capsys):
    text = STRIP.read_text().replace("# A simulated strip", "# Ein Streifen, Größe")
    p = tmp_path / "strip.txt"
    p.write_bytes(text.encode("latin-1"))
    line = next(n for n, s in enumerate(text.splitlines(), 1) if "Größe" in s)
    assert main(["online", str(p)]) == 2
    err = capsys.readouterr().err
    assert f"{p}, line {line}: not utf-8 text: byte 0xf6" in err and "Traceback" not in err
    assert main(["online", str(p), "--encoding", "latin-1", "-q"]) == 0
    p.write_bytes(b"\xef\xbb\xbf" + STRIP.read_bytes())  # a byte-order mark
    assert main(["online", str(p), "-q"]) == 0


def test_online_stdin_with_a_byte_order_mark(monkeypatch, capsys):
    import io

    monkeypatch.setattr(sys, "stdin", io.StringIO("\ufeff" + STRIP.read_text()))
    assert main(["online", "-", "-q"]) == 0


# ------------------------------------------------------------------ templates
def _templates(tmp_path: Path, line3: str) -> Path:
    d = tmp_path / "tpl"
    d.mkdir()
    lines = (TEMPLATES / "adjustment.html.j2").read_text().splitlines()
    lines[2] = line3
    (d / "adjustment.html.j2").write_text("\n".join(lines) + "\n")
    return d


@pytest.mark.parametrize("line3, message", [
    ("{% block heading %}A {% if %}{% endblock %}", "Expected an expression"),
    ("{% block heading %}A {{ no_such_name }}{% endblock %}", "'no_such_name' is undefined"),
    ("{% block heading %}A {{ 1 // 0 }}{% endblock %}", "ZeroDivisionError: integer division"),
    ('{% block heading %}A {% include "nothere.j2" %}{% endblock %}',
     "includes or extends 'nothere.j2', which is neither in the template folder nor"),
    ("{% block heading %}{{ cycler.__init__.__globals__.os.popen('id').read() }}"
     "{% endblock %}", "access to attribute '__init__' of 'type' object is unsafe"),
])
def test_template_errors_name_the_template_and_line(results, tmp_path, capsys, line3,
                                                    message):
    d = _templates(tmp_path, line3)
    out = tmp_path / "r.html"
    assert main(["report", str(results), "-o", str(out), "--templates", str(d)]) == 2
    err = capsys.readouterr().err
    assert f"baarda: error: template {d / 'adjustment.html.j2'}, line 3: {message}" in err
    assert "Traceback" not in err and not out.exists()


def test_a_sandboxed_template_still_renders(results, tmp_path):
    d = _templates(tmp_path, "{% block heading %}Branded: {{ title | upper }}{% endblock %}")
    out = tmp_path / "r.html"
    assert main(["report", str(results), "-o", str(out), "--templates", str(d), "-q"]) == 0
    assert "Branded: DEMO" in out.read_text()


# ------------------------------------------------------------------ run.json, summary.json
def _tamper(folder: Path, name: str, change) -> None:
    """Change a JSON file of a result folder; summary.json re-signed in run.json (a run.json
    changed is not checksummed: what is wrong with it is said)."""
    p = folder / name
    if callable(change):
        d = json.loads(p.read_text())
        change(d)
        p.write_text(json.dumps(d))
    else:
        p.write_bytes(change)
    if name == "summary.json":
        from baarda.io.run_manifest import file_record

        m = json.loads((folder / "run.json").read_text())
        m["files"]["summary.json"] = file_record(p)
        (folder / "run.json").write_text(json.dumps(m))


DEEP = b"[" * 100_000 + b"]" * 100_000
TAMPERINGS = {
    "files_list": ("run.json", lambda d: d.update(files=[]), "'files' must be an object"),
    "files_text": ("run.json", lambda d: d.update(files="x"), "'files' must be an object"),
    "files_null": ("run.json", lambda d: d.update(files=None), "'files' must be an object"),
    "files_entry": ("run.json", lambda d: d["files"].update({"points.csv": 3}),
                    "'files' entry 'points.csv' must be an object"),
    "run_missing": ("run.json", lambda d: d.pop("run"), "no 'run'"),
    "run_array": ("run.json", b"[]", "a JSON list, not an object"),
    "run_deep": ("run.json", DEEP, "JSON nested too deeply"),
    "run_latin1": ("run.json", b'{"run": "caf\xe9"}', "not UTF-8 text: byte 0xe9"),
    "summary_deep": ("summary.json", DEEP, "JSON nested too deeply"),
    "summary_latin1": ("summary.json", b'{"project": "caf\xe9"}', "not UTF-8 text"),
    "summary_array": ("summary.json", b"[1, 2]", "expected a JSON object, not list"),
    "adjustments": ("summary.json", lambda d: d.update(adjustments=[1]),
                    "'adjustments' must be an object, not list"),
    "adjustment": ("summary.json", lambda d: d.update(adjustments={"bundle": 3}),
                   "expected a JSON object, not int"),
    "cameras": ("summary.json", lambda d: d.update(cameras="cam"),
                "'cameras' must be an array, not str"),
    "camera": ("summary.json", lambda d: d.update(cameras=[3]), "'cameras[0]' must be an "
               "object"),
    "sections": ("summary.json", lambda d: d.update(sections={"a": 1}),
                 "'sections' must be an array, not dict"),
    "section_lines": ("summary.json", lambda d: d["sections"][0].update(lines=3),
                      "'sections[0].lines' must be an array"),
    "sigma0": ("summary.json", lambda d: d.update(sigma0="abc"),
               "'sigma0' must be a number, not \"abc\""),
    "nested_sigma0": ("summary.json", lambda d: d["adjustments"]["bundle"].update(
        sigma0=[1]), "'adjustments.bundle.sigma0' must be a number"),
    "global_test": ("summary.json", lambda d: d.update(global_test=2.25),
                    "'global_test' must be an object, not float"),
}


@pytest.mark.parametrize("case", sorted(TAMPERINGS))
@pytest.mark.parametrize("command", ["check", "report"])
def test_malformed_run_json_or_summary_json_is_named(results, tmp_path, capsys, case,
                                                     command):
    folder = tmp_path / "out"
    shutil.copytree(results, folder)
    name, change, message = TAMPERINGS[case]
    _tamper(folder, name, change)
    argv = ["check", str(folder)] if command == "check" else ["report", str(folder), "--text"]
    code = main(argv)
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert code == 2, err
    assert f"{folder / name}" in err and message in err, err


# ------------------------------------------------------------------ FIFOs
def test_a_fifo_where_a_file_is_expected_is_never_opened(tmp_path, capsys):
    fifo = tmp_path / "control.txt"
    os.mkfifo(fifo)
    assert main(["adjust", str(DEMO), "--control", str(fifo), "-o", str(tmp_path / "o")]) == 2
    assert f"{fifo}: is a FIFO (named pipe), not a regular file" in capsys.readouterr().err
    assert main(["online", str(fifo)]) == 2
    assert f"{fifo}: is a FIFO (named pipe), not a regular file" in capsys.readouterr().err
    for what, path in (("a folder", tmp_path), ("a character device", Path(os.devnull))):
        assert main(["adjust", str(DEMO), "--control", str(path), "-o",
                     str(tmp_path / "o")]) == 2
        assert f"{path}: is {what}, not a regular file" in capsys.readouterr().err
    loop = tmp_path / "loop.txt"
    loop.symlink_to("loop.txt")
    assert main(["online", str(loop)]) == 2
    assert f"{loop}: is a symbolic link loop, not a file" in capsys.readouterr().err


MICMAC = next((p for p in (ROOT.parent / "shared" / "data" / "micmac_ign_ultracam_aerial",
                           Path("/work/shared/data/micmac_ign_ultracam_aerial"))
               if p.is_dir()), None)


@pytest.mark.skipif(MICMAC is None, reason="the MicMac data set is not on this machine")
def test_a_fifo_in_a_micmac_folder_does_not_block_the_reader(tmp_path, capsys):
    d = tmp_path / "mm"
    d.mkdir()
    for p in MICMAC.iterdir():
        if p.name != "ImAerien.xml":
            (d / p.name).symlink_to(p)
    os.mkfifo(d / "ImAerien.xml")
    code = main(["convert", str(d), "-o", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code in (0, 2) and "Traceback" not in err  # returned: the FIFO was not opened
