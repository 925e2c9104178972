"""SIGTERM handled as Ctrl-C, and what killed runs leave behind removed by the next run
(issue 29)."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from baarda.cli import main
from baarda.io.run_manifest import MANIFEST
from baarda.output.run_folder import (
    RunFolder,
    _lock,
    _unlock,
    new_run_id,
    remove_leftovers,
)

ROOT = Path(__file__).parents[2]
DEMO = ROOT / "examples" / "demo"


def leftovers(parent: Path) -> list[str]:
    return sorted(p.name for p in parent.iterdir() if p.name.endswith((".partial", ".old")))


def run_id(out: Path) -> str:
    return json.loads((out / MANIFEST).read_text())["run"]


def baarda(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "baarda", *args], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


@pytest.mark.slow
def test_sigterm_keeps_the_earlier_run_and_sigkill_leftovers_are_removed(tmp_path):
    """A 20 x 20-photo block adjusted into OUT, then snooped into OUT and sent SIGTERM after
    2 s: exit 143 with a message, OUT holds the first run, no staging folder.  Then SIGKILL
    (nothing can be cleaned up): the next run removes the staging folder and says so."""
    proj, out = tmp_path / "block", tmp_path / "out"
    assert main(["simulate", "-o", str(proj), "--strips", "20", "--photos", "20",
                 "--pattern", "5", "--blunders", "10", "--seed", "1"]) == 0
    assert main(["adjust", str(proj), "-o", str(out), "-qq"]) == 0
    first = run_id(out)
    files = {p.name: p.read_bytes() for p in out.iterdir()}

    p = baarda("adjust", str(proj), "-o", str(out), "--snoop")
    time.sleep(2.0)
    assert p.poll() is None, "the snooping ended within 2 s: the test needs a larger block"
    p.send_signal(signal.SIGTERM)
    err = p.communicate(timeout=120)[1]
    assert p.returncode == 143, err
    assert "terminated by SIGTERM (nothing of this run was written)" in err
    assert "Traceback" not in err
    assert run_id(out) == first
    assert {q.name: q.read_bytes() for q in out.iterdir()} == files
    assert leftovers(tmp_path) == []

    p = baarda("adjust", str(proj), "-o", str(out), "--snoop")
    staging = None
    for _ in range(600):  # until the run has made its staging folder
        staging = next((q for q in tmp_path.iterdir() if q.name.endswith(".partial")), None)
        if staging is not None:
            break
        time.sleep(0.01)
    assert staging is not None
    time.sleep(0.5)
    p.send_signal(signal.SIGKILL)
    p.communicate(timeout=60)
    assert p.returncode == -signal.SIGKILL
    assert leftovers(tmp_path) == [staging.name]  # a kill leaves it: nothing runs after
    assert run_id(out) == first

    p = baarda("adjust", str(proj), "-o", str(out), "-q")
    err = p.communicate(timeout=300)[1]
    assert p.returncode == 0, err
    assert f"removed {staging.name}, the staging folder that a killed run left beside out" \
        in err
    assert leftovers(tmp_path) == []
    assert run_id(out) != first


def test_sigterm_in_process_is_exit_143_and_the_handlers_are_restored(tmp_path, capsys,
                                                                       monkeypatch):
    """The handler raises Terminated in the command; main says so and returns 143; the
    handlers of SIGTERM, SIGINT and SIGALRM are Python's again afterwards."""
    from baarda.output import bundle_results

    out = tmp_path / "out"
    assert main(["adjust", str(DEMO), "-o", str(out), "-qq"]) == 0
    before = run_id(out)

    def write_then_terminate(run, qc, **kw):
        bundle_results.write_results.__wrapped__(run, qc, **kw)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # the handler raises here
        raise AssertionError("SIGTERM was not handled")

    write_then_terminate.__wrapped__ = bundle_results.write_results
    monkeypatch.setattr(bundle_results, "write_results", write_then_terminate)
    handlers = [signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGINT, signal.SIGALRM)]
    assert main(["adjust", str(DEMO), "-o", str(out), "-q", "--snoop"]) == 143
    assert "baarda: terminated by SIGTERM" in capsys.readouterr().err
    assert [signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGINT, signal.SIGALRM)] \
        == handlers
    assert run_id(out) == before and leftovers(tmp_path) == []


def fake_leftover(parent: Path, name: str, kind: str) -> Path:
    p = parent / f".{name}.{new_run_id()}.{kind}"
    p.mkdir()
    (p / "summary.json").write_text("{}")
    return p


