"""One run, one folder; the output place checked before any work; exit codes 0, 2, 3, 130
(issue 15)."""

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
from baarda.errors import ProjectError
from baarda.io.result_folder import read_results
from baarda.io.run_manifest import MANIFEST, file_record

DEMO = Path(__file__).parents[2] / "examples" / "demo"


def snapshot(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def leftovers(parent: Path) -> list[str]:
    return [p.name for p in parent.iterdir() if p.name.endswith((".partial", ".old"))]


class Terminal:
    """The reading end of a pseudo-terminal that a process writes its stderr to."""

    def __init__(self, fd: int):
        self.fd, self.text = fd, ""

    def _read(self, timeout: float) -> bool:
        import select

        if not select.select([self.fd], [], [], timeout)[0]:
            return False
        try:
            chunk = os.read(self.fd, 65536)
        except OSError:  # the process closed it
            return False
        self.text += chunk.decode("utf-8", "replace")
        return bool(chunk)

    def wait_for(self, text: str, timeout: float = 120) -> str:
        """What was written until `text` appeared (or the writer stopped)."""
        end = time.monotonic() + timeout
        while text not in self.text and time.monotonic() < end:
            self._read(0.5)
        return self.text

    def rest(self) -> str:
        while self._read(0.5):
            pass
        os.close(self.fd)
        return self.text


def on_a_terminal(args: list[str], **kwargs) -> tuple[subprocess.Popen, Terminal]:
    """`python -m baarda ARGS` with stderr a terminal (a pty), stdout discarded."""
    import fcntl
    import pty
    import struct
    import termios

    main_fd, sub_fd = pty.openpty()
    fcntl.ioctl(sub_fd, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 160, 0, 0))  # rows, cols
    # Ctrl-C reaches a program on a terminal: a suite started in the background by a shell
    # without job control ignores SIGINT, and its children would inherit that
    p = subprocess.Popen([sys.executable, "-m", "baarda", *args], stderr=sub_fd,
                         stdout=subprocess.DEVNULL,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
                         **kwargs)
    os.close(sub_fd)
    return p, Terminal(main_fd)


@pytest.fixture
def project(tmp_path):
    dst = tmp_path / "demo"
    shutil.copytree(DEMO, dst)
    return dst


