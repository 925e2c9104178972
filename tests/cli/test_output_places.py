"""Where results may be written (issue 43): a single-file output replaces only an absent or
regular file (a link to one is written through; a FIFO, a link loop, a dangling link whose
folder is missing are refused, exit 2); a re-run replaces only the files of the earlier run;
two runs into one folder at once: the later is refused."""

import json
import os
from pathlib import Path

import pytest

from baarda.cli import main
from baarda.io.run_manifest import MANIFEST
from baarda.output.run_folder import RunFolder

DEMO = Path(__file__).parents[2] / "examples" / "demo"
STRIP = Path(__file__).parents[2] / "examples" / "online" / "strip.txt"


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    out = tmp_path_factory.mktemp("res") / "out"
    assert main(["adjust", str(DEMO), "-o", str(out), "-q"]) == 0
    return out


def commands(results: Path, target: Path) -> dict[str, list[str]]:
    return {"report": ["report", str(results), "-o", str(target), "-q"],
            "quality": ["report", str(results), "--quality", str(target), "-q"],
            "pdf": ["report", str(results), "--pdf", str(target), "-q"],
            "pattern": ["pattern", "3x3", "--svg", str(target)],
            "online": ["online", str(STRIP), "-o", str(target), "-q"]}


def make(kind: str, folder: Path) -> Path:
    """A target of `kind` in `folder` (never a device node)."""
    target = folder / "target"
    if kind == "fifo":
        os.mkfifo(target)
    elif kind == "link_to_fifo":
        os.mkfifo(folder / "pipe")
        target.symlink_to("pipe")
    elif kind == "loop":
        target.symlink_to("target")
    elif kind == "dangling_no_folder":
        target.symlink_to(folder / "missing" / "deeper" / "x")
    return target