def test_leftovers_are_removed_and_named_but_not_those_of_a_live_run(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["adjust", str(DEMO), "-o", str(out), "-qq"]) == 0
    dead = fake_leftover(tmp_path, "out", "partial")
    old = fake_leftover(tmp_path, "out", "old")
    live = fake_leftover(tmp_path, "out", "partial")
    other = fake_leftover(tmp_path, "other", "partial")  # of another output folder
    fd = _lock(live)  # a run still writing holds its lock: a second run is refused
    try:
        assert main(["adjust", str(DEMO), "-o", str(out), "-q"]) == 2
        assert "is writing this output folder now" in capsys.readouterr().err
        assert dead.exists() and old.exists() and live.exists()  # nothing removed then
        assert not remove_leftovers(out) == [] and live.exists()  # the live one stays
    finally:
        _unlock(fd)
    live_gone = fake_leftover(tmp_path, "out", "partial")  # killed: no lock
    assert main(["adjust", str(DEMO), "-o", str(out), "-q"]) == 0
    err = capsys.readouterr().err
    assert f"baarda: warning: removed {live_gone.name}, the staging folder that a killed " \
        "run left beside out" in err
    assert not dead.exists() and not old.exists() and not live_gone.exists()
    assert other.exists()


def test_an_earlier_run_moved_aside_by_a_killed_run_is_put_back(tmp_path, capsys):
    """Killed between moving the earlier run aside and moving the new one in: OUT is
    missing; the next run puts the earlier run back (and replaces it as a whole)."""
    out = tmp_path / "out"
    assert main(["adjust", str(DEMO), "-o", str(out), "-qq"]) == 0
    first = run_id(out)
    old = tmp_path / f".out.{new_run_id()}.old"
    os.replace(out, old)
    run = RunFolder(out)
    assert out.is_dir() and run_id(out) == first and run.replaces == f"run {first}"
    assert run.cleaned == [f"moved {old.name} back to {out}: a killed run had moved run "
                           f"{first} aside"]
    run.discard()
    assert run_id(out) == first and leftovers(tmp_path) == []


def test_an_earlier_run_that_cannot_be_removed_is_a_warning(tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    assert main(["adjust", str(DEMO), "-o", str(out), "-qq"]) == 0
    from baarda.output import run_folder

    rmtree = shutil.rmtree

    def keep_old(path, *a, **k):  # an earlier run whose files cannot be deleted
        if str(path).endswith(".old"):
            return
        rmtree(path, *a, **k)

    monkeypatch.setattr(run_folder.shutil, "rmtree", keep_old)
    assert main(["adjust", str(DEMO), "-o", str(out), "-q"]) == 0
    err = capsys.readouterr().err
    (old,) = [p for p in tmp_path.iterdir() if p.name.endswith(".old")]
    assert f"baarda: warning: could not remove the earlier run, moved aside to {old}: " \
        "remove it by hand" in err


@pytest.mark.parametrize("when", ["printing", "moving"])
def test_ctrl_c_after_the_results_went_in_place_says_they_are_written(tmp_path, monkeypatch,
                                                                     capsys, when):
    """Ctrl-C once the run's folder is in place (while the summary is printed, or just as the
    folder is moved there: the folder's run.json tells whose run it holds): exit 130, and the
    message says the folder holds this run, complete, not that nothing was written."""
    import baarda.output.run_folder as run_folder
    from baarda.cli.console import Console

    out = tmp_path / "out"
    assert main(["adjust", str(DEMO), "-o", str(out), "-qq"]) == 0  # an earlier run
    first = run_id(out)
    if when == "printing":
        def interrupted(self, text="", end="\n"):
            raise KeyboardInterrupt

        monkeypatch.setattr(Console, "print", interrupted)
    else:
        replace = os.replace

        def replace_then_ctrl_c(src, dst):
            replace(src, dst)
            if Path(dst) == out:
                os.kill(os.getpid(), signal.SIGINT)  # the move is done, the caller not told yet

        monkeypatch.setattr(run_folder.os, "replace", replace_then_ctrl_c)
    assert main(["adjust", str(DEMO), "-o", str(out)]) == 130
    err = capsys.readouterr().err
    assert f"interrupted (after the results were written: {out} holds this run, " \
        "complete" in err and "nothing of this run was written" not in err
    assert run_id(out) != first and (out / "summary.json").is_file()
    assert leftovers(tmp_path) == []