def test_a_run_lists_its_files_and_replaces_the_previous_runs_files(project, tmp_path):
    out = tmp_path / "out"
    assert main(["adjust", str(project), "-o", str(out), "-q"]) == 0
    manifest = json.loads((out / MANIFEST).read_text())
    names = {"summary.json", "photos.csv", "points.csv", "observations.csv"}
    assert set(manifest["files"]) == names
    for name in names:
        assert manifest["files"][name] == file_record(out / name)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["run"] == manifest["run"]
    assert manifest["command"].startswith("baarda adjust ")
    (out / "report.html").write_text("an old report")
    assert main(["adjust", str(project), "-o", str(out), "-q", "--snoop"]) == 0
    second = json.loads((out / MANIFEST).read_text())
    assert second["run"] != manifest["run"]
    assert set(second["files"]) == names  # every file of the earlier run replaced
    assert (out / "report.html").read_text() == "an old report"  # not baarda's: kept
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("case", ["file", "foreign", "input", "holds_input", "proc"])
def test_output_place_is_checked_before_any_work(project, tmp_path, capsys, case,
                                                 monkeypatch):
    out = {"file": tmp_path / "a_file", "foreign": tmp_path / "mine", "input": project,
           "holds_input": tmp_path, "proc": Path("/proc/baarda_out")}[case]
    if case == "file":
        out.write_text("keep me")
    if case == "foreign":
        out.mkdir()
        (out / "thesis.tex").write_text("keep me")
    before = snapshot(tmp_path)

    def no_work(*a, **k):  # the check comes before reading or adjusting
        raise AssertionError("computed before checking the output place")

    monkeypatch.setattr("baarda.cli.adjust.read_configured_input", no_work)
    assert main(["adjust", str(project), "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.startswith("baarda: error: ")
    expected = {"file": "is not a folder", "foreign": "holds files that baarda did not write "
                "(thesis.tex)", "input": "is the input", "holds_input": "holds the input",
                "proc": "cannot write the output folder here"}[case]
    assert expected in err
    assert snapshot(tmp_path) == before


def test_interrupted_run_leaves_the_previous_run(project, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    assert main(["adjust", str(project), "-o", str(out), "-q"]) == 0
    before = snapshot(out)
    from baarda.output import bundle_results

    write = bundle_results.write_results

    def write_then_interrupt(run, qc):
        write(run, qc)  # half of the run written...
        raise KeyboardInterrupt  # ...then Ctrl-C

    # the command imports the writer when it needs it (after reading its input)
    monkeypatch.setattr(bundle_results, "write_results", write_then_interrupt)
    assert main(["adjust", str(project), "-o", str(out), "-q", "--snoop"]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert snapshot(out) == before
    assert leftovers(tmp_path) == []
    read_results(out)  # still one whole run


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.0, 0.05, 0.2])
def test_ctrl_c_in_a_real_process(tmp_path, delay):
    """SIGINT while adjusting: exit 130, one line, no traceback, no folder; also while numba
    loads its kernels right after reading (an exception inside numba's callbacks was lost,
    became a SystemError or crashed the process)."""
    proj = tmp_path / "big"
    assert main(["simulate", "-o", str(proj), "--strips", "8", "--photos", "25", "--pattern",
                 "5", "--seed", "3"]) == 0
    out = tmp_path / "out"
    # stderr a terminal: the progress display says when reading is done
    p, terminal = on_a_terminal(["snoop", str(proj), "-o", str(out)])
    seen = terminal.wait_for("] read simulated")
    assert "] read simulated" in seen, seen
    time.sleep(delay)
    p.send_signal(signal.SIGINT)
    p.wait(timeout=60)
    err = terminal.rest()
    assert p.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert not out.exists() and leftovers(tmp_path) == []


def test_report_refuses_a_folder_that_mixes_runs(project, tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    assert main(["adjust", str(project), "-o", str(a), "-q"]) == 0
    assert main(["adjust", str(project), "-o", str(b), "-q", "--snoop"]) == 0
    shutil.copy(b / "observations.csv", a / "observations.csv")
    with pytest.raises(ProjectError, match="mixes runs"):
        read_results(a)
    assert main(["report", str(a), "--text"]) == 2
    assert "observations.csv: is not the file that run" in capsys.readouterr().err
    os.remove(a / "photos.csv")  # a missing optional file is not a mix
    shutil.copy(b / "observations.csv", a / "photos_local.csv")  # nor is an unread file
    shutil.copy(b / MANIFEST, a / MANIFEST)
    with pytest.raises(ProjectError, match="summary.json: is not the file"):
        read_results(a)


@pytest.mark.slow
def test_report_file_is_checked_before_reading(project, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["adjust", str(project), "-o", str(out), "-q"]) == 0
    for bad in (out / "observations.csv", out / MANIFEST, out):
        before = snapshot(out)
        assert main(["report", str(out), "-o", str(bad)]) == 2
        assert snapshot(out) == before
    assert main(["report", str(out), "-o", str(out / "report.html"), "-q"]) == 0
    read_results(out)  # the report beside the results does not break the run


def test_not_converged_exits_3_marks_the_results_and_does_not_snoop(project, tmp_path,
                                                                      capsys, monkeypatch):
    from dataclasses import replace

    from baarda.bundle.bundle_problem import SOLVE, BundleProblem

    fit = BundleProblem.fit

    def two_iterations(self, start=None, options=SOLVE, progress=None):
        return fit(self, start, replace(options, max_iterations=2), progress)

    monkeypatch.setattr(BundleProblem, "fit", two_iterations)
    out = tmp_path / "out"
    assert main(["adjust", str(project), "-o", str(out), "--snoop"]) == 3
    printed = capsys.readouterr().out
    assert "NOT CONVERGED after 2 iterations" in printed.splitlines()[2]
    assert "data snooping not run" in printed
    s = json.loads((out / "summary.json").read_text())
    assert s["converged"] is False and s["n_rejected"] == 0
    res = read_results(out)
    assert not res.converged
    from baarda.report.text_report import text_report

    assert "NOT CONVERGED" in text_report(res).splitlines()[2]


def test_a_project_without_control_is_a_datum_error_that_offers_free(project, tmp_path,
                                                                      capsys):
    head = (project / "ground_points.csv").read_text().splitlines()[0]
    (project / "ground_points.csv").write_text(head + "\n")
    out = tmp_path / "out"
    assert main(["adjust", str(project), "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert "datum defect" in err and "0 planimetric" in err and "--free" in err
    assert not out.exists()
    assert main(["adjust", str(project), "-o", str(out), "--free"]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[3].startswith("datum: FREE NETWORK (no control)")


def test_free_turns_control_into_check_points(project, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["adjust", str(project), "-o", str(out), "--free"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["n_check_points"] > 0
    assert "used as check points only" in capsys.readouterr().out


def test_control_on_one_edge_is_warned_with_numbers(tmp_path, capsys):
    from baarda.pipeline import prepare
    from baarda.simulate.aerial import FlightPlan, simulate_block

    block, _ = simulate_block(FlightPlan(strips=4, photos_per_strip=8, seed=2))
    pts = block.points
    edge = pts.xyz[:, 1] < pts.xyz[pts.role == "control", 1].min() + 1.0  # lowest row only
    from dataclasses import replace

    role = pts.role.copy()
    role[(pts.role == "control") & ~edge] = "tie"
    sigma = pts.sigma.copy()
    sigma[role != "control"] = float("nan")
    block = replace(block, points=replace(pts, role=role, sigma=sigma))
    notes = prepare(block).notes
    weak = [n for n in notes if n.startswith("weak control: the height control spans")]
    assert len(weak) == 1 and "% of the block's width" in weak[0]
    full, _ = simulate_block(FlightPlan(strips=4, photos_per_strip=8, seed=2))
    assert not [n for n in prepare(full).notes if n.startswith("weak control")]


def test_default_sigmas_are_said(project):
    from baarda.io.project import read_project

    toml = (project / "project.toml").read_text().replace("image_um = 5.0\n", "")
    (project / "project.toml").write_text(toml)
    rows = (project / "image_points.csv").read_text().splitlines()
    (project / "image_points.csv").write_text(
        "\n".join(",".join(r.split(",")[:4]) for r in rows) + "\n")
    block = read_project(project)
    assert any(n.startswith("a-priori image sigma 5 µm (the default) for") for n in
               block.notes)