@pytest.mark.parametrize("command", ["report", "quality", "pdf", "pattern", "online"])
@pytest.mark.parametrize("kind", ["fifo", "link_to_fifo", "loop", "dangling_no_folder"])
def test_a_single_file_output_refuses_what_is_not_a_regular_file(results, tmp_path, capsys,
                                                                  command, kind):
    target = make(kind, tmp_path)
    before = {p.name: (os.lstat(p).st_mode, os.readlink(p) if p.is_symlink() else None)
              for p in tmp_path.iterdir()}
    assert main(commands(results, target)[command]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.startswith(f"baarda: error: {target}: ")
    expected = {"fifo": "is a FIFO (named pipe)", "link_to_fifo": "is a FIFO (named pipe) "
                f"(a link to {tmp_path / 'pipe'})", "loop": "is a symbolic link loop",
                "dangling_no_folder": "whose folder does not exist"}[kind]
    assert expected in err
    after = {p.name: (os.lstat(p).st_mode, os.readlink(p) if p.is_symlink() else None)
             for p in tmp_path.iterdir()}
    assert after == before  # nothing replaced, no folder made, no temporary file left
    assert not (tmp_path / "missing").exists()


@pytest.mark.parametrize("command", ["report", "pattern", "online"])
def test_a_link_to_a_regular_file_is_written_through(results, tmp_path, command):
    real = tmp_path / "real.out"
    real.write_text("old")
    os.chmod(real, 0o640)
    link = tmp_path / "link.out"
    link.symlink_to("real.out")
    assert main(commands(results, link)[command]) == 0
    assert link.is_symlink() and os.readlink(link) == "real.out"
    assert real.read_text() != "old" and len(real.read_text()) > 100
    assert oct(os.stat(real).st_mode & 0o777) == oct(0o640)  # its permissions kept
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.out", "real.out"]


def test_a_dangling_link_whose_folder_exists_makes_the_file(results, tmp_path):
    link = tmp_path / "link.html"
    link.symlink_to("made.html")
    assert main(commands(results, link)["report"]) == 0
    assert link.is_symlink() and (tmp_path / "made.html").stat().st_size > 1000


@pytest.mark.parametrize("command", ["adjust", "convert", "simulate", "plan", "models"])
def test_a_link_loop_as_output_folder_is_bad_input(tmp_path, capsys, command):
    loop = tmp_path / "loop"
    loop.symlink_to("loop")
    argv = {"adjust": ["adjust", str(DEMO)], "convert": ["convert", str(DEMO)],
            "simulate": ["simulate"], "plan": ["plan", "--strips", "2", "--photos", "4"],
            "models": ["simulate-models"]}[command]
    assert main([*argv, "-o", str(loop), "-q"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and f"{loop}: is a symbolic link loop" in err


def test_a_link_loop_as_input_is_bad_input(tmp_path, capsys):
    loop = tmp_path / "loop.txt"
    loop.symlink_to("loop.txt")
    assert main(["adjust", str(loop), "-o", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and str(loop) in err and "symbolic link loop" in err
    assert not (tmp_path / "out").exists()


def test_a_rerun_replaces_only_what_run_json_lists(tmp_path, capsys):
    """The tutorial's order: adjust, report into the folder, adjust again: the report and a
    file of the user's stay (named), the earlier run's files are replaced."""
    out = tmp_path / "out"
    assert main(["adjust", str(DEMO), "-o", str(out), "-q"]) == 0
    first = json.loads((out / MANIFEST).read_text())["run"]
    assert main(["report", str(out), "-o", str(out / "report.html"), "-q"]) == 0
    report = (out / "report.html").read_bytes()
    (out / "notes").mkdir()
    (out / "notes" / "mine.txt").write_text("keep me")
    (out / "summary.json.bak").write_text("mine too")
    capsys.readouterr()
    assert main(["adjust", str(DEMO), "-o", str(out), "-q", "--snoop"]) == 0
    err = capsys.readouterr().err
    assert (f"kept 3 file(s) in {out} that no run of baarda wrote there (notes/mine.txt, "
            f"report.html, summary.json.bak); they may describe run {first}") in err
    second = json.loads((out / MANIFEST).read_text())
    assert second["run"] != first and "report.html" not in second["files"]
    assert (out / "report.html").read_bytes() == report
    assert (out / "notes" / "mine.txt").read_text() == "keep me"
    assert (out / "summary.json.bak").read_text() == "mine too"
    assert json.loads((out / "summary.json").read_text())["run"] == second["run"]
    assert [p.name for p in tmp_path.iterdir()] == ["out"]  # nothing left beside it


def test_a_file_of_the_user_named_like_a_new_result_is_kept_beside_it(tmp_path):
    out = tmp_path / "out"
    with RunFolder(out) as run:
        run.file("summary.json").write_text("{}")
    (out / "extra.csv").write_text("mine")  # not written by the first run
    with RunFolder(out) as run:
        run.file("summary.json").write_text("{}")
        run.file("extra.csv").write_text("the new run's")
    assert run.kept == ["extra.csv.earlier"]
    assert (out / "extra.csv").read_text() == "the new run's"
    assert (out / "extra.csv.earlier").read_text() == "mine"
    assert set(json.loads((out / MANIFEST).read_text())["files"]) == {"summary.json",
                                                                     "extra.csv"}


def test_two_runs_into_one_folder_the_later_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["adjust", str(DEMO), "-o", str(out), "-q"]) == 0
    before = (out / MANIFEST).read_bytes()
    first = RunFolder(out)  # a run in progress: its staging folder locked
    try:
        assert main(["adjust", str(DEMO), "-o", str(out), "-q"]) == 2
        err = capsys.readouterr().err
        assert f"another run ({first.run_id}) is writing this output folder now" in err
        assert (out / MANIFEST).read_bytes() == before
        assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".partial")] == [
            first.path.name]  # the refused run left nothing
        (first.path / "summary.json").write_text("{}")
        first.commit()
    finally:
        first.discard()
    assert json.loads((out / MANIFEST).read_text())["run"] == first.run_id
    assert main(["adjust", str(DEMO), "-o", str(out), "-q"]) == 0  # the lock went with it


def test_a_non_numeric_field_in_a_dbat_control_line_is_an_error_of_that_line(tmp_path,
                                                                              capsys):
    from baarda.errors import ProjectError
    from baarda.io.control_file import read_control_file

    p = tmp_path / "c.txt"
    p.write_text("# Id, X, Y, Z, sX, sY, sZ\n"
                 "001001, 12.5, -805.00, -20.80, 0.05, 0.05, 0.1\n"
                 "001007, abc, -805.02, -20.85, 0.05, 0.05, 0.1\n"
                 "001009, 14.1, -806.10, -20.90, 0.05, 0.05, 0.1\n")
    with pytest.raises(ProjectError) as e:
        read_control_file(p)
    assert (e.value.path, e.value.line, e.value.column) == (str(p), 3, "X")
    assert "'abc' is not a number" in str(e.value)
    p.write_text("001001, 12.5, -805.00, -20.80\n001007, abc, -805.02, -20.85\n"
                 "001009, 14.1, -806.10, -20.90\n")  # no header: most lines have no name
    with pytest.raises(ProjectError) as e:
        read_control_file(p)
    assert (e.value.line, e.value.column) == (2, "X")
    assert main(["adjust", str(DEMO), "--control", str(p), "-o", str(tmp_path / "o")]) == 2
    assert f"{p}, line 2, column 'X': 'abc' is not a number" in capsys.readouterr().err
    p.write_text("1, a, 1, 2, 3\n2, 17, 1, 2, 3\n3, c, 1, 2, 3\n")  # names, one numeric
    assert read_control_file(p).ids == ["1", "2", "3"]


def _deny(monkeypatch, folder: Path, code: int) -> None:
    """Writing under `folder` fails with `code` (EACCES: the test may run as root, which
    chmod does not stop; EROFS: a read-only file system), as the system would say it."""
    import errno
    import tempfile

    mkdir, temporary = Path.mkdir, tempfile.TemporaryFile

    def refuse(path) -> None:
        if folder == Path(path) or folder in Path(path).parents:
            raise OSError(code, os.strerror(code), str(path))

    def guarded_mkdir(self, *a, **k):
        refuse(self)
        return mkdir(self, *a, **k)

    def guarded_temporary(*a, **k):
        refuse(Path(k.get("dir") or "/") / "x")
        return temporary(*a, **k)

    monkeypatch.setattr(Path, "mkdir", guarded_mkdir)
    monkeypatch.setattr(tempfile, "TemporaryFile", guarded_temporary)
    assert errno.errorcode[code]


@pytest.mark.parametrize("code", [13, 30])  # EACCES, EROFS
def test_an_unwritable_output_place_is_exit_4_as_the_tutorial_says(results, tmp_path,
                                                                   capsys, monkeypatch,
                                                                   code):
    """'4 the results could not be written (disk full, no permission ...)': a place without
    permission or on a read-only file system was exit 2 when found before the work; a
    place of the wrong kind (a file where a folder is named) stays bad input, 2."""
    locked = tmp_path / "locked"
    locked.mkdir()
    _deny(monkeypatch, locked, code)
    assert main(["adjust", str(DEMO), "-o", str(locked / "out"), "-q"]) == 4
    err = capsys.readouterr().err
    assert f"could not write the results: {locked / 'out'}: {os.strerror(code)}" in err
    assert main(["report", str(results), "-o", str(locked / "r.html"), "-q"]) == 4
    assert f"{locked}: {os.strerror(code)}" in capsys.readouterr().err
    (tmp_path / "a_file").write_text("")
    assert main(["adjust", str(DEMO), "-o", str(tmp_path / "a_file" / "out"), "-q"]) == 2
    assert not list(locked.iterdir())


def test_a_folder_without_write_permission_is_exit_4(tmp_path, capsys):
    """The same with the file system's own permissions, where they bind (not as root)."""
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    try:
        code = main(["adjust", str(DEMO), "-o", str(locked / "out"), "-q"])
        assert code == (0 if os.geteuid() == 0 else 4), capsys.readouterr().err
    finally:
        locked.chmod(0o755)
